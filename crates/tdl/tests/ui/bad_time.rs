tdl::tdl! {
    goal g() {
        spawn a() with terminate at 25:00:00;
    }
    command a() {}
}

fn main() {}
