//! The public entry points: `parse_str`, `parse_tokens`, rendering, and the AST shape a code
//! generator relies on.

use std::str::FromStr;

use tdl_syntax::{
    ConstraintKind, Facet, Item, Point, RelTime, Severity, Stmt, TagKind, Then, When,
};

#[test]
fn renders_as_rustc_with_location_source_caret_and_hint() {
    let src = "goal g() {\n    spawn a();\n    a   on robot2;\n}\n";
    let parse = tdl_syntax::parse_str("robot.tdl", src);
    let text = parse.render("robot.tdl", Some(src));
    assert_eq!(
        text,
        "error: `on` places a task when it is spawned\n --> robot.tdl:3:9\n  |\n3 |     a   on robot2;\n  |         ^^\n  |\n  = help: put it on the spawn: `spawn arm_move(1.0) with on \"arm\";` (a node runs where it was spawned)\n"
    );
    // Issue 12, point 14: the same through annotate-snippets' styled renderer carries the ANSI
    // colours rustc uses; the plain one none.
    let styled = parse.diagnostics[0].render_styled("robot.tdl", Some(src));
    assert!(styled.contains("\u{1b}["), "{styled:?}");
    assert!(!text.contains('\u{1b}'), "{text:?}");
    // Without the source (the macro's case) the location and the hint remain.
    let bare = parse.diagnostics[0].render("robot.tdl", None);
    assert!(bare.contains("--> robot.tdl:3:9"), "{bare}");
    assert!(bare.contains("= help: put it on the spawn"), "{bare}");
    let diag = &parse.diagnostics[0];
    assert_eq!(
        (diag.line(), diag.column(), diag.severity()),
        (3, 9, Severity::Error)
    );
}

#[test]
fn parse_tokens_matches_parse_str() {
    let src = "goal g() { t1: spawn a() with wait; spawn b() with serial t2; }";
    let tokens = proc_macro2::TokenStream::from_str(src).expect("valid tokens");
    let from_tokens = tdl_syntax::parse_tokens(tokens);
    let from_str = tdl_syntax::parse_str("g.tdl", src);
    assert_eq!(
        tdl_syntax::dump(&from_tokens.file),
        tdl_syntax::dump(&from_str.file)
    );
    let messages: Vec<&str> = from_tokens
        .diagnostics
        .iter()
        .map(|it| it.message())
        .collect();
    assert_eq!(messages, ["unknown tag `t2`"]);
}

#[test]
fn lexer_errors_become_diagnostics() {
    let parse = tdl_syntax::parse_str("bad.tdl", "goal g() {\n    spawn a(\"oops);\n}\n");
    assert!(parse.has_errors());
    assert!(
        parse.diagnostics[0]
            .message()
            .starts_with("cannot read the input as Rust tokens")
    );
    assert_eq!(parse.diagnostics[0].line(), 2);
}

#[test]
fn one_mistake_per_statement_and_parsing_goes_on() {
    let src = "goal g() {\n    spawn a() with bogus;\n    spawn b() with wait wait;\n    spawn c();\n}\ngoal h() { spawn d(); }\n";
    let parse = tdl_syntax::parse_str("g.tdl", src);
    let lines: Vec<usize> = parse.diagnostics.iter().map(|it| it.line()).collect();
    assert_eq!(lines, [2, 3]);
    assert_eq!(parse.file.items.len(), 2);
    let Item::Task(g) = &parse.file.items[0] else {
        panic!("expected a task")
    };
    assert_eq!(g.body.stmts.len(), 1, "the good spawn is kept");
}

#[test]
fn joined_keywords_and_synonyms_give_the_same_tree() {
    let spelled = tdl_syntax::parse_str(
        "a.tdl",
        "goal g() { spawn a(); spawn b() with sequential expansion a, disable execution until a execution completed, terminate at a completed; }",
    );
    let joined = tdl_syntax::parse_str(
        "b.tdl",
        "goal g() { spawn a(); spawn b() with SEQUENTIAL_PLANNING a, disable_achievement_until a achievement_completed, terminateAt a completed; }",
    );
    assert!(spelled.diagnostics.is_empty() && joined.diagnostics.is_empty());
    assert_eq!(
        tdl_syntax::dump(&spelled.file),
        tdl_syntax::dump(&joined.file)
    );
    let Item::Task(task) = &joined.file.items[0] else {
        panic!("expected a task")
    };
    let Stmt::Spawn(spawn) = &task.body.stmts[1] else {
        panic!("expected a spawn")
    };
    let ConstraintKind::Sequential {
        facet,
        tag: Some(tag),
    } = &spawn.constraints[0].kind
    else {
        panic!("expected sequential")
    };
    assert_eq!(*facet, Facet::Expansion);
    assert!(matches!(&tag.kind, TagKind::Named { name, .. } if name == "a"));
}

