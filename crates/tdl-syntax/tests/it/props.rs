//! Property test: random token soup never panics the front end, and every diagnostic points at
//! a real line and column of the input.

use proptest::prelude::*;

/// Fragments drawn at random: TDL keywords, identifiers, punctuation, literals and brackets,
/// including unbalanced ones.
const FRAGMENTS: &[&str] = &[
    "goal",
    "command",
    "monitor",
    "handler",
    "handles",
    "exception",
    "persistent",
    "pub",
    "spawn",
    "with",
    "succeed",
    "fail",
    "bypass",
    "trigger",
    "let",
    "if",
    "else",
    "for",
    "in",
    "while",
    "loop",
    "match",
    "fn",
    "use",
    "struct",
    "sequential",
    "execution",
    "expansion",
    "handling",
    "planning",
    "serial",
    "parallel",
    "wait",
    "expand",
    "first",
    "delay",
    "disable",
    "until",
    "for",
    "after",
    "terminate",
    "at",
    "activate",
    "maximum",
    "trigger",
    "period",
    "on",
    "name",
    "previous",
    "self",
    "parent",
    "child",
    "this",
    "enabled",
    "active",
    "completed",
    "expand_first",
    "disable_until",
    "terminate_at",
    "max_activations",
    "a",
    "b",
    "t1",
    "move_by",
    "x",
    "(",
    ")",
    "{",
    "}",
    "[",
    "]",
    "(",
    ")",
    "{",
    "}",
    ";",
    ";",
    ",",
    ",",
    ":",
    "::",
    ".",
    "=",
    "=>",
    "->",
    "-",
    "+",
    "<",
    ">",
    "!",
    "#",
    "'a",
    "&",
    "|",
    "?",
    "0",
    "1",
    "30s",
    "1.5s",
    "200ms",
    "0:0:30.0",
    "13:00:00",
    "25:61:99",
    "3days",
    "1e400s",
    "\"str\"",
    "'c'",
    "*/",
    "//",
    "\n",
    "\t",
    "r#\"raw\"#",
    "b'x'",
    "é",
    "@",
    "$",
    "~",
    "1__0",
    "1.",
    ".5",
];

/// Fragments that make the lexer fail: unterminated strings and comments, stray characters.
const BREAKERS: &[&str] = &[
    "\"unterminated",
    "/*",
    "'",
    "\\",
    "€",
    "🤖",
    "\u{0}",
    "`",
    "0x",
    "1e",
];

/// Cases per property: 512 by default, `PROPTEST_CASES=N` for a longer run.
fn cases() -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|it| it.parse().ok())
        .unwrap_or(512)
}

fn soup() -> impl Strategy<Value = String> {
    proptest::collection::vec(proptest::sample::select(FRAGMENTS), 0..60)
        .prop_map(|parts| parts.join(" "))
}

/// Soup with one lexer-breaking fragment spliced in.
fn broken_soup() -> impl Strategy<Value = String> {
    (soup(), proptest::sample::select(BREAKERS), 0..60usize).prop_map(|(src, breaker, at)| {
        let mut parts: Vec<&str> = src.split(' ').collect();
        parts.insert(at.min(parts.len()), breaker);
        parts.join(" ")
    })
}

/// A valid-looking program with one random fragment spliced in somewhere.
fn mutated_program() -> impl Strategy<Value = String> {
    const PROGRAM: &str = "goal g(x: u32) with delay expansion {\n    t1: spawn a(x) with serial previous, terminate in 30s;\n    with (parallel) { spawn b(); spawn c(); }\n    t1 wait;\n}\nmonitor m() with period 1s { trigger; }\n";
    (0..PROGRAM.len(), proptest::sample::select(FRAGMENTS)).prop_map(|(at, fragment)| {
        let at = (0..=at)
            .rev()
            .find(|it| PROGRAM.is_char_boundary(*it))
            .unwrap_or(0);
        format!("{} {fragment} {}", &PROGRAM[..at], &PROGRAM[at..])
    })
}

fn check_positions(src: &str) {
    let parse = tdl_syntax::parse_str("soup.tdl", src);
    let n_lines = src.split('\n').count().max(1);
    for diag in &parse.diagnostics {
        assert!(
            (1..=n_lines).contains(&diag.line()),
            "line {} outside 1..={n_lines} for {:?} in {src:?}",
            diag.line(),
            diag.message()
        );
        assert!(diag.column() >= 1);
        assert!(!diag.message().is_empty());
        // Rendering must not panic either.
        let _ = diag.render("soup.tdl", Some(src));
    }
    let _ = tdl_syntax::dump(&parse.file);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases()))]

    #[test]
    fn random_tokens_never_panic(src in soup()) {
        check_positions(&src);
    }

    #[test]
    fn lexer_errors_never_panic(src in broken_soup()) {
        check_positions(&src);
    }

    #[test]
    fn mutated_programs_never_panic(src in mutated_program()) {
        check_positions(&src);
    }
}
