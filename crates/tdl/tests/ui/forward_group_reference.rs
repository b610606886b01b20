tdl::tdl! {
    goal g() {
        spawn a() with sequential execution grp;
        grp: with (parallel) {
            spawn b();
            spawn c();
        }
    }
    command a() {}
    command b() {}
    command c() {}
}

fn main() {}
