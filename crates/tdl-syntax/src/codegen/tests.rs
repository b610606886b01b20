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

/// Whether `out` contains `needle`, ignoring whitespace, commas (prettyplease wraps lines by
/// depth, adding trailing commas) and the comments naming source lines.
fn has(out: &str, needle: &str) -> bool {
    let uncommented: String = out
        .lines()
        .map(|line| line.split(" // t.tdl:").next().unwrap_or(line))
        .collect();
    let squash = |s: &str| s.split_whitespace().collect::<String>().replace(',', "");
    squash(&uncommented).contains(&squash(needle))
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
    assert!(
        has(
            &out,
            "tdl_prev = ::core::option::Option::Some(tdl_group_1);"
        ),
        "{out}"
    );
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
         handler h(limit: u32) handles B as b with maximum activate 2, persistent n: u32 = 0 {
             n += 1;
             if b.data().is_some_and(|it| it.x > limit) { bypass; }
             retry;
         }
         command c() with exception handler h(3) { fail C; }",
    );
    for line in [
        "::tdl::Handler::new(",
        "let b: ::tdl::Caught<B> = ::tdl::codegen::caught::<B>(&ctx, \"h\")?;",
        "::tdl::Handler::new(\"h\", ::tdl::codegen::handles::<B>(\"B\"),",
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
fn monitor_limits_in_groups_and_constraint_statements() {
    // Catalogue 1.4: a group's value, then the spawn's own (the last wins); a constraint statement
    // sets it again at run time.
    let out = expand(
        "monitor m() { trigger; }
         goal g() {
             with (maximum activate 5, period 2s) { w: spawn m() with maximum activate 2; }
             w maximum trigger 3;
             w maximum activate (4 + 1);
             w period 0.5;
         }",
    );
    for line in [
        ".max_activations(5).period(::std::time::Duration::from_secs(2)).max_activations(2)",
        "ctx.set_max_triggers(tdl_w, 3)?;",
        "ctx.set_max_activations(tdl_w, ::tdl::codegen::count((4 + 1)))?;",
        "ctx.set_period(tdl_w, ::std::time::Duration::from_millis(500))?;",
    ] {
        assert!(has(&out, line), "missing {line:?} in:\n{out}");
    }
    // What only goes on a spawn is refused in a statement.
    let errs = errors(
        "monitor m() { trigger; }
         goal g() { w: spawn m(); w maximum trigger 3; w name \"x\"; w parent p; }",
    );
    assert_eq!(
        errs,
        [
            "this constraint can only be given on the spawn",
            "this constraint can only be given on the spawn"
        ]
    );
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
    assert!(!has(&plain, "codegen::caught"), "{plain}");
    // Issue 12, point 1: without `as`, nothing is bound, and a word `exception` (here a struct
    // field) is plain Rust.
    let field = expand(
        "exception E; handler h() handles E { let failure = ctx.failure(); log(failure.map(|f| f.exception.clone())); }",
    );
    assert!(!has(&field, "codegen::caught"), "{field}");
    assert!(has(&field, "f.exception.clone()"), "{field}");
    // Likewise a field named `failing` binds no `failing` local (it would be unused).
    let field = expand("exception E; handler h() handles E { let r = (1, 2); log(r.failing); }");
    assert!(!has(&field, "let failing"), "{field}");
}

#[test]
fn every_body_holds_its_children_and_goals_are_retryable() {
    let out = expand("command c(n: u32) { log(n); } goal g() { spawn c(1); }");
    assert_eq!(out.matches("ctx.hold_children(true)?;").count(), 2, "{out}");
    // Neither body awaits: both are synchronous actions, retryable.
    assert!(
        has(&out, "::tdl::Task::retryable_now(::tdl::NodeKind::Goal,"),
        "{out}"
    );
    assert!(
        has(&out, "::tdl::Task::retryable_now(::tdl::NodeKind::Command,"),
        "{out}"
    );
    assert!(
        has(&out, "let tdl_args = (&tdl_args).tdl_args_in(&ctx);"),
        "{out}"
    );
    // The tuple of the arguments is kept beside each node (wiretap checks, `retry_with`).
    assert!(has(&out, ".with_args_erased(tdl_kept)"), "{out}");
    // A body that awaits (a wait, Rust's `.await`) is an async action.
    let out =
        expand("command c() { tokio::task::yield_now().await; } goal g() { spawn c() with wait; }");
    assert_eq!(out.matches("::tdl::Task::retryable(").count(), 2, "{out}");
    assert!(!has(&out, "retryable_now"), "{out}");
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
fn external_events_are_bound_by_name_where_the_constraint_is_applied() {
    // The id comes from `ctx.external` at the spawn or the statement, not at compile time, so
    // one program serves any run; a computed name is borrowed, not moved.
    let out = expand(
        "monitor m() { trigger; }
         goal g(topic: String) {
             a: spawn work() with terminate at external \"stop\";
             spawn work() with disable execution until external (topic);
             w: spawn m() with activate at external \"tick\";
             a disable until external \"go\";
         }",
    );
    let external = |name: &str, then: &str| {
        format!(
            "::tdl::Constraint::Trigger(::tdl::When::External(ctx.external({name})?), ::tdl::Then::{then})"
        )
    };
    for line in [
        format!(".with({})", external("\"stop\"", "Terminate")),
        format!(
            ".with({})",
            external(
                "::core::convert::AsRef::<str>::as_ref(&(topic))",
                "Enable(::tdl::Facet::Execution)"
            )
        ),
        format!(".with({})", external("\"tick\"", "Activate")),
        format!(
            "ctx.constrain(tdl_a, {})?;",
            external("\"go\"", "Enable(::tdl::Facet::Handling)")
        ),
    ] {
        assert!(has(&out, &line), "missing {line:?} in:\n{out}");
    }
}

#[test]
fn triggers_on_a_group_or_loop_tag_apply_to_the_whole_entity() {
    // Enablement once per member; `terminate at` the group once every member got there, armed
    // when the node exists.
    let out = expand(
        "goal g(n: u32) {
             grp: with (parallel) { spawn a(); spawn b(); }
             for i in 0..n { mv: spawn move_by(i); }
             spawn c() with terminate at grp completed, disable until mv completed;
         }",
    );
    for line in [
        "for &node in ::core::option::Option::unwrap_or_default(::core::option::Option::Some((tdl_mv.values().copied().collect::<::std::vec::Vec<_>>()).as_slice())) {",
        "::tdl::When::Event(::tdl::Event::new(node, ::tdl::Point::Completed)), ::tdl::Then::Enable(::tdl::Facet::Handling)",
        "let tdl_node = tdl_spawn.start()?;",
        "::tdl::codegen::trigger_entity(&ctx, tdl_node, ::core::option::Option::Some(tdl_grp.as_slice()), ::tdl::Facet::Execution, ::tdl::Point::Completed, ::core::option::Option::None, ::tdl::Then::Terminate)?;",
    ] {
        assert!(has(&out, line), "missing {line:?} in:\n{out}");
    }
}

#[test]
fn previous_is_none_before_anything_and_a_missing_after_event_keeps_the_delay() {
    let out = expand(
        "monitor m() { trigger; }
         goal g() {
             spawn a() with disable for 2s after previous completed;
             spawn b() with terminate in 3s after previous active;
             w: spawn m() with activate in 1s after previous completed;
         }",
    );
    for line in [
        "let mut tdl_prev: ::core::option::Option<::std::vec::Vec<::tdl::NodeId>> = ::core::option::Option::None;",
        "if ::tdl::codegen::no_members(tdl_prev.as_deref()) { tdl_spawn = tdl_spawn.with(::tdl::Constraint::Trigger(::tdl::When::In(::std::time::Duration::from_secs(2)), ::tdl::Then::Enable(::tdl::Facet::Handling))); }",
        "::tdl::codegen::trigger_entity(&ctx, tdl_node, tdl_prev.as_deref(), ::tdl::Facet::Handling, ::tdl::Point::Active, ::core::option::Option::Some(::std::time::Duration::from_secs(3)), ::tdl::Then::Terminate)?;",
        "::tdl::codegen::trigger_entity(&ctx, tdl_node, tdl_prev.as_deref(), ::tdl::Facet::Execution, ::tdl::Point::Completed, ::core::option::Option::Some(::std::time::Duration::from_secs(1)), ::tdl::Then::Activate)?;",
        "tdl_prev = ::core::option::Option::Some(::std::vec![tdl_node]);",
    ] {
        assert!(has(&out, line), "missing {line:?} in:\n{out}");
    }
}

#[test]
fn several_task_level_on_terminate_tasks_each_get_a_local() {
    let out = expand(
        "command release() {} command stow() {}
         goal grasp() with on terminate spawn release(), on terminate stow() { work(); }",
    );
    for line in [
        "let tdl_on_terminate_0 = release();",
        "let tdl_on_terminate_1 = stow();",
        ".on_terminate(tdl_on_terminate_0).on_terminate(tdl_on_terminate_1)",
    ] {
        assert!(has(&out, line), "missing {line:?} in:\n{out}");
    }
}

#[test]
fn on_terminate_labels_are_reservations_the_spawn_fulfils() {
    let out = expand(
        "goal g() {
             spawn report() with sequential execution one;
             h: spawn hold() with on terminate one: spawn release(), on terminate two: spawn stow();
             two serial one;
             for i in 0..3 { spawn grip(i) with on terminate g1: spawn drop(i); g1[.] wait; }
         }",
    );
    for line in [
        "let tdl_one = ctx.reserve(\"release\")?;",
        "let tdl_two = ctx.reserve(\"stow\")?;",
        ".on_terminate_fulfils(release(), tdl_one).on_terminate_fulfils(stow(), tdl_two)",
        "ctx.constrain(tdl_two, ::tdl::Constraint::Serial(::tdl::NodeRef::from(tdl_one)))?;",
        ".on_terminate_fulfils(drop(i), tdl_slot(&ctx, &mut tdl_g1, [tdl_i_0], \"drop\")?)",
    ] {
        assert!(has(&out, line), "missing {line:?} in:\n{out}");
    }
    let errs = errors("goal g() with on terminate c: spawn cleanup() { work(); }");
    assert_eq!(errs, ["a task-level `on terminate` takes no label"]);
}

#[test]
fn node_bind_and_parent() {
    let out = expand(
        "goal g(up: tdl::NodeId) {
             a: spawn work();
             let me = node!(parent);
             log(node!(a), me);
             for i in 0..2 { s: spawn step(i); log(node!(s[.])); }
             bind door = up;
             door terminate;
             spawn other() with serial door;
             u: spawn under() with parent node!(door);
             spawn after() with terminate at u completed;
             log(node!(u));
         }",
    );
    for line in [
        "let mut tdl_door: ::core::option::Option<::tdl::NodeId> = ::core::option::Option::None;",
        "let mut tdl_u: ::core::option::Option<::tdl::NodeId> = ::core::option::Option::None;",
        "let me = (ctx.node());",
        "log((tdl_a), me);",
        "log((tdl_slot(&ctx, &mut tdl_s, [tdl_i_0], \"step\")?));",
        "tdl_door = ::core::option::Option::Some::<::tdl::NodeId>(up);",
        "for &target in ::core::option::Option::unwrap_or_default(::core::option::Option::Some(tdl_door.as_slice())) { ctx.terminate(target)?; }",
        ".under((::tdl::codegen::bound(tdl_door, \"door\")?))",
        "tdl_u = ::core::option::Option::Some(tdl_node);",
        "::tdl::codegen::trigger_entity(&ctx, tdl_node, ::core::option::Option::Some(tdl_u.as_slice()),",
        "log((::tdl::codegen::bound(tdl_u, \"u\")?));",
        "#[allow(unused_assignments)]",
    ] {
        assert!(has(&out, line), "missing {line:?} in:\n{out}");
    }
}