#[test]
fn waited_spawn_binds_the_result_and_times_are_nanos() {
    let parse = tdl_syntax::parse_str(
        "a.tdl",
        "goal g() { let (l, r): (i32, i32) = spawn look() with wait, terminate in 1.5s; }",
    );
    assert!(parse.diagnostics.is_empty());
    let Item::Task(task) = &parse.file.items[0] else {
        panic!("expected a task")
    };
    let Stmt::Spawn(spawn) = &task.body.stmts[0] else {
        panic!("expected a spawn")
    };
    assert!(spawn.binding.as_ref().is_some_and(|it| it.ty.is_some()));
    assert!(matches!(
        spawn.constraints[1].kind,
        ConstraintKind::Trigger {
            when: When::In(RelTime::Nanos(1_500_000_000)),
            then: Then::Terminate
        }
    ));
}

#[test]
fn disable_terminate_and_activate_share_one_when() {
    let parse = tdl_syntax::parse_str(
        "a.tdl",
        "monitor m() { trigger; }
         goal g() {
             a: spawn x();
             spawn m() with disable execution for 2s after a completed,
                 terminate in 2s after a completed, activate in 2s after a completed,
                 disable until 13:00:00, terminate at 13:00:00, activate at 13:00:00,
                 disable until a active, terminate, activate;
         }",
    );
    assert!(parse.diagnostics.is_empty(), "{:?}", parse.diagnostics);
    let Item::Task(task) = &parse.file.items[1] else {
        panic!("expected a task")
    };
    let Stmt::Spawn(spawn) = &task.body.stmts[1] else {
        panic!("expected a spawn")
    };
    let triggers: Vec<(&When, Then)> = spawn
        .constraints
        .iter()
        .map(|it| match &it.kind {
            ConstraintKind::Trigger { when, then } => (when, *then),
            other => panic!("expected a trigger, found {other:?}"),
        })
        .collect();
    let thens: Vec<Then> = triggers.iter().map(|it| it.1).collect();
    let enable = Then::Enable(Some(Facet::Execution));
    assert_eq!(
        thens,
        [
            enable,
            Then::Terminate,
            Then::Activate,
            Then::Enable(None),
            Then::Terminate,
            Then::Activate,
            Then::Enable(None),
            Then::Terminate,
            Then::Activate
        ]
    );
    for (when, _) in &triggers[..3] {
        let When::After(RelTime::Nanos(2_000_000_000), event) = when else {
            panic!("expected `2s after a completed`, found {when:?}")
        };
        assert!(matches!(&event.tag.kind, TagKind::Named { name, .. } if name == "a"));
        assert_eq!(event.point, Point::Completed);
    }
    for (when, _) in &triggers[3..6] {
        assert!(
            matches!(when, When::At(time) if time.hour == 13 && time.minute == 0),
            "{when:?}"
        );
    }
    assert!(matches!(triggers[6].0, When::Event(event) if event.point == Point::Active));
    assert!(matches!(triggers[7].0, When::Now) && matches!(triggers[8].0, When::Now));
}

/// Issue 12, point 3: the files of a program share their names. A typo in a handled exception
/// declared in another file is an error in the file of the typo; without the typo the program is
/// clean, and an exception's ancestry crosses files.
#[test]
fn names_resolve_across_the_files_of_a_program() {
    let faults = "exception Fault; exception TerrainFault : Fault;";
    let typo = "handler h() handles TerainFault { let _ = 1; }";
    let results = tdl_syntax::compile_program(&[("faults.tdl", faults), ("walk.tdl", typo)]);
    assert!(results[0].0.is_some(), "{:?}", results[0].1);
    let errors: Vec<String> = results[1]
        .1
        .iter()
        .map(|it| it.message().to_owned())
        .collect();
    assert_eq!(errors, ["unknown exception `TerainFault`"]);
    assert!(results[1].0.is_none());
    // Alone, the file of the typo declares no exception to check against: only rustc can see it.
    assert!(tdl_syntax::compile_str("walk.tdl", typo).0.is_some());

    let walk = "exception Slip : TerrainFault; handler h() handles Fault { let _ = 1; }";
    let results = tdl_syntax::compile_program(&[("faults.tdl", faults), ("walk.tdl", walk)]);
    let code = results[1]
        .0
        .as_ref()
        .map(ToString::to_string)
        .unwrap_or_default();
    let squashed: String = code.split_whitespace().collect();
    assert!(squashed.contains("&[\"TerrainFault\",\"Fault\"]"), "{code}");

    // A name declared in two files is an error once, at the later declaration, which points
    // at the first in the other file.
    let twice = "exception Fault;";
    let results = tdl_syntax::compile_program(&[("a.tdl", faults), ("b.tdl", twice)]);
    assert!(results[0].1.is_empty(), "{:?}", results[0].1);
    let [diag] = results[1].1.as_slice() else {
        panic!("one error expected: {:?}", results[1].1);
    };
    assert_eq!(diag.message(), "`Fault` is also declared in a.tdl");
    assert_eq!(diag.labels()[0].file(), Some("a.tdl"));
    assert_eq!(diag.labels()[0].start().line, 1);
    assert!(results[1].0.is_none());
}

