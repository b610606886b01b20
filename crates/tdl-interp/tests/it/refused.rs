//! What the interpreter refuses, it refuses when the program is loaded, with located
//! diagnostics.

use tdl_interp::{LoadError, Program, Registry};

fn refusal(src: &str) -> String {
    match Program::from_sources(&[("bad.tdl".into(), src.into())], &Registry::new()) {
        Ok(_) => panic!("loaded a program that should be refused"),
        Err(LoadError::Invalid(text)) => text,
        Err(other) => panic!("refused for another reason: {other}"),
    }
}

#[test]
fn an_unknown_task_is_refused_naming_it() {
    let text = refusal("goal g() {\n    spawn dig(1.0);\n}\n");
    assert!(
        text.contains("`dig` is not a task of the program"),
        "{text}"
    );
    assert!(text.contains("bad.tdl:2"), "{text}");
}

#[test]
fn an_unknown_function_is_refused_naming_it() {
    let text = refusal("command c() {\n    let x = compute(2);\n}\n");
    assert!(
        text.contains("cannot find the function `compute`"),
        "{text}"
    );
    assert!(text.contains("bad.tdl:2"), "{text}");
}

#[test]
fn a_construct_outside_the_subset_is_refused_saying_the_compiler_accepts_it() {
    let text = refusal("command c() {\n    let f = async { 1 };\n}\n");
    assert!(
        text.contains("an `async` block is not in the interpreted subset"),
        "{text}"
    );
    assert!(text.contains("the compiled path"), "{text}");
}

#[test]
fn an_extern_task_no_registry_offers_is_refused_naming_it() {
    let text = refusal(
        "extern command dig(x: f64, y: f64) -> f64;\n\ngoal g() {\n    let d = spawn dig(1.0, 2.0) with wait;\n}\n",
    );
    assert!(
        text.contains("declares the extern command `dig`, which no registry offers"),
        "{text}"
    );
    assert!(text.contains("bad.tdl:1"), "{text}");
}

#[test]
fn a_spawn_of_an_extern_task_with_the_wrong_count_is_refused() {
    let mut r = Registry::new();
    r.task("dig", |x: f64, y: f64| {
        tdl::Task::command(
            "dig",
            move |_| async move { Ok::<f64, tdl::Failure>(x + y) },
        )
    });
    let src = "extern command dig(x: f64, y: f64) -> f64;\n\ngoal g() {\n    spawn dig(1.0);\n}\n";
    let text = match Program::from_sources(&[("bad.tdl".into(), src.into())], &r) {
        Ok(_) => panic!("loaded a spawn with one argument of two"),
        Err(e) => e.to_string(),
    };
    assert!(text.contains("takes 2 argument(s)"), "{text}");
    assert!(text.contains("bad.tdl:4"), "{text}");
}
