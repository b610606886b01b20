//! The model of small programs: sites, relations, `previous`, reach and the text of fragments.

use super::*;

fn program(src: &str) -> tdl_syntax::Ast {
    let parse = tdl_syntax::parse_str("t.tdl", src);
    assert!(!parse.has_errors(), "{:?}", parse.diagnostics);
    parse.file
}

fn structure(ast: &tdl_syntax::Ast) -> Program<'_> {
    Program::new(&hir::Program::new(&[("t.tdl", ast)]))
}

fn relations(p: &Program<'_>, task: &str) -> Vec<String> {
    let t = p.task(task).expect("the task");
    t.relations
        .iter()
        .map(|r| {
            let from = match r.from {
                Endpoint::Task => "this".to_string(),
                Endpoint::Site(s) => t.sites[s].task.clone(),
            };
            format!("{from} -> {}: {}", t.sites[r.to].task, r.label)
        })
        .collect()
}

#[test]
fn constraints_name_the_spawns_their_tags_resolve_to() {
    let files = program(
        "goal g() {
            spawn a();
            spawn w() with terminate at a execution completed;
            spawn b() with sequential execution previous, terminate in 30s after self handling active;
            l: spawn c() with wait, exception handler h(1) maximum activate 2;
            spawn d() with serial l, disable until parent handling active, on terminate e();
        }
        handler h(n: u32) handles Oops { bypass; }
        exception Oops;",
    );
    let p = structure(&files);
    assert_eq!(
        relations(&p, "g"),
        [
            "this -> d: disable until handling active",
            "a -> w: terminate at execution completed",
            "w -> b: sequential execution",
            "c -> d: serial",
        ]
    );
    let g = p.task("g").expect("g");
    let names: Vec<&str> = g.sites.iter().map(|s| s.task.as_str()).collect();
    assert_eq!(names, ["a", "w", "b", "c", "d", "e"]);
    assert_eq!(g.sites[5].origin, Origin::OnTerminate(Some(4)));
    assert_eq!(
        g.sites[2].notes,
        ["terminate in 30s after self handling active"]
    );
    assert_eq!(g.sites[3].flags, ["wait"]);
    assert_eq!(g.sites[3].labels, ["l"]);
    assert_eq!(g.sites[3].handlers[0].name, "h");
    assert_eq!(g.sites[3].handlers[0].max.as_deref(), Some("2"));
    assert_eq!(
        plain(&g.sites[2].constraints[0]),
        "sequential execution previous (w)"
    );
    let h = p.task("h").expect("h");
    assert!(h.bypasses);
    assert_eq!(p.handler_users("h").len(), 1);
}

#[test]
fn previous_is_every_spawn_that_may_come_just_before() {
    let files = program(
        "goal g(n: u32) {
            spawn p();
            for i in 0..n {
                if i > 0 { spawn t() with sequential execution previous; }
                spawn m() with sequential execution previous;
            }
            with (serial previous) { spawn x(); spawn y(); }
            spawn z() with serial previous;
        }",
    );
    let p = structure(&files);
    assert_eq!(
        relations(&p, "g"),
        [
            "p -> t: sequential execution",
            "p -> m: sequential execution",
            "p -> x: serial",
            "t -> m: sequential execution",
            "m -> t: sequential execution",
            "m -> m: sequential execution",
            "m -> x: serial",
            "x -> y: serial",
            "x -> z: serial",
            "y -> z: serial",
        ]
    );
    let g = p.task("g").expect("g");
    assert!(g.sites[1].repeated && g.sites[1].conditional);
    assert!(g.sites[2].repeated && !g.sites[2].conditional);
}

