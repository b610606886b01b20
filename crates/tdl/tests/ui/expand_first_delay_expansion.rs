tdl::tdl! {
    goal g() {
        spawn a() with expand first, delay expansion;
    }
    command a() {}
}

fn main() {}