/// Issue 12, point 9: each line generated for a body statement of a `.tdl` file ends with a
/// comment naming the file and the statement's line, so that rustc's snippet of an error in
/// generated code names the `.tdl` line.
#[test]
fn generated_lines_name_their_tdl_line() {
    let src = "command step(i: u32) {}
goal walk(n: u32) {
    let x: u32 = \"a\";
    for i in 0..n {
        spawn step(i + x)
            with sequential execution previous;
    }
    let s = \"two
lines\";
    println!(\"{s}\");
}
";
    let (tokens, diags) = crate::compile_program(&[("src/walk.tdl", src)]).remove(0);
    assert!(diags.is_empty(), "{diags:?}");
    let out = pretty(&tokens.expect("no errors"));
    let line_of = |needle: &str| {
        out.lines()
            .find(|line| line.contains(needle))
            .unwrap_or_else(|| panic!("no {needle:?} in:\n{out}"))
    };
    assert!(
        line_of("let x: u32 = \"a\";").ends_with("; // src/walk.tdl:3"),
        "{out}"
    );
    assert!(
        line_of("for i in 0..n {").ends_with("{ // src/walk.tdl:4"),
        "{out}"
    );
    // Every line of the spawn, which the generator spreads over several, names line 5.
    assert!(
        line_of("step(i + x)").ends_with(" // src/walk.tdl:5"),
        "{out}"
    );
    assert!(
        line_of("ctx.spawn").ends_with(" // src/walk.tdl:5"),
        "{out}"
    );
    // A string spanning lines is left as it is.
    assert!(
        out.contains("let s = \"two\nlines\"; // src/walk.tdl:8\n"),
        "{out}"
    );
    assert!(
        line_of("println!").ends_with(" // src/walk.tdl:10"),
        "{out}"
    );
    // The generator's own code after the statements names no line, nor does the task's shell.
    assert!(
        !line_of("::core::result::Result::Ok(())").contains("walk.tdl"),
        "{out}"
    );
    assert!(!line_of("fn walk(n: u32)").contains("walk.tdl"), "{out}");
    assert!(!out.contains("__tdl_source"), "{out}");
}

/// A marker the printer wraps over several lines (a long file name in a deeply nested
/// statement) is still a comment, never code left behind.
#[test]
fn wrapped_source_markers_become_comments_too() {
    let src = "goal walk(n: u32) {
    for i in 0..n {
        if i > 0 {
            while i < n {
                match i {
                    1 => {
                        spawn step(i + 1) with sequential execution previous;
                    }
                    _ => {}
                }
            }
        }
    }
}
";
    let name = "crates/a_crate_with_a_rather_long_name/src/missions/with_a_long_path/walk_the_long_way_round.tdl";
    let (tokens, diags) = crate::compile_program(&[(name, src)]).remove(0);
    assert!(diags.is_empty(), "{diags:?}");
    let out = pretty(&tokens.expect("no errors"));
    assert!(!out.contains("__tdl_source"), "{out}");
    let spawn = out
        .lines()
        .find(|line| line.contains("ctx.spawn"))
        .unwrap_or_else(|| panic!("no spawn in:\n{out}"));
    assert!(spawn.ends_with(&format!(" // {name}:7")), "{out}");
}

