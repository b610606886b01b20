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

/// Whether `out` contains `needle`, ignoring whitespace and commas (prettyplease wraps lines by
/// depth, adding trailing commas).
fn has(out: &str, needle: &str) -> bool {
    let squash = |s: &str| s.split_whitespace().collect::<String>().replace(',', "");
    squash(out).contains(&squash(needle))
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
        assert!(has(&out, line), "missing {line:?} in:\n{out}");
    }
}

#[test]
fn iteration_tags_use_counted_loops_and_slots() {
    let out = expand(include_str!("../../test_data/ok/loops_iteration_tags.tdl"));
    assert!(has(&out, "let mut tdl_n_0: i64 = 0;"), "{out}");
    assert!(
        has(
            &out,
            "tdl_slot(&ctx, &mut tdl_turn, [(i - 1) as i64], \"turn\")?"
        ),
        "{out}"
    );
    assert!(has(&out, "tdl_visit.values().copied()"), "{out}");
}

#[test]
fn nested_groups_snapshot_previous_for_the_outer_group() {
    let out = expand(include_str!(
        "../../test_data/ok/with_groups_deliver_mail.tdl"
    ));
    assert!(has(&out, "let tdl_prev_1 = tdl_prev.clone();"), "{out}");
    assert!(has(&out, "tdl_prev = tdl_group_1;"), "{out}");
}

#[test]
fn exceptions_become_error_types() {
    let out = expand("exception A; exception B : A { x: u32 } command c() { fail B { x: 1 }; }");
    assert!(has(&out, "impl ::tdl::Exception for B {"), "{out}");
    assert!(has(&out, "&[\"A\"]"), "{out}");
    assert!(has(&out, "impl ::std::error::Error for B {}"), "{out}");
    assert!(has(&out, "::tdl::Exception::raise(B { x: 1 })"), "{out}");
}

#[test]
fn fig6_monitor_becomes_a_tcm_monitor() {
    let out = expand(include_str!("../../test_data/ok/fig6_monitor_pickup.tdl"));
    for line in [
        "::tdl::Task::monitor(",
        "max_triggers: ::core::option::Option::Some(1),",
        "max_activations: ::core::option::Option::Some(15),",
        "::std::time::Duration::from_millis(1500),",
        "ctx.trigger()?;",
        "ctx.hold_children(true)?;",
    ] {
        assert!(has(&out, line), "missing {line:?} in:\n{out}");
    }
}

#[test]
fn handlers_bind_the_exception_and_persistent_state() {
    let out = expand(
        "exception A; exception B : A { x: u32 } exception C : B;
         handler h(limit: u32) handles B with maximum activate 2, persistent n: u32 = 0 {
             n += 1;
             if exception.x > limit { bypass; }
             retry;
         }
         command c() with exception handler h(3) { fail C; }",
    );
    for line in [
        "::tdl::Handler::new(",
        "let exception: ::std::sync::Arc<B> = ::tdl::codegen::caught::<B>(&ctx, \"h\")?;",
        "let mut n: u32 = tdl_persistent_n.load();",
        "tdl_persistent_n.store(n);",
        "return ctx.bypass();",
        "let tdl_retry = ctx.retry()?;",
        ".max_activations(2)",
        "&[\"B\", \"A\"]",
        "::tdl::Exception::raise(C {})",
        ".handler(tdl_handler_0)",
    ] {
        assert!(has(&out, line), "missing {line:?} in:\n{out}");
    }
}

#[test]
fn monitor_settings_in_a_constraint_statement_are_refused() {
    let errs = errors(
        "monitor m() { trigger; } goal g() { w: spawn m(); w maximum trigger 3; w activate; }",
    );
    assert_eq!(errs, ["this constraint can only be given on the spawn"]);
}

#[test]
fn handler_locals_are_bound_when_named_even_in_format_strings() {
    let out = expand(include_str!("../../test_data/ok/handlers_retry.tdl"));
    for line in [
        "let failing: ::tdl::NodeId = ::tdl::codegen::failing_node(&ctx)?;",
        "let attached: ::tdl::NodeId = ::tdl::codegen::attached_node(&ctx)?;",
        "::tdl::codegen::caught::<Blocked>(&ctx, \"retry_move\")?;",
    ] {
        assert!(has(&out, line), "missing {line:?} in:\n{out}");
    }
    let plain = expand("exception E; handler h() handles E { log(1); }");
    assert!(!has(&plain, "let failing"), "{plain}");
    assert!(!has(&plain, "let exception"), "{plain}");
}

#[test]
fn every_body_holds_its_children_and_goals_are_retryable() {
    let out = expand("command c(n: u32) { log(n); } goal g() { spawn c(1); }");
    assert_eq!(out.matches("ctx.hold_children(true)?;").count(), 2, "{out}");
    assert!(
        has(&out, "::tdl::Task::retryable(::tdl::NodeKind::Goal,"),
        "{out}"
    );
    assert!(has(&out, "let tdl_args = (&tdl_args).tdl_args();"), "{out}");
}

#[test]
fn raw_and_odd_names_do_not_panic() {
    // Found while preparing the fuzz target: `r#` labels and names that are not CamelCase-able.
    let out = expand(
        "goal r#type(r#in: u32) { r#a: spawn x(r#in); r#a wait; spawn r#y(); spawn z() with sequential execution r#y; }
         goal __() {} command self_() {} command _1() {}
         monitor m() with persistent r#p: u32 = 0 { r#p += 1; }",
    );
    for line in [
        "struct Type {",
        "let tdl_a = ctx.reserve(\"x\")?;",
        "struct Task___ {}",
        "struct Task_self_ {}",
        "struct Task__1 {}",
        "tdl_persistent_p.store(r#p);",
    ] {
        assert!(has(&out, line), "missing {line:?} in:\n{out}");
    }
}
