tdl::tdl! {
    goal g() {
        spawn a() with sequentially;
    }
    command a() {}
}

fn main() {}
