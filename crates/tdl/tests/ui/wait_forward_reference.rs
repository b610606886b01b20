tdl::tdl! {
    goal g() {
        later wait;
        later: spawn a();
    }
    command a() {}
}

fn main() {}