/// The program-wide checks see every file: a handler in one file handles an exception raised in
/// another, and a recursion through two files is reported once, in the file of the task named
/// first.
#[test]
fn unhandled_exceptions_and_recursion_are_checked_across_files() {
    let messages = |results: &[(
        Option<proc_macro2::TokenStream>,
        Vec<tdl_syntax::Diagnostic>,
    )]| {
        results
            .iter()
            .map(|(_, diags)| diags.iter().map(|it| it.message().to_owned()).collect())
            .collect::<Vec<Vec<String>>>()
    };
    let leg = "exception Fault; exception Slip : Fault; command move_leg() { fail Slip; }";
    let walk = "handler steady() handles Fault { let _ = 1; } \
                goal walk() { spawn move_leg() with exception handler steady(); }";
    let results = tdl_syntax::compile_program(&[("leg.tdl", leg), ("walk.tdl", walk)]);
    assert_eq!(messages(&results), [Vec::<String>::new(), Vec::new()]);
    let walk = "goal walk() { spawn move_leg(); }";
    let results = tdl_syntax::compile_program(&[("leg.tdl", leg), ("walk.tdl", walk)]);
    assert_eq!(
        messages(&results),
        [
            vec!["no handler in this program handles `Slip` raised here".to_owned()],
            Vec::new()
        ]
    );
    // Warnings do not keep the code from being generated.
    assert!(results.iter().all(|(code, _)| code.is_some()));

    let ping = "goal ping() { spawn pong(); }";
    let pong = "goal pong() { spawn ping(); }";
    let results = tdl_syntax::compile_program(&[("pong.tdl", pong), ("ping.tdl", ping)]);
    assert_eq!(
        messages(&results),
        [
            Vec::new(),
            vec![
                "`ping` spawns `pong`, which spawns `ping`, each on every path through its body: \
                 the recursion never ends"
                    .to_owned()
            ]
        ]
    );
}

/// Found by fuzzing: brackets nested thousands deep exhausted the stack of the recursive parser
/// (a crash, not a diagnostic). Now a clear error at the first bracket too deep, on a thread with
/// a small stack, as the parser of a debug build would see it.
#[test]
fn brackets_nested_too_deep_are_an_error_not_a_crash() {
    let run = || {
        let n = 5000;
        let src = format!(
            "goal g() {{\n    let x = {}1{};\n}}\n",
            "(".repeat(n),
            ")".repeat(n)
        );
        let (_, diags) = tdl_syntax::compile_str("deep.tdl", &src);
        diags
            .iter()
            .map(|d| (d.line(), d.column(), d.message().to_owned()))
            .collect::<Vec<_>>()
    };
    let diags = std::thread::Builder::new()
        .stack_size(512 * 1024)
        .spawn(run)
        .expect("thread")
        .join()
        .expect("no crash");
    // The body's brace is level 1 and the first `(` (column 13) level 2, so the first bracket
    // past the limit is the `(` at column 13 + limit - 1.
    let limit = tdl_syntax::MAX_NESTING;
    assert_eq!(
        diags,
        [(
            2,
            12 + limit,
            format!("code nested more than {limit} deep (brackets, generic arguments or `&`)")
        )]
    );
}

/// Also found by fuzzing: nesting without brackets, which the parser descends into as deeply:
/// generic arguments and a run of `&`.
#[test]
fn generics_and_references_nested_too_deep_are_an_error_not_a_crash() {
    let run = || {
        let n = 3000;
        let generics = format!("type T = {}u8{};\n", "Vec<".repeat(n), ">".repeat(n));
        let refs = format!("type R = {}u8;\n", "&".repeat(n));
        [generics, refs].map(|src| {
            let (_, diags) = tdl_syntax::compile_str("deep.tdl", &src);
            diags
                .iter()
                .map(|d| d.message().to_owned())
                .collect::<Vec<_>>()
        })
    };
    let diags = std::thread::Builder::new()
        .stack_size(512 * 1024)
        .spawn(run)
        .expect("thread")
        .join()
        .expect("no crash");
    let limit = tdl_syntax::MAX_NESTING;
    for d in diags {
        assert_eq!(
            d,
            [format!(
                "code nested more than {limit} deep (brackets, generic arguments or `&`)"
            )]
        );
    }
}

