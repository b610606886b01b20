tdl::tdl! {
    goal g() {
        t1: spawn a();
        t1: spawn b();
    }
    command a() {}
    command b() {}
}

fn main() {}
