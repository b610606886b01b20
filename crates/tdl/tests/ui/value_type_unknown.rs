fn external() -> tdl::Task {
    unimplemented!()
}

tdl::tdl! {
    goal g() {
        let v = spawn external() with wait;
        assert!(v > 0);
    }
}

fn main() {}