/// The `tdl!` macro's expansion carries no source markers: its spans point at the source.
#[test]
fn macro_expansion_has_no_source_markers() {
    let tokens: proc_macro2::TokenStream = "goal walk() { let x = 1; println!(\"{x}\"); }"
        .parse()
        .expect("tokens");
    let out = pretty(&crate::expand_macro(tokens));
    assert!(out.contains("println!(\"{x}\");\n"), "{out}");
    assert!(!out.contains("__tdl_source"), "{out}");
}

#[test]
fn resources_generate_uses_with_their_declarations() {
    let out = expand(include_str!("../../test_data/ok/resources.tdl"));
    for line in [
        // A task-level use and priority go on the task.
        ".uses(::tdl::Resource::new(\"cpu\", 1u32), 1).priority(2i32)",
        // A declared resource is named by its declaration, so the run declares it on first use.
        ".uses(::tdl::Resource::new(\"base\", 1u32), 1).uses(::tdl::Resource::new(\"arm\", 2u32).pending_limit(4u32), 2).priority(-1i32)",
        ".uses(::tdl::Resource::new(\"arm\", 2u32).pending_limit(4u32), ::tdl::codegen::count(n)).deny_if_busy()",
        ".priority((n as i32 + 1))",
        // The runtime's own exceptions, handled without a declaration.
        "::tdl::codegen::handles::<::tdl::ResourceDenied>(\"ResourceDenied\")",
        "let denied: ::tdl::Caught<::tdl::ResourceDenied> = ::tdl::codegen::caught::<::tdl::ResourceDenied>(&ctx, \"retake\")?;",
        // Reserve and lock statements.
        "ctx.reserve_resource(::tdl::Resource::new(\"base\", 1u32), ctx.node())?;",
        "ctx.lock_resource(::tdl::Resource::new(\"camera\", 1u32))?;",
        "ctx.unlock_resource(::tdl::Resource::new(\"camera\", 1u32))?;",
        "ctx.unreserve_resource(::tdl::Resource::new(\"base\", 1u32))?;",
    ] {
        assert!(has(&out, line), "missing {line:?} in:\n{out}");
    }
    // A resource the program does not declare is named, for the runtime to have declared it.
    let out = expand("command c() {} goal g() { spawn c() with uses lidar(2); }");
    assert!(has(&out, ".uses(\"lidar\", 2)"), "{out}");
}

