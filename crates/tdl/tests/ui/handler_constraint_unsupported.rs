tdl::tdl! {
    exception Stuck;
    goal g() {
        spawn a() with exception handler unstick();
    }
    command a() {}
}

fn unstick() -> tdl::Task {
    unimplemented!()
}

fn main() {}
