//! Unit tests for `jsonl.rs`: exact serialisation, round trips, and errors naming the line.

use super::{ReadError, read_jsonl, to_line, write_line};
use crate::event::{TraceConstraint, TraceEvent, TraceKind, TraceThen, TraceWhen};
use crate::state::Point;
use crate::test_util::{S, Tb, X, ev_ref, small_run};

#[test]
fn lines_serialise_flat_with_tags() {
    let t = small_run();
    assert_eq!(
        to_line(&t[0]),
        r#"{"seq":0,"t":0,"ev":"run_started","version":10,"run":0}"#
    );
    assert_eq!(
        to_line(&t[1]),
        r#"{"seq":1,"t":0,"ev":"spawned","node":1,"parent":0,"kind":"goal","name":"deliver"}"#
    );
    assert_eq!(
        to_line(&t[2]),
        r#"{"seq":2,"t":0,"ev":"transition","node":1,"facet":"expansion","from":"disabled","to":"enabled"}"#
    );
    let placed = TraceEvent {
        seq: 9,
        t: S,
        kind: TraceKind::Placed {
            node: 4,
            agent: "robot".into(),
        },
    };
    assert_eq!(
        to_line(&placed),
        r#"{"seq":9,"t":1000000000,"ev":"placed","node":4,"agent":"robot"}"#
    );
    assert_eq!(
        super::parse_line(&to_line(&placed), 1).expect("reads back"),
        placed
    );
    let log = TraceEvent {
        seq: 10,
        t: 2 * S,
        kind: TraceKind::Log {
            node: 4,
            message: "battery 42.5".into(),
        },
    };
    assert_eq!(
        to_line(&log),
        r#"{"seq":10,"t":2000000000,"ev":"log","node":4,"message":"battery 42.5"}"#
    );
    assert_eq!(
        super::parse_line(&to_line(&log), 1).expect("reads back"),
        log
    );
    let c = TraceEvent {
        seq: 3,
        t: S,
        kind: TraceKind::Constrained {
            node: 2,
            constraint: TraceConstraint::trigger(
                TraceWhen::After {
                    delay_ns: 5,
                    event: ev_ref(1, X, Point::Completed),
                },
                TraceThen::Enable(X),
            ),
        },
    };
    assert_eq!(
        to_line(&c),
        r#"{"seq":3,"t":1000000000,"ev":"constrained","node":2,"constraint":{"form":"trigger","when":{"after":{"delay_ns":5,"event":{"node":1,"facet":"execution","point":"completed"}}},"then":{"enable":"execution"}}}"#
    );
}

