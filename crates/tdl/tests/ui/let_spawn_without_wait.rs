tdl::tdl! {
    goal g() {
        let v = spawn a();
        assert_eq!(v, 1);
    }
    command a() -> u32 { 1 }
}

fn main() {}
