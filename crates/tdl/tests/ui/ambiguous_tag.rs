tdl::tdl! {
    goal g() {
        spawn a();
        spawn a();
        spawn b() with sequential execution a;
    }
    command a() {}
    command b() {}
}

fn main() {}
