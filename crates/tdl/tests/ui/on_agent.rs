tdl::tdl! {
    goal g() {
        spawn a();
        a on "robot2";
    }
    command a() {}
}

fn main() {}
