//! `cargo run -p xtask -- tidy`: checks the house rules (see `tidy.rs`); the same checks run as
//! this crate's test on every `cargo test --workspace`. `cargo run -p xtask -- circles SRC`:
//! the import circles among the modules of the crate whose sources are in SRC (`circles.rs`).

mod circles;
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
        Some("circles") => {
            let Some(src) = args.get(1) else {
                eprintln!("usage: cargo run -p xtask -- circles SRC (say crates/tcm/src)");
                std::process::exit(2);
            };
            match circles::circles(std::path::Path::new(src)) {
                Ok(found) if found.is_empty() => println!("no import circle among the modules"),
                Ok(found) => {
                    for c in found {
                        println!("circle: {}", c.join(", "));
                    }
                }
                Err(e) => {
                    eprintln!("{e}");
                    std::process::exit(2);
                }
            }
        }
        _ => {
            eprintln!("usage: cargo run -p xtask -- tidy | circles SRC");
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
