//! `cargo run -p xtask -- tidy`: checks the house rules (see `tidy.rs`); the same checks run as
//! this crate's test on every `cargo test --workspace`.

mod tidy;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.first().map(String::as_str) {
        Some("tidy") => {
            let problems = tidy::check(&tidy::workspace_root());
            for p in &problems {
                eprintln!("{p}");
            }
            std::process::exit(if problems.is_empty() { 0 } else { 1 });
        }
        _ => {
            eprintln!("usage: cargo run -p xtask -- tidy");
            std::process::exit(2);
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn tidy() {
        let problems = super::tidy::check(&super::tidy::workspace_root());
        assert!(
            problems.is_empty(),
            "house rules broken:\n{}",
            problems.join("\n")
        );
    }
}
