//! Unit tests of the code generator: the generated text for small programs.

use crate::{compile_str, pretty};

fn expand(src: &str) -> String {
    let (tokens, diags) = compile_str("t.tdl", src);
    let text: Vec<String> = diags.iter().map(|d| d.render("t.tdl", Some(src))).collect();
    match tokens {
        Some(tokens) => pretty(&tokens),
        None => panic!("unexpected errors:\n{}", text.join("\n")),
    }
}

fn errors(src: &str) -> Vec<String> {
    let (tokens, diags) = compile_str("t.tdl", src);
    assert!(tokens.is_none(), "expected errors");
    diags
        .iter()
        .filter(|d| d.is_error())
        .map(|d| d.message().to_owned())
        .collect()
}

#[test]
fn fig4() {
    let src = include_str!("../../test_data/ok/fig4_deliver_mail.tdl");
    let out = expand(src);
    for line in [
        "struct DeliverMail {",
        "fn deliver_mail(room: u32) -> ::tdl::Task {",
        "let tdl_monitor_pickup = ctx.reserve(\"monitor_pickup\")?;",
        ".fulfils(tdl_monitor_pickup)",
        "tdl_spawn = tdl_spawn.sequential(::tdl::Facet::Execution, node);",
        ".terminate_in(::std::time::Duration::from_secs(30))",
        "::tdl::Event::new(tdl_monitor_pickup, ::tdl::Point::Completed),",
        ".wait_value::<i32>()",
        ".with(::tdl::Constraint::DelayExpansion)",
        "let tdl_result: i32 = { robot::look_for_door().await };",
    ] {
        assert!(out.contains(line), "missing {line:?} in:\n{out}");
    }
}

#[test]
fn iteration_tags_use_counted_loops_and_slots() {
    let out = expand(include_str!("../../test_data/ok/loops_iteration_tags.tdl"));
    assert!(out.contains("let mut tdl_n_0: i64 = 0;"), "{out}");
    assert!(
        out.contains("tdl_slot(&ctx, &mut tdl_turn, [(i - 1) as i64], \"turn\")?"),
        "{out}"
    );
    assert!(out.contains("tdl_visit.values().copied()"), "{out}");
}

#[test]
fn nested_groups_snapshot_previous_for_the_outer_group() {
    let out = expand(include_str!(
        "../../test_data/ok/with_groups_deliver_mail.tdl"
    ));
    assert!(out.contains("let tdl_prev_1 = tdl_prev.clone();"), "{out}");
    assert!(out.contains("tdl_prev = tdl_group_1;"), "{out}");
}

#[test]
fn exceptions_become_error_types() {
    let out = expand("exception A; exception B : A { x: u32 } command c() { fail B { x: 1 }; }");
    assert!(out.contains("pub const PARENT: ::core::option::Option<&'static str> = ::core::option::Option::Some(\"A\");") || out.contains("const PARENT"), "{out}");
    assert!(out.contains("impl ::std::error::Error for B {}"), "{out}");
    assert!(out.contains("::tdl::Failure::from(B { x: 1 })"), "{out}");
}

#[test]
fn monitors_are_reported() {
    let src = include_str!("../../test_data/ok/fig6_monitor_pickup.tdl");
    let errs = errors(src);
    assert_eq!(
        errs,
        [
            "monitors are not supported by the code generator yet",
            "monitors are not supported by the code generator yet"
        ],
        "one per monitor"
    );
}