#[test]
fn resource_misuse_is_an_error() {
    assert_eq!(
        errors("resource arm(2); command c() {} goal g() { spawn c() with uses arm(3); }"),
        ["asks for 3 of `arm`, whose capacity is 2"]
    );
}

#[test]
fn an_idempotent_command_is_declared_so_to_the_runtime() {
    let out = expand("idempotent command home() {} goal g() { spawn home(); }");
    assert_eq!(out.matches(".idempotent()").count(), 1, "{out}");
    let errs = errors("idempotent goal g() {}");
    assert!(
        errs.iter()
            .any(|e| e.contains("a goal cannot be `idempotent`")),
        "{errs:?}"
    );
}

#[test]
fn a_blocking_command_runs_its_body_on_a_blocking_thread() {
    let out = expand("blocking command plan(n: u32) -> u32 { n + 1 } goal g() { spawn plan(1); }");
    assert!(has(&out, "ctx.blocking(move |ctx| {"), "{out}");
    assert!(
        has(&out, "::core::result::Result::Ok(tdl_result)}).await"),
        "{out}"
    );
    assert_eq!(
        out.matches("ctx.blocking(").count(),
        1,
        "the goal is async: {out}"
    );
}

#[test]
fn state_and_conditions_generate_declarations_conditions_and_their_constraints() {
    let out = expand(include_str!("../../test_data/ok/state_conditions.tdl"));
    let healthy =
        "::tdl::StateVar::new(\"healthy\", ::tdl::StateType::Bool, ::tdl::StateValue::Bool(true))";
    let battery = "::tdl::StateVar::new(\"battery\", ::tdl::StateType::Float, ::tdl::StateValue::Float(100f64))";
    let errors =
        "::tdl::StateVar::new(\"errors\", ::tdl::StateType::Int, ::tdl::StateValue::Unknown)";
    let mode = "::tdl::StateVar::new(\"mode\", ::tdl::StateType::Str, ::tdl::StateValue::Str(::std::string::String::from(\"auto\")))";
    let position =
        "::tdl::StateVar::new(\"position\", ::tdl::StateType::Float, ::tdl::StateValue::Unknown)";
    let floor =
        "::tdl::StateVar::new(\"floor\", ::tdl::StateType::Int, ::tdl::StateValue::Int(-2i64))";
    let not_healthy =
        format!("ctx.condition(&[{healthy}], ::tdl::Expr::not(::tdl::Expr::var(\"healthy\")))?");
    for line in [
        // pause while !healthy
        format!(".with(::tdl::Constraint::pause_while({not_healthy}))"),
        // disable until healthy && battery > 20.5: the default facet, each variable declared
        format!(
            ".with(::tdl::Constraint::disable(::tdl::Facet::Handling, ::tdl::When::Condition(\
             ctx.condition(&[{healthy}, {battery}], ::tdl::Expr::bin(::tdl::BinOp::And, \
             ::tdl::Expr::var(\"healthy\"), ::tdl::Expr::bin(::tdl::BinOp::Gt, \
             ::tdl::Expr::var(\"battery\"), ::tdl::Expr::lit(20.5f64))))?)))"
        ),
        format!(
            ".with(::tdl::Constraint::disable(::tdl::Facet::Execution, ::tdl::When::Condition(\
             ctx.condition(&[{errors}, {mode}], ::tdl::Expr::bin(::tdl::BinOp::Or, \
             ::tdl::Expr::bin(::tdl::BinOp::Eq, ::tdl::Expr::var(\"errors\"), ::tdl::Expr::lit(0i64)), \
             ::tdl::Expr::bin(::tdl::BinOp::Ne, ::tdl::Expr::var(\"mode\"), ::tdl::Expr::lit(\"auto\"))))?)))"
        ),
        format!(
            ".with(::tdl::Constraint::skip_if(ctx.condition(&[{position}], \
             ::tdl::Expr::not(::tdl::Expr::known(::tdl::Expr::var(\"position\"))))?))"
        ),
        format!(".with(::tdl::Constraint::invariant(ctx.condition(&[{battery}, {healthy}],"),
        // terminate when errors > 3 * floor + -1: a negative literal is one literal
        format!(
            ".with(::tdl::Constraint::terminate(::tdl::When::Condition(ctx.condition(&[{errors}, {floor}], \
             ::tdl::Expr::bin(::tdl::BinOp::Gt, ::tdl::Expr::var(\"errors\"), ::tdl::Expr::bin(\
             ::tdl::BinOp::Add, ::tdl::Expr::bin(::tdl::BinOp::Mul, ::tdl::Expr::lit(3i64), \
             ::tdl::Expr::var(\"floor\")), ::tdl::Expr::lit(-1i64))))?)))"
        ),
        format!(
            ".with(::tdl::Constraint::activate(::tdl::When::Condition(ctx.condition(&[{battery}], \
             ::tdl::Expr::bin(::tdl::BinOp::Lt, ::tdl::Expr::var(\"battery\"), ::tdl::Expr::lit(20f64)))?)))"
        ),
        format!(
            ".with(::tdl::Constraint::activate(::tdl::When::Changed(ctx.state_var(&{mode})?)))"
        ),
        // A constraint statement.
        format!(
            "ctx.constrain(tdl_w, ::tdl::Constraint::terminate(::tdl::When::Condition(ctx.condition(&[{mode}], \
             ::tdl::Expr::bin(::tdl::BinOp::Eq, ::tdl::Expr::var(\"mode\"), ::tdl::Expr::lit(\"off\")))?)))?;"
        ),
        // A `with` group's conditions on its spawn.
        format!(
            ".with(::tdl::Constraint::pause_while({not_healthy})).with(::tdl::Constraint::skip_if("
        ),
        // -(errors - 1) * 2 / 3 <= floor
        "::tdl::Expr::Neg(::std::boxed::Box::new(::tdl::Expr::bin(::tdl::BinOp::Sub, \
         ::tdl::Expr::var(\"errors\"), ::tdl::Expr::lit(1i64))))"
            .to_owned(),
        format!("ctx.set_state(&{battery}, v)?;"),
        format!("ctx.set_state(&{errors}, (ctx.read_state::<i64>(&{errors})?).unwrap_or(0) + 1)?;"),
        format!("ctx.set_state(&{position}, ::tdl::StateValue::Unknown)?;"),
        format!("ctx.set_state(&{mode}, \"manual\")?;"),
        "ctx.raise(\"step_done\")?;".to_owned(),
        "ctx.raise(::core::convert::AsRef::<str>::as_ref(&(format!(\"done/{}\", 7))))?;".to_owned(),
        format!("(ctx.read_state::<f64>(&{battery})?)"),
    ] {
        assert!(has(&out, &line), "missing {line:?} in:\n{out}");
    }
}

