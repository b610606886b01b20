tdl::tdl! {
    monitor watch() with period 1s {
        trigger;
    }
}

fn main() {}
