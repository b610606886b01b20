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
        ".with(::tdl::Constraint::Trigger(::tdl::When::In(::std::time::Duration::from_secs(30)), ::tdl::Then::Terminate))",
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

#[test]
fn every_trigger_lowers_to_one_when_and_then() {
    let out = expand(
        "monitor m() { trigger; }
         goal g() {
             a: spawn work();
             w: spawn m() with activate, activate at a completed, activate in 1s after a active,
                 activate at 9:30:00, activate in 200ms;
             spawn work() with disable until a completed, disable execution for 2s,
                 disable expansion for 1s after a expansion completed, disable until 13:00:00,
                 terminate, terminate at 6:00:00, terminate in 1s after a completed;
             a terminate in 2s;
             w activate;
             a terminate;
         }",
    );
    let trigger = |when: &str, then: &str| {
        format!(".with(::tdl::Constraint::Trigger(::tdl::When::{when}, ::tdl::Then::{then}))")
    };
    let a_completed = "::tdl::Event::new(tdl_a, ::tdl::Point::Completed)";
    for line in [
        trigger("Now", "Activate"),
        trigger(&format!("Event({a_completed})"), "Activate"),
        trigger(
            "After(::std::time::Duration::from_secs(1), ::tdl::Event::new(tdl_a, ::tdl::Point::Active))",
            "Activate",
        ),
        trigger("At(ctx.time_of_day(34200.0))", "Activate"),
        trigger("In(::std::time::Duration::from_millis(200))", "Activate"),
        trigger(
            &format!("Event({a_completed})"),
            "Enable(::tdl::Facet::Handling)",
        ),
        trigger(
            "In(::std::time::Duration::from_secs(2))",
            "Enable(::tdl::Facet::Execution)",
        ),
        trigger(
            "After(::std::time::Duration::from_secs(1), ::tdl::Event::on(tdl_a, ::tdl::Facet::Expansion, ::tdl::Point::Completed))",
            "Enable(::tdl::Facet::Expansion)",
        ),
        trigger(
            "At(ctx.time_of_day(46800.0))",
            "Enable(::tdl::Facet::Handling)",
        ),
        trigger("Now", "Terminate"),
        trigger("At(ctx.time_of_day(21600.0))", "Terminate"),
        trigger(
            &format!("After(::std::time::Duration::from_secs(1), {a_completed})"),
            "Terminate",
        ),
        "ctx.constrain(tdl_a, ::tdl::Constraint::Trigger(::tdl::When::In(::std::time::Duration::from_secs(2)), ::tdl::Then::Terminate))?;".to_owned(),
        "ctx.constrain(tdl_w, ::tdl::Constraint::Trigger(::tdl::When::Now, ::tdl::Then::Activate))?;".to_owned(),
        "ctx.terminate(tdl_a)?;".to_owned(),
    ] {
        assert!(has(&out, &line), "missing {line:?} in:\n{out}");
    }
    for gone in [
        "Until",
        "TerminateWhen",
        "ActivateWhen",
        ".terminate_in(",
        ".disable_until(",
    ] {
        assert!(!out.contains(gone), "{gone:?} in:\n{out}");
    }
}

#[test]
fn triggers_on_a_group_or_loop_tag_apply_once_per_node() {
    let out = expand(
        "goal g(n: u32) {
             grp: with (parallel) { spawn a(); spawn b(); }
             for i in 0..n { mv: spawn move_by(i); }
             spawn c() with terminate at grp completed, disable until mv completed;
         }",
    );
    for line in [
        "for &node in &tdl_grp { tdl_spawn = tdl_spawn.with(::tdl::Constraint::Trigger(::tdl::When::Event(::tdl::Event::new(node, ::tdl::Point::Completed)), ::tdl::Then::Terminate)); }",
        "for node in tdl_mv.values().copied().collect::<::std::vec::Vec<_>>() {",
        "::tdl::When::Event(::tdl::Event::new(node, ::tdl::Point::Completed)), ::tdl::Then::Enable(::tdl::Facet::Handling)",
    ] {
        assert!(has(&out, line), "missing {line:?} in:\n{out}");
    }
}
