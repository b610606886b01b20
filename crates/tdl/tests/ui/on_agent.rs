tdl::tdl! {
    goal g() {
        spawn a() with on "robot2";
    }
    command a() {}
}

fn main() {}
