//! Steering the live demo from the viewer in a real headless browser (Debian's `chromium`,
//! installed by the test setup when missing): `xavier --view --control --approve notify_sender
//! --pause-at-start` on rooms 3 and 7. From the page opened at the address it prints (the run's
//! token in it): a breakpoint before `center_on_door`, set with the task-name field, pauses the
//! run there (the banner and the trace's `paused` record say so); Step, twice, starts two more
//! nodes; the breakpoint is removed and the run continued; an exception `Blocked` injected into
//! the next `guardedMove` (from a guarded move's details) makes the navigation of room 7 choose
//! its `detour` handler; each `notify_sender` is held until approved from its details; the run
//! ends and the process prints its summary. The trace, fetched from the viewer, goes through the
//! checker. Screenshots go to `target/viewer/`.

use std::io::{BufRead, BufReader};
use std::process::{ChildStdout, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{Context, bail, ensure};
use tcm_trace::{Facet, State, TraceEvent, TraceKind};
use test_support::browser::Browser;

use super::viewer::{Killed, chromium, runtime, shots};

/// Long enough for any one step of the test on a loaded machine.
const WAIT: Duration = Duration::from_secs(60);

/// The lines a child printed so far, read by a thread of their own.
#[derive(Clone, Default)]
struct Lines(Arc<Mutex<Vec<String>>>);

impl Lines {
    fn read(stdout: ChildStdout) -> Lines {
        let lines = Lines::default();
        let kept = lines.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                kept.0.lock().unwrap_or_else(|e| e.into_inner()).push(line);
            }
        });
        lines
    }

    /// The rest of the first line that starts with `prefix`, waiting up to `limit` for it.
    fn after(&self, prefix: &str, limit: Duration) -> anyhow::Result<String> {
        let start = Instant::now();
        loop {
            let found = self
                .0
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .iter()
                .find_map(|l| l.strip_prefix(prefix).map(str::to_string));
            if let Some(rest) = found {
                return Ok(rest);
            }
            if start.elapsed() > limit {
                bail!("no line starting with {prefix:?} within {limit:?}");
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

/// The run's trace so far, as the viewer serves it.
async fn trace(b: &mut Browser) -> anyhow::Result<Vec<TraceEvent>> {
    let text = b
        .eval("fetch('/api/runs/0/trace.jsonl').then((r) => r.text())")
        .await?;
    let text = text.as_str().context("the trace as text")?;
    Ok(tcm_trace::read_jsonl(text.as_bytes())?)
}

/// Polls the trace until `done` holds of it.
async fn wait_trace(
    b: &mut Browser,
    what: &str,
    done: impl Fn(&[TraceEvent]) -> bool,
) -> anyhow::Result<Vec<TraceEvent>> {
    let start = Instant::now();
    loop {
        let t = trace(b).await?;
        if done(&t) {
            return Ok(t);
        }
        if start.elapsed() > WAIT {
            bail!(
                "waited {WAIT:?} for {what}; the trace has {} records",
                t.len()
            );
        }
        tokio::time::sleep(Duration::from_millis(150)).await;
    }
}

/// The nodes whose handling became active, in order.
fn started(t: &[TraceEvent]) -> Vec<u64> {
    t.iter()
        .filter_map(|e| match e.kind {
            TraceKind::Transition {
                node,
                facet: Facet::Handling,
                to: State::Active,
                ..
            } => Some(node),
            _ => None,
        })
        .collect()
}

/// Why the run is paused after the last record, if it is.
fn paused(t: &[TraceEvent]) -> Option<&str> {
    let mut why = None;
    for e in t {
        match &e.kind {
            TraceKind::Paused { why: w, .. } => why = Some(w.as_str()),
            TraceKind::Resumed { .. } => why = None,
            _ => {}
        }
    }
    why
}

/// Each node's name and parent.
fn nodes(t: &[TraceEvent]) -> std::collections::BTreeMap<u64, (String, u64)> {
    t.iter()
        .filter_map(|e| match &e.kind {
            TraceKind::Spawned {
                node, parent, name, ..
            } => Some((*node, (name.clone(), *parent))),
            _ => None,
        })
        .collect()
}

/// Selects the node held first, from the bar's link, and approves it from its details.
async fn approve_held(b: &mut Browser, shot: Option<&str>) -> anyhow::Result<u64> {
    let held = b
        .wait_for("CTL.held.length ? CTL.held[0] : null", WAIT)
        .await?
        .as_u64()
        .context("a held node's number")?;
    b.click("#ctl-held a.node").await?;
    b.wait_for(
        &format!(
            "S.selected === {held} && !!document.querySelector('#ctl-node [data-ctl=approve]')"
        ),
        WAIT,
    )
    .await?;
    if let Some(name) = shot {
        b.screenshot(&shots().join(name)).await?;
    }
    b.click("#ctl-node [data-ctl=approve]").await?;
    b.wait_for(&format!("!CTL.held.includes({held})"), WAIT)
        .await?;
    Ok(held)
}

#[test]
fn the_demo_is_steered_from_the_viewer() -> anyhow::Result<()> {
    let chromium = chromium()?;
    let mut child = Killed(
        Command::new(env!("CARGO_BIN_EXE_xavier"))
            .args([
                "--view",
                "--listen",
                "127.0.0.1:0",
                "--control",
                "--approve",
                "notify_sender",
                "--pause-at-start",
                "--speed",
                "20",
                "--rooms",
                "3,7",
            ])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .context("cannot start xavier --view --control")?,
    );
    let out = Lines::read(child.0.stdout.take().context("the child's stdout")?);
    let url = out.after("control: ", WAIT)?;
    ensure!(
        url.starts_with("http://127.0.0.1:") && url.contains("?run=0&token="),
        "control url: {url}"
    );

    runtime().block_on(async {
        let mut b = Browser::start(&chromium, 1400, 900).await?;
        b.goto(&url).await?;
        // The page steers the run, paused before its first start.
        b.wait_for(
            "steering() && !document.getElementById('steerbar').hidden && CTL.paused !== null",
            WAIT,
        )
        .await?;

        // A breakpoint before each start of center_on_door, by the task's name; then continue.
        b.eval("document.getElementById('ctl-task').value = 'center_on_door'")
            .await?;
        b.click("#ctl-break-task").await?;
        b.wait_for("CTL.rules.some((r) => r.what === 'break before center_on_door')", WAIT)
            .await?;
        b.click("#ctl-continue").await?;
        let banner = b
            .wait_for(
                "(() => { const b = document.getElementById('ctl-banner'); \
                 return !b.hidden && b.textContent.includes('center_on_door') ? b.textContent : null; })()",
                WAIT,
            )
            .await?;
        ensure!(
            banner.as_str().is_some_and(|b| b.starts_with("paused: breakpoint #2: before center_on_door {")),
            "banner: {banner}"
        );
        b.screenshot(&shots().join("steer-breakpoint.png")).await?;
        let t = wait_trace(&mut b, "the breakpoint's pause", |t| {
            paused(t).is_some_and(|w| w.contains("before center_on_door"))
        })
        .await?;
        let before = started(&t).len();

        // Step, twice: two more starts, the run paused again after each.
        b.click("#ctl-step").await?;
        let t = wait_trace(&mut b, "the first step", |t| {
            started(t).len() == before + 1 && paused(t) == Some("step")
        })
        .await?;
        let first = started(&t)[before];
        ensure!(
            nodes(&t).get(&first).is_some_and(|(name, _)| name == "center_on_door"),
            "the first step started {first}, not the node the breakpoint held"
        );
        // The next start waits until the body just started spawned what it waits for.
        b.wait_for(
            "S.nodes.some((n) => n && n.n > 0 && stateAt(n, 0, S.records - 1) === 'enabled' \
             && !reached(n, M_TERMINATING, S.records - 1))",
            WAIT,
        )
        .await?;
        b.click("#ctl-step").await?;
        wait_trace(&mut b, "the second step", |t| {
            started(t).len() == before + 2 && paused(t) == Some("step")
        })
        .await?;

        // The breakpoint removed, the run continued: it runs to room 3's notify_sender, held.
        b.click("#ctl-rules [data-ctl=remove]").await?;
        b.wait_for("CTL.rules.length === 0", WAIT).await?;
        b.click("#ctl-continue").await?;
        b.wait_for("CTL.held.length > 0 && CTL.paused === null", WAIT)
            .await?;

        // Blocked, into the next guardedMove (room 7's first stretch), from a guarded move's
        // details: select one of room 3's, open "Inject exception…", name it.
        let moved = b
            .eval("S.nodes.find((n) => n && n.name === 'guardedMove').n")
            .await?
            .as_u64()
            .context("a guarded move in the tree")?;
        b.eval(&format!("reveal({moved})")).await?;
        let row = format!("#tree .row[data-n=\"{moved}\"] .name");
        let mut attempt = 0;
        loop {
            attempt += 1;
            b.click(&row).await?;
            let shown = b
                .wait_for(
                    &format!("S.selected === {moved} && !!document.querySelector('#ctl-node [data-ctl=inject]')"),
                    Duration::from_secs(10),
                )
                .await;
            match shown {
                Ok(_) => break,
                Err(_) if attempt < 3 => continue,
                Err(e) => return Err(e),
            }
        }
        b.click("#ctl-node [data-ctl=inject]").await?;
        b.eval("document.querySelector('#ctl-node [data-ctl=inject-exception]').value = 'Blocked'")
            .await?;
        b.screenshot(&shots().join("steer-inject.png")).await?;
        b.click("#ctl-node [data-ctl=inject-go]").await?;
        b.wait_for("CTL.rules.some((r) => r.what === 'inject Blocked into guardedMove')", WAIT)
            .await?;

        // Room 3's notify_sender approved: room 7's navigation meets the fault and detours.
        approve_held(&mut b, Some("steer-held.png")).await?;
        let t = wait_trace(&mut b, "the detour", |t| {
            t.iter().any(|e| matches!(&e.kind,
                TraceKind::HandlerChosen { handler, exception, .. } if handler == "detour" && exception == "Blocked"))
        })
        .await?;
        let names = nodes(&t);
        let injected = t.iter().find_map(|e| match &e.kind {
            TraceKind::Injected { node, outcome } => Some((*node, outcome.clone())),
            _ => None,
        });
        let (node, outcome) = injected.context("an injected record")?;
        let (name, parent) = names.get(&node).context("the injected node")?;
        ensure!(
            name == "guardedMove"
                && names.get(parent).is_some_and(|(p, _)| p == "navigate_to_locn")
                && outcome.starts_with("fail Blocked"),
            "injected into {name} {{{node}}} under {parent}: {outcome}"
        );

        // Room 7's notify_sender, approved in turn; the run ends.
        approve_held(&mut b, None).await?;
        if b.eval("CTL.paused !== null").await? == true {
            b.click("#ctl-continue").await?;
        }
        b.wait_for(
            "document.getElementById('status').textContent.startsWith('finished')",
            WAIT,
        )
        .await?;
        b.eval("render()").await?;
        b.screenshot(&shots().join("steer-finished.png")).await?;
        ensure!(
            b.eval("document.getElementById('steerbar').hidden").await? == true,
            "the bar is still shown once the run ended"
        );

        let t = trace(&mut b).await?;
        tcm::testing::assert_checked(&t);
        let approved: Vec<&str> = t
            .iter()
            .filter_map(|e| match &e.kind {
                TraceKind::Approved { by, .. } => Some(by.as_str()),
                _ => None,
            })
            .collect();
        ensure!(
            approved.len() == 2 && approved.iter().all(|by| by.starts_with("viewer 127.0.0.1:")),
            "approvals: {approved:?}"
        );
        let by_page = t
            .iter()
            .filter(|e| matches!(&e.kind, TraceKind::Control { by, .. } if by.starts_with("viewer 127.0.0.1:")))
            .count();
        // break, continue, step, step, remove, continue, inject, approve, approve.
        ensure!(by_page >= 9, "{by_page} control records from the page");
        anyhow::Ok(())
    })?;

    // The process printed its summary: both rooms delivered, the run completed.
    let delivered = out.after("  delivered:", WAIT)?;
    ensure!(delivered.trim() == "3, 7", "delivered: {delivered}");
    let run = out.after("  run:", WAIT)?;
    ensure!(run.trim() == "completed", "run: {run}");
    Ok(())
}
