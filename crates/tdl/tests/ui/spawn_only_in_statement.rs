tdl::tdl! {
    monitor watch() with period 1s {
        trigger;
    }
    goal g() {
        w: spawn watch();
        w maximum trigger 3;
        w name "watcher";
    }
}

fn main() {}
