//! Mutual TLS (docs/distributed.md, "Who may speak"): an executive and an agent holding
//! certificates of their system's authority run a task over `tls/127.0.0.1`; a stranger whose
//! certificate another authority signed, or who has none, opens no link to the executive: it is
//! never seen as an agent, so never placed on, and what it sends reaches nobody. The certificates
//! are made for the test with the `openssl` command (the test says why and returns when it is
//! missing).

use crate::util::{JOIN, bounded, system};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;
use tcm::testing::run_checked;
use tcm::{RunOutcome, Runtime, Task};
use tcm_zenoh::config::{Certs, loopback_tls_connect, loopback_tls_listen};
use tcm_zenoh::{Agent, Executive, Json, RemoteCtx, RemoteFailure};

pub(crate) fn openssl(dir: &Path, args: &[&str]) {
    let out = Command::new("openssl")
        .args(args)
        .current_dir(dir)
        .output()
        .expect("openssl runs");
    assert!(
        out.status.success(),
        "openssl {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// An authority `name` in `dir`: its certificate and key.
pub(crate) fn authority(dir: &Path, name: &str) {
    openssl(
        dir,
        &[
            "req",
            "-x509",
            "-newkey",
            "ec",
            "-pkeyopt",
            "ec_paramgen_curve:prime256v1",
            "-nodes",
            "-days",
            "1",
            "-subj",
            &format!("/CN={name}"),
            "-keyout",
            &format!("{name}.key"),
            "-out",
            &format!("{name}.pem"),
            "-addext",
            "basicConstraints=critical,CA:TRUE",
            "-addext",
            "keyUsage=critical,keyCertSign,cRLSign",
        ],
    );
}

/// A certificate for `name`, reached at 127.0.0.1, signed by authority `by`.
pub(crate) fn certificate(dir: &Path, name: &str, by: &str) -> Certs {
    openssl(
        dir,
        &[
            "req",
            "-newkey",
            "ec",
            "-pkeyopt",
            "ec_paramgen_curve:prime256v1",
            "-nodes",
            "-subj",
            &format!("/CN={name}"),
            "-keyout",
            &format!("{name}.key"),
            "-out",
            &format!("{name}.csr"),
        ],
    );
    let ext = dir.join(format!("{name}.ext"));
    std::fs::write(
        &ext,
        "subjectAltName=IP:127.0.0.1\nbasicConstraints=CA:FALSE\n\
         keyUsage=digitalSignature\nextendedKeyUsage=serverAuth,clientAuth\n",
    )
    .expect("the extensions file");
    openssl(
        dir,
        &[
            "x509",
            "-req",
            "-in",
            &format!("{name}.csr"),
            "-CA",
            &format!("{by}.pem"),
            "-CAkey",
            &format!("{by}.key"),
            "-CAcreateserial",
            "-days",
            "1",
            "-out",
            &format!("{name}.pem"),
            "-extfile",
            &format!("{name}.ext"),
        ],
    );
    Certs {
        authority: dir.join(format!("{by}.pem")),
        certificate: dir.join(format!("{name}.pem")),
        key: dir.join(format!("{name}.key")),
    }
}

/// A fresh directory for one test's certificates.
pub(crate) fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("tcm-zenoh-tls-{}", system(name)));
    std::fs::create_dir_all(&dir).expect("a directory");
    dir
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn only_holders_of_the_systems_certificates_join_it() {
    if Command::new("openssl").arg("version").output().is_err() {
        eprintln!("openssl is not on PATH: no certificates to test TLS with");
        return;
    }
    bounded(async {
        let dir = scratch("tls");
        authority(&dir, "system");
        authority(&dir, "other");
        let exec_certs = certificate(&dir, "exec", "system");
        let arm_certs = certificate(&dir, "arm", "system");
        // The fake agent trusts the system's authority (its certificate is no secret), so only
        // the executive's check of the fake agent's own certificate keeps it out.
        let fake_certs = Certs {
            authority: dir.join("system.pem"),
            ..certificate(&dir, "fake", "other")
        };
        let sys = system("tls");
        let port = tcm_zenoh::config::free_port().expect("a port");
        let exec = Executive::open(
            &sys,
            loopback_tls_listen(port, &exec_certs).expect("config"),
        )
        .await
        .expect("the executive opens");
        let arm = Agent::builder(sys.clone(), "arm")
            .command("double", |_: RemoteCtx, x: i64| async move {
                Ok::<_, RemoteFailure>(x * 2)
            })
            .start(loopback_tls_connect(port, &arm_certs).expect("config"))
            .await
            .expect("the agent starts");
        exec.wait_for("arm", Some("double"), JOIN)
            .await
            .expect("the executive sees the agent over TLS");
        // A fake agent with another authority's certificate, and one with none (a TCP
        // connection to the TLS port), offering the same task under names that come first: had
        // the executive seen them, `At::Any` would place the task on one of them.
        let fake = Agent::builder(sys.clone(), "a-fake")
            .command("double", |_: RemoteCtx, _: i64| async move {
                Ok::<_, RemoteFailure>(666)
            })
            .start(loopback_tls_connect(port, &fake_certs).expect("config"))
            .await
            .expect("the fake agent's session opens (its link does not)");
        let bare = Agent::builder(sys.clone(), "a-bare")
            .command("double", |_: RemoteCtx, _: i64| async move {
                Ok::<_, RemoteFailure>(666)
            })
            .start(tcm_zenoh::config::loopback_connect(port).expect("config"))
            .await
            .expect("the bare agent's session opens (its link does not)");
        for name in ["a-fake", "a-bare"] {
            assert!(
                exec.wait_for(name, None, Duration::from_secs(2))
                    .await
                    .is_err(),
                "{name} was seen"
            );
        }
        assert_eq!(exec.agents(), ["arm"]);
        assert_eq!(exec.offering("double"), ["arm"]);
        // What the fake agent sends reaches nobody: a forged done for the task to come.
        let forged = json!({"task": 1, "seq": 1, "body": {"kind": "done", "result": {"Ok": 666}}});
        fake.session()
            .put(
                format!("tdl/{sys}/to-exec/{}/arm", exec.id()),
                serde_json::to_vec(&forged).expect("JSON"),
            )
            .await
            .expect("a put, to nobody");
        let e = exec.clone();
        let main = Task::goal("main", move |ctx| async move {
            let v: Json = ctx
                .spawn(e.remote(tcm_zenoh::At::Any, "double", 21).task())
                .wait_value()
                .await?;
            assert_eq!(v, json!(42));
            Ok(())
        });
        let (report, _) = run_checked(Runtime::new(), main).await;
        assert_eq!(report.outcome, RunOutcome::Completed, "{report}");
        assert!(report.is_clean(), "{report}");
        let stats = exec.stats();
        assert_eq!(
            (stats.succeeded, stats.late, stats.strangers),
            (1, 0, 0),
            "{stats:?}"
        );
        assert_eq!((fake.stats().started, bare.stats().started), (0, 0));
        assert_eq!(arm.stats().started, 1);
        drop((fake, bare, arm));
        exec.close().await;
        let _ = std::fs::remove_dir_all(&dir);
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn under_access_control_a_member_cannot_speak_for_another_agent() {
    if Command::new("openssl").arg("version").output().is_err() {
        eprintln!("openssl is not on PATH: no certificates to test TLS with");
        return;
    }
    bounded(async {
        use tcm_zenoh::config::{Roster, with_access};
        let dir = scratch("acl");
        authority(&dir, "system");
        let exec_certs = certificate(&dir, "exec", "system");
        let arm_certs = certificate(&dir, "arm", "system");
        // A member of the system, with a certificate of its authority, that turns against it.
        let fake_certs = certificate(&dir, "fake", "system");
        let sys = system("acl");
        let roster = Roster {
            executives: vec!["exec".into()],
            agents: vec!["arm".into(), "fake".into()],
            clients: Vec::new(),
        };
        let port = tcm_zenoh::config::free_port().expect("a port");
        let config = with_access(
            loopback_tls_listen(port, &exec_certs).expect("config"),
            &sys,
            &roster,
        )
        .expect("config");
        let exec = Executive::open(&sys, config)
            .await
            .expect("the executive opens");
        let (gate, open) = tokio::sync::watch::channel(false);
        let arm = Agent::builder(sys.clone(), "arm")
            .command("gated", move |_: RemoteCtx, (): ()| {
                let mut open = open.clone();
                async move {
                    let _ = open.wait_for(|o| *o).await;
                    Ok::<_, RemoteFailure>("real")
                }
            })
            .start(
                with_access(
                    loopback_tls_connect(port, &arm_certs).expect("config"),
                    &sys,
                    &roster,
                )
                .expect("config"),
            )
            .await
            .expect("the agent starts");
        let fake = Agent::builder(sys.clone(), "fake")
            .command("other", |_: RemoteCtx, (): ()| async move {
                Ok::<_, RemoteFailure>(())
            })
            .start(loopback_tls_connect(port, &fake_certs).expect("config"))
            .await
            .expect("the fake agent starts");
        exec.wait_for("arm", Some("gated"), JOIN)
            .await
            .expect("the executive sees arm");
        exec.wait_for("fake", Some("other"), JOIN)
            .await
            .expect("the executive sees fake, a member");
        let e = exec.clone();
        let run = tokio::spawn(async move {
            let main = Task::goal("main", move |ctx| async move {
                let v: Json = ctx
                    .spawn(e.remote("arm", "gated", ()).task())
                    .wait_value()
                    .await?;
                assert_eq!(v, json!("real"));
                Ok(())
            });
            run_checked(Runtime::new(), main).await
        });
        // Once arm's `started` (number 1) is in, the fake member sends `done`, number 2, as arm:
        // without access control the executive would apply it.
        let start = std::time::Instant::now();
        while arm.running() == 0 {
            assert!(start.elapsed() < JOIN, "the body did not start");
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
        let forged =
            json!({"task": 1, "seq": 2, "body": {"kind": "done", "result": {"Ok": "forged"}}});
        for _ in 0..3 {
            fake.session()
                .put(
                    format!("tdl/{sys}/to-exec/{}/arm", exec.id()),
                    serde_json::to_vec(&forged).expect("JSON"),
                )
                .await
                .expect("a put");
        }
        tokio::time::sleep(Duration::from_millis(300)).await;
        gate.send_replace(true);
        let (report, _) = run.await.expect("the run");
        assert!(report.is_clean(), "{report}");
        let stats = exec.stats();
        assert_eq!(
            (
                stats.succeeded,
                stats.duplicates,
                stats.refused,
                stats.strangers
            ),
            (1, 0, 0, 0),
            "the forged done never reached the executive: {stats:?}"
        );
        drop((fake, arm));
        exec.close().await;
        let _ = std::fs::remove_dir_all(&dir);
    })
    .await;
}
