tdl::tdl! {
    command move_to(x: f64) {
        if x < 0.0 {
            retry;
        }
    }
}

fn main() {}