#[test]
fn round_trip_every_kind() {
    let mut b = Tb::new();
    b.push(TraceKind::Reserved {
        node: 3,
        parent: 0,
        name: "r".into(),
    });
    b.push(TraceKind::Dead { node: 3 });
    b.push(TraceKind::ConstraintVoid {
        node: 3,
        reason: "never spawned".into(),
    });
    b.push(TraceKind::Failed {
        node: 1,
        exception: "E".into(),
        message: "m \"q\"\n".into(),
    });
    b.push(TraceKind::Warning {
        node: None,
        message: "w".into(),
    });
    b.push(TraceKind::Warning {
        node: Some(2),
        message: "w".into(),
    });
    b.push(TraceKind::Log {
        node: 2,
        message: "l \"q\"\n".into(),
    });
    b.push(TraceKind::StateDeclared {
        var: "battery".into(),
        ty: tcm_expr::Type::Float,
        value: tcm_expr::Value::Float(0.1 + 0.2),
    });
    b.push(TraceKind::StateSet {
        var: "battery".into(),
        value: tcm_expr::Value::Unknown,
    });
    b.push(TraceKind::Skipped { node: 1 });
    b.push(TraceKind::Constrained {
        node: 1,
        constraint: crate::TraceConstraint::trigger(
            crate::TraceWhen::Condition(tcm_expr::Expr::and(
                tcm_expr::Expr::var("ok"),
                tcm_expr::Expr::not(tcm_expr::Expr::var("fault")),
            )),
            crate::TraceThen::Pause,
        ),
    });
    for kind in [
        TraceKind::Terminating { node: 1 },
        TraceKind::Terminated { node: 1 },
        TraceKind::Suspended { node: 1 },
        TraceKind::Unsuspended { node: 1 },
        TraceKind::Reclaimed { node: 1 },
        TraceKind::External {
            name: "button".into(),
        },
    ] {
        b.push(kind);
    }
    for constraint in [
        TraceConstraint::ExpandFirst,
        TraceConstraint::DelayExpansion,
        TraceConstraint::trigger(TraceWhen::At(7), TraceThen::Enable(X)),
        TraceConstraint::trigger(TraceWhen::External("go".into()), TraceThen::Enable(X)),
        TraceConstraint::trigger(
            TraceWhen::Event(ev_ref(1, X, Point::Active)),
            TraceThen::Enable(X),
        ),
        TraceConstraint::trigger(TraceWhen::Now, TraceThen::Terminate),
        TraceConstraint::trigger(
            TraceWhen::All {
                events: vec![
                    ev_ref(1, X, Point::Completed),
                    ev_ref(2, X, Point::Completed),
                ],
                delay_ns: Some(5),
            },
            TraceThen::Terminate,
        ),
        TraceConstraint::trigger(
            TraceWhen::All {
                events: vec![],
                delay_ns: None,
            },
            TraceThen::Activate,
        ),
        TraceConstraint::trigger(
            TraceWhen::Event(ev_ref(1, X, Point::Enabled)),
            TraceThen::Terminate,
        ),
        TraceConstraint::trigger(TraceWhen::At(u64::MAX), TraceThen::Terminate),
        TraceConstraint::trigger(
            TraceWhen::After {
                delay_ns: 1,
                event: ev_ref(1, X, Point::Enabled),
            },
            TraceThen::Terminate,
        ),
        TraceConstraint::trigger(TraceWhen::External("stop".into()), TraceThen::Terminate),
    ] {
        b.constrain(2, constraint);
    }
    let mut trace = small_run();
    trace.extend(b.build().into_iter().skip(1));
    let mut buf = Vec::new();
    for ev in &trace {
        assert!(write_line(ev, &mut buf).is_ok());
    }
    let text = String::from_utf8(buf).unwrap_or_default();
    assert_eq!(text.lines().count(), trace.len());
    let back = read_jsonl(text.as_bytes());
    assert_eq!(back.ok(), Some(trace));
}

#[test]
fn blank_lines_are_skipped() {
    let t = small_run();
    let text = format!("{}\n\n  \n{}\n", to_line(&t[0]), to_line(&t[1]));
    assert_eq!(read_jsonl(text.as_bytes()).ok(), Some(t[..2].to_vec()));
}

fn error_text(input: &str) -> String {
    match read_jsonl(input.as_bytes()) {
        Ok(_) => "no error".into(),
        Err(e) => e.to_string(),
    }
}

#[test]
fn errors_name_the_line_and_the_problem() {
    let first = to_line(&small_run()[0]);
    let text = error_text(&format!(
        "{first}\n{{\"seq\":1,\"t\":0,\"ev\":\"exploded\"}}\n"
    ));
    assert!(
        text.starts_with(
            "line 2: not a trace record: unknown variant `exploded`, expected one of `run_started`"
        ),
        "{text}"
    );
    let e = error_text(&format!(
        "{first}\n\n{{\"seq\":1,\"t\":0,\"ev\":\"dead\"}}\n"
    ));
    assert!(
        e.starts_with("line 3: not a trace record: missing field `node`"),
        "{e}"
    );
    let e = error_text("{\"seq\":1,");
    assert!(
        e.starts_with("line 1: not a trace record: EOF while parsing"),
        "{e}"
    );
    let e = error_text("{\"seq\":0,\"t\":0,\"ev\":\"run_started\",\"version\":11,\"run\":0}");
    assert_eq!(
        e,
        "line 1: the trace has format version 11, but this reader reads versions 1 to 10"
    );
    assert!(matches!(
        read_jsonl(&b"\xff\n"[..]),
        Err(ReadError::Io { line: 1, .. })
    ));
}