#[test]
fn conditions_with_errors_generate_nothing() {
    let errs = errors(
        "state ok: bool;\ncommand a() {}\ngoal g() { spawn a() with skip if ok > 1; set nope = 1; }",
    );
    assert_eq!(
        errs,
        [
            "`>` cannot be applied to `bool` and `int`",
            "no state variable `nope` is declared"
        ]
    );
}

/// `#[allow(tdl::…)]` accepts the warning and never reaches the generated Rust (rustc would
/// reject a lint of the unknown tool `tdl`); the Rust lints of a mixed attribute and the
/// other attributes stay, on the task and on a Rust statement alike.
#[test]
fn tdl_lint_attributes_are_stripped_and_rust_ones_kept() {
    let src = "exception Fault;\n\
        #[allow(tdl::unhandled_exception, dead_code)]\n\
        #[doc(alias = \"stop\")]\n\
        #[allow(tdl::redundant_parallel)]\n\
        goal g(x: u32) {\n\
            spawn a() with parallel;\n\
            #[allow(tdl::unhandled_exception, unused_variables)]\n\
            let y = x;\n\
            fail Fault;\n\
        }\n\
        command a() {}\n\
        #[allow(tdl::fail_without_exception)]\n\
        handler h() handles Fault for a { fail; }\n";
    let (tokens, diags) = compile_str("t.tdl", src);
    // The task's allow accepts the `fail`; the one of `let y` accepts nothing, and says so.
    let left: Vec<(Option<crate::Lint>, usize)> =
        diags.iter().map(|d| (d.lint(), d.line())).collect();
    assert_eq!(left, [(Some(crate::Lint::UnusedAllow), 7)], "{diags:?}");
    let out = pretty(&tokens.expect("no errors"));
    assert!(!out.contains("tdl::unhandled_exception"), "{out}");
    assert!(!out.contains("tdl::redundant_parallel"), "{out}");
    assert!(!out.contains("tdl::fail_without_exception"), "{out}");
    assert!(
        has(&out, "#[allow(dead_code)] #[doc(alias = \"stop\")]"),
        "{out}"
    );
    assert!(has(&out, "#[allow(unused_variables)] let y = x;"), "{out}");
    // The macro's expansion too.
    let expanded = crate::expand_macro(src.parse().expect("tokens")).to_string();
    for lint in [
        "unhandled_exception",
        "redundant_parallel",
        "fail_without_exception",
    ] {
        assert!(!expanded.contains(&format!("tdl :: {lint}")), "{expanded}");
    }
    assert!(expanded.contains("allow (dead_code)"), "{expanded}");
}

