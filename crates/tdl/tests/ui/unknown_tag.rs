tdl::tdl! {
    goal g() {
        spawn a() with serial nowhere;
    }
    command a() {}
}

fn main() {}