#[test]
fn reach_follows_spawns_handlers_and_exceptions() {
    let files = program(
        "exception Base;
        exception Oops: Base;
        goal top() with exception handler fix() { spawn mid(); }
        goal mid() { spawn leaf(); fail Oops; }
        command leaf() {}
        handler fix() handles Base { retry; }
        handler outside() handles Base for leaf { bypass; }
        goal unrelated() {}",
    );
    let p = structure(&files);
    let (tasks, exceptions) = p.reach("mid").expect("mid");
    assert_eq!(
        tasks.into_iter().collect::<Vec<_>>(),
        ["leaf", "mid", "outside"]
    );
    assert_eq!(exceptions.into_iter().collect::<Vec<_>>(), ["Base", "Oops"]);
    let (tasks, _) = p.reach("top").expect("top");
    assert_eq!(tasks.len(), 5, "{tasks:?}");
    assert!(p.reach("nowhere").is_none());
}

#[test]
fn ids_are_plain_and_unique() {
    let mut used = BTreeSet::new();
    assert_eq!(unique_id("r#type", &mut used), "r_type");
    assert_eq!(unique_id("r_type", &mut used), "r_type_2");
    assert_eq!(unique_id("façade", &mut used), "fa_ade");
}

#[test]
fn rust_fragments_are_written_as_rustfmt_would() {
    let files = program(
        "goal g(v: Vec < Option < u32 > >, m: & 'static str) { spawn t(m . len (), v [0] . clone ()); }",
    );
    let g = structure(&files);
    let g = g.task("g").expect("g");
    assert_eq!(print::type_text(&g.task.args[0].ty), "Vec<Option<u32>>");
    assert_eq!(print::type_text(&g.task.args[1].ty), "&'static str");
    assert_eq!(g.sites[0].args, "m.len(), v[0].clone()");
}

#[test]
fn a_body_that_waits_orders_what_comes_next_after_the_end_of_what_it_waited_for() {
    let files = program(
        "goal g(n: u32) {
            spawn a() with wait;
            let v = spawn b() with wait;
            if n > v { let o = spawn c() with outcome; } else { spawn d(); }
            spawn e();
            with (wait) { spawn f(); spawn h(); }
            spawn i();
        }
        command b() -> u32 { 0 }",
    );
    let p = structure(&files);
    let after: Vec<String> = relations(&p, "g")
        .into_iter()
        .filter(|it| it.ends_with("after its end"))
        .collect();
    assert_eq!(
        after,
        [
            "a -> b: after its end",
            "b -> c: after its end",
            "b -> d: after its end",
            "c -> e: after its end",
            // A group's `wait` is each member's: `f` ends before `h` starts, both before `i`.
            "f -> h: after its end",
            "f -> i: after its end",
            "h -> i: after its end",
        ]
    );
}

#[test]
fn conditions_are_notes_of_their_sites_and_state_is_listed() {
    let files = program(
        "/// Whether the lander may act.
        state healthy: bool = true;
        state battery: float = 100;
        command step() {}
        monitor watch() {}
        goal g() {
            a: spawn step() with pause while !healthy, skip if battery < 10;
            w: spawn watch() with activate on change of battery;
            a terminate when (battery - 5.0) * 2 < 20 || !healthy;
            spawn step() with disable until healthy, serial a;
            set battery = 50;
            raise \"done\";
        }",
    );
    let p = structure(&files);
    let g = p.task("g").expect("g");
    assert_eq!(
        g.sites[0].notes,
        [
            "pause while !healthy",
            "skip if battery < 10",
            "terminate when (battery - 5.0) * 2 < 20 || !healthy",
        ]
    );
    assert_eq!(g.sites[1].notes, ["activate on change of battery"]);
    assert_eq!(g.sites[2].notes, ["disable until healthy"]);
    assert_eq!(relations(&p, "g"), ["step -> step: serial"]);
    assert_eq!(g.sets, ["battery"]);
    assert_eq!(g.raises_external, ["\"done\""]);
    let states: Vec<(&str, &[String])> = p
        .states
        .iter()
        .map(|v| (v.text.as_str(), v.set_by.as_slice()))
        .collect();
    assert_eq!(
        states,
        [
            ("state healthy: bool = true", &[][..]),
            ("state battery: float = 100.0", &["g".to_string()][..]),
        ]
    );
    assert_eq!(
        p.states[0].doc.as_deref(),
        Some("Whether the lander may act.")
    );
}