/// Arguments by value (`by_value.rs`): a variable named again later is cloned; one named in no
/// later statement, or only in another branch of an `if`, is moved; in a loop, a variable from
/// outside it is cloned, one the loop binds anew each iteration is not; a handler's arguments
/// count as later than the spawn's own; a task-level handler's arguments are cloned when the
/// body names them.
#[test]
fn arguments_are_cloned_only_where_the_variable_is_named_again() {
    let out = expand(
        "exception E;
         handler h(log: Log) handles E { }
         command a(log: Log) { }
         command b(s: Sender) { }
         command d(log: Log, room: u32) { }
         goal g(s: Sender, log: Log, rooms: Vec<u32>, c: bool) with exception handler h(log) {
             spawn a(log);
             if c { spawn b(s); } else { spawn b(s); }
             for room in rooms { spawn d(log, room); }
             spawn a(log) with exception handler h(log);
         }",
    );
    for line in [
        "let tdl_handler_0 = h(::core::clone::Clone::clone(&log));",
        "ctx.spawn(a(::core::clone::Clone::clone(&log)))",
        "ctx.spawn(b(s))",
        "ctx.spawn(d(::core::clone::Clone::clone(&log), room))",
        "ctx.spawn(a(::core::clone::Clone::clone(&log))).handler(h(log))",
    ] {
        assert!(has(&out, line), "missing {line:?} in:\n{out}");
    }
    assert!(!has(&out, "Clone::clone(&s)"), "{out}");
    assert!(!has(&out, "Clone::clone(&room)"), "{out}");
}