/// `tdl doc` reads the doc comments of tasks and exceptions from the tree: `///` lines and
/// `/** */` blocks are kept (as `#[doc]` attributes) with their text, and plain comments are not.
#[test]
fn doc_comments_of_tasks_and_exceptions_are_kept() {
    let src = "\
// Not a doc comment.
/// Delivers the mail.
///
///     indented: kept relative to the rest
/// Second paragraph.
pub goal deliver(room: u32) { spawn go(room); }

/** A block
    doc comment. */
exception Lost;

// Plain comment only.
command go(room: u32) {}
";
    let parse = tdl_syntax::parse_str("doc.tdl", src);
    assert!(parse.diagnostics.is_empty(), "{:?}", parse.diagnostics);
    let [Item::Task(deliver), Item::Exception(lost), Item::Task(go)] = &parse.file.items[..] else {
        panic!("expected a task, an exception and a task")
    };
    assert_eq!(
        deliver.doc().as_deref(),
        Some("Delivers the mail.\n\n    indented: kept relative to the rest\nSecond paragraph.")
    );
    assert_eq!(lost.doc().as_deref(), Some("A block\ndoc comment."));
    assert_eq!(go.doc(), None);
}

/// `environment { … }`: each entry read, printed canonically, and checked against the declared
/// variables (a value of the wrong type, an unknown variable, `at most 0`, a condition that is
/// not a bool).
#[test]
fn an_environment_declaration_is_read_and_checked() {
    let src = "state battery: float = 100.0;\nstate docked: bool = false;\nenvironment {\n    battery: 100, 15.5 at most 2 when !docked;\n    external \"go\";\n}\n";
    let parse = tdl_syntax::parse_str("env.tdl", src);
    assert!(parse.diagnostics.is_empty(), "{:?}", parse.diagnostics);
    let Some(Item::Environment(env)) = parse.file.items.get(2) else {
        panic!("an environment item: {:?}", parse.file.items);
    };
    let lines: Vec<String> = env
        .entries
        .iter()
        .map(tdl_syntax::print::env_entry)
        .collect();
    assert_eq!(
        lines,
        [
            "battery: 100, 15.5 at most 2 when !docked",
            "external \"go\""
        ]
    );
    assert_eq!(env.entries[1].at_most(), 1);

    let bad = "state battery: float;\nenvironment {\n    battery: true;\n    speed: 1.0;\n    battery: 1.0 at most 0 when battery;\n}\n";
    let parse = tdl_syntax::parse_str("env.tdl", bad);
    let messages: Vec<(usize, String)> = parse
        .diagnostics
        .iter()
        .map(|d| (d.line(), d.message().to_owned()))
        .collect();
    assert_eq!(
        messages,
        [
            (3, "`battery` is a `float`, and `true` a `bool`".to_owned()),
            (4, "no state variable `speed` is declared".to_owned()),
            (5, "`at most 0`: the entry would never be used".to_owned()),
            (5, "this condition is a `float`, not a `bool`".to_owned()),
        ]
    );
}

#[test]
fn an_extern_task_is_a_signature_the_generator_leaves_to_rust() {
    let src = "/// Digs.\nextern command dig(x: f64, y: f64) -> f64;\n\
               goal g() {\n    let d = spawn dig(1.0, 2.0) with wait;\n}\n";
    let parse = tdl_syntax::parse_str("x.tdl", src);
    assert!(!parse.has_errors(), "{:?}", parse.diagnostics);
    let Item::Extern(e) = &parse.file.items[0] else {
        panic!("not an extern: {:?}", parse.file.items[0]);
    };
    assert_eq!(e.name, "dig");
    assert_eq!(e.args.len(), 2);
    assert!(e.result.is_some());
    let dump = tdl_syntax::dump(&parse.file);
    assert!(
        dump.contains("extern command dig(x: f64, y: f64) -> f64"),
        "{dump}"
    );
    // The waited value is typed by the declaration; nothing is generated for `dig` itself.
    let (code, diags) = tdl_syntax::compile_str("x.tdl", src);
    assert!(diags.iter().all(|d| !d.is_error()), "{diags:?}");
    let code = code.expect("code").to_string();
    assert!(code.contains("wait_value :: < f64 >"), "{code}");
    assert!(!code.contains("struct Dig"), "{code}");
}

#[test]
fn an_extern_task_also_written_in_tdl_is_an_error() {
    let src = "extern command dig(x: f64);\ncommand dig(x: f64) {}\n";
    let (_, diags) = tdl_syntax::compile_str("x.tdl", src);
    assert!(
        diags
            .iter()
            .any(|d| d.is_error() && d.message().contains("declared `extern` and defined in TDL")),
        "{diags:?}"
    );
}