#[test]
fn documented_examples_are_exact() {
    // Every example line of docs/trace-format.md parses and serialises back to itself, and together they
    // show every record kind and every constraint form.
    let doc = include_str!("../../../../docs/trace-format.md");
    let mut kinds = std::collections::BTreeSet::new();
    let mut forms = std::collections::BTreeSet::new();
    let (mut whens, mut thens) = (
        std::collections::BTreeSet::new(),
        std::collections::BTreeSet::new(),
    );
    for (i, line) in doc
        .lines()
        .enumerate()
        .filter(|(_, l)| l.starts_with("{\"seq\""))
    {
        let ev = super::parse_line(line, i + 1);
        let Ok(ev) = ev else {
            panic!("docs line {}: {:?}", i + 1, ev.err().map(|e| e.to_string()))
        };
        assert_eq!(to_line(&ev), line, "docs line {}", i + 1);
        let value: serde_json::Value = serde_json::from_str(line).unwrap_or_default();
        kinds.insert(value["ev"].as_str().unwrap_or_default().to_string());
        if let Some(form) = value["constraint"]["form"].as_str() {
            forms.insert(form.to_string());
            let key = |v: &serde_json::Value| match v {
                serde_json::Value::Object(m) => m.keys().next().cloned().unwrap_or_default(),
                other => other.as_str().unwrap_or_default().to_string(),
            };
            whens.insert(key(&value["constraint"]["when"]));
            thens.insert(key(&value["constraint"]["then"]));
        }
    }
    assert_eq!(kinds.len(), 50, "{kinds:?}");
    assert_eq!(forms.len(), 3, "{forms:?}");
    // Every kind of "when" with every kind of "then" is shown (the empty string is not a trigger).
    assert_eq!(whens.len(), 8, "{whens:?}");
    assert_eq!(thens.len(), 7, "{thens:?}");
}

#[test]
fn version_1_constraints_read_as_version_2_triggers() {
    // docs/trace-format.md, "Versions": each version 1 constraint object reads as the version 2
    // example with the same `seq`.
    let doc = include_str!("../../../../docs/trace-format.md");
    let current: std::collections::BTreeMap<u64, TraceConstraint> = doc
        .lines()
        .filter(|l| l.starts_with("{\"seq\"") && l.contains("\"constrained\""))
        .filter_map(|l| super::parse_line(l, 0).ok())
        .filter_map(|ev| match ev.kind {
            TraceKind::Constrained { constraint, .. } => Some((ev.seq, constraint)),
            _ => None,
        })
        .collect();
    let versions = &doc[doc.find("## Versions").unwrap_or(0)..];
    let mut n = 0;
    for line in versions.lines() {
        let Some((seq, object)) = line.split_once(' ') else {
            continue;
        };
        let Ok(seq) = seq.parse::<u64>() else {
            continue;
        };
        let old: TraceConstraint =
            serde_json::from_str(object).unwrap_or_else(|e| panic!("version 1 form {object}: {e}"));
        assert_eq!(Some(&old), current.get(&seq), "version 1 form {object}");
        n += 1;
    }
    assert_eq!(n, 14, "every version 1 trigger form is shown");
    // A whole version 1 trace still reads, and the checker accepts its version.
    let v1 = "{\"seq\":0,\"t\":0,\"ev\":\"run_started\",\"version\":1,\"run\":0}\n";
    let trace = read_jsonl(v1.as_bytes()).unwrap_or_default();
    assert_eq!(trace.len(), 1);
    assert!(crate::check(&trace).is_ok());
}
