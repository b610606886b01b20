tdl::tdl! {
    command count() -> u32 {
        if true {
            succeed;
        }
        3
    }
}

fn main() {}
