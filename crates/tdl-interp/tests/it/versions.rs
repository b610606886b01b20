//! A program superseded by a newer version while it runs: new spawns use the newer definitions
//! from then on, each node's `spawned` record names the version it runs, and a version whose
//! tasks would not take the running bodies' arguments is refused. Virtual time.

use std::time::Duration;

use tdl::{Recorder, TraceKind};
use tdl_interp::{Program, Registry};

const V1: &str = "\
pub goal patrol(n: i64) {
    for i in 0..n {
        spawn step(i) with wait;
    }
}

goal step(i: i64) {
    spawn tick(i) with wait;
}
";

/// `step` spawns two ticks now; `patrol` is unchanged.
const V2: &str = "\
pub goal patrol(n: i64) {
    for i in 0..n {
        spawn step(i) with wait;
    }
}

goal step(i: i64) {
    spawn tick(i) with wait;
    spawn tick(i + 100) with wait;
}
";

fn registry() -> Registry {
    let mut r = Registry::new();
    r.task("tick", |_i: i64| {
        tdl::Task::command("tick", |_| async {
            tokio::time::sleep(Duration::from_secs(1)).await;
            Ok(())
        })
    });
    r
}

fn load(text: &str) -> Program {
    match Program::from_sources(&[("patrol.tdl".into(), text.into())], &registry()) {
        Ok(p) => p,
        Err(e) => panic!("{e}"),
    }
}

#[tokio::test(start_paused = true)]
async fn new_spawns_use_the_newer_version_and_each_node_names_its_version() {
    let v1 = load(V1);
    let v2 = load(V2);
    assert_ne!(v1.hash(), v2.hash());
    assert_eq!(v1.hash(), load(V1).hash(), "the same text, the same hash");
    let (name1, name2) = (
        format!("patrol@{}", v1.hash()),
        format!("patrol@{}", v2.hash()),
    );
    let v1 = v1.stamped(&name1);
    let v2 = v2.stamped(&name2);
    let rec = Recorder::new();
    let session = tdl::Runtime::new()
        .with_sink(rec.clone())
        .start()
        .expect("in a runtime");
    let control = session.control();
    let root = control
        .spawn(v1.task_json("patrol", &serde_json::json!(4)).expect("task"))
        .expect("spawn");
    // Steps 0 and 1 run under version 1 (a tick each: 1 s per step); step 2 starts after 2 s.
    tokio::time::sleep(Duration::from_millis(1500)).await;
    v1.supersede(&v2).expect("compatible");
    control.wait(root).await.expect("the patrol ends");
    session.finish().await.expect("finish");

    let trace = rec.events();
    tdl::testing::assert_checked(&trace);
    let spawned: Vec<(String, Option<String>)> = trace
        .iter()
        .filter_map(|e| match &e.kind {
            TraceKind::Spawned { name, version, .. } => Some((name.clone(), version.clone())),
            _ => None,
        })
        .collect();
    let steps: Vec<Option<&str>> = spawned
        .iter()
        .filter(|(n, _)| n == "step")
        .map(|(_, v)| v.as_deref())
        .collect();
    let (one, two) = (Some(name1.as_str()), Some(name2.as_str()));
    assert_eq!(steps, vec![one, one, two, two], "{spawned:?}");
    // The patrol itself ran version 1 to its end; the steps of version 2 ran two ticks each.
    assert_eq!(spawned[0], ("patrol".to_string(), Some(name1.clone())));
    let ticks = spawned.iter().filter(|(n, _)| n == "tick").count();
    assert_eq!(ticks, 1 + 1 + 2 + 2);
    // Ticks come from the registry: no version.
    assert!(
        spawned
            .iter()
            .filter(|(n, _)| n == "tick")
            .all(|(_, v)| v.is_none())
    );
}

#[test]
fn a_version_whose_tasks_take_other_arguments_is_refused() {
    let v1 = load(V1);
    let changed = load(
        &V2.replace("goal step(i: i64)", "goal step(i: f64)")
            .replace(
                "spawn step(i) with wait;",
                "spawn step(i as f64) with wait;",
            )
            .replace(
                "spawn tick(i) with wait;\n    spawn tick(i + 100) with wait;",
                "spawn tick(1) with wait;",
            ),
    );
    let problems = v1.supersede(&changed).expect_err("incompatible");
    assert_eq!(
        problems,
        vec!["`step` changes parameters: (i64) becomes (f64)".to_string()]
    );
}

#[test]
fn a_program_of_recovery_alone_loads_without_a_registry_for_the_task_it_recovers() {
    let text = "\
exception Blocked;
extern goal guarded_move(d: f64);

handler back_off(d: f64) handles Blocked for guarded_move {
}
";
    let program =
        match Program::from_sources(&[("recovery.tdl".into(), text.into())], &Registry::new()) {
            Ok(p) => p,
            Err(e) => panic!("{e}"),
        };
    assert_eq!(program.attached_tasks(), vec!["guarded_move".to_string()]);
    assert_eq!(program.attached().len(), 1);
    assert!(program.tasks().is_empty());
    // Spawning it is another matter: then a registry must offer it.
    let spawns = format!("{text}\npub goal go() {{\n    spawn guarded_move(1.0);\n}}\n");
    let refused = Program::from_sources(&[("recovery.tdl".into(), spawns)], &Registry::new())
        .expect_err("an extern spawned but offered by no registry");
    assert!(
        refused.to_string().contains("which no registry offers"),
        "{refused}"
    );
}
