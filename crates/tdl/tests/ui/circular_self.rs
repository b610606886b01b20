tdl::tdl! {
    goal g() {
        spawn a() with serial self;
    }
    command a() {}
}

fn main() {}
