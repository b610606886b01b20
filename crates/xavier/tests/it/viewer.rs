//! The viewer in a real headless browser (Debian's `chromium`, installed by the test setup when
//! missing): on a trace file of the mission, as `tdl view` serves it, the tree shows the mission's
//! nodes, a node that waits lists its unsatisfied constraint, moving the time cursor changes a
//! node's state; and on the live demo (`xavier --view`), nodes appear while it runs. Screenshots
//! go to `target/viewer/`.

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use anyhow::{Context, bail, ensure};

use test_support::browser::Browser;

pub(crate) fn shots() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/viewer")
}

pub(crate) fn chromium() -> anyhow::Result<PathBuf> {
    test_support::ensure_tool("chromium", "chromium").map_err(|e| anyhow::anyhow!(e))
}

pub(crate) fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("a tokio runtime for the browser client")
}

/// A child process killed when dropped.
pub(crate) struct Killed(pub(crate) Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Reads the child's stdout until a line starts with `prefix`; returns the rest of that line.
fn read_url(child: &mut Child, prefix: &str) -> anyhow::Result<String> {
    let stdout = child.stdout.take().context("the child's stdout")?;
    let (tx, rx) = std::sync::mpsc::channel();
    let wanted = prefix.to_string();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if let Some(rest) = line.strip_prefix(&wanted) {
                let url = rest
                    .split_whitespace()
                    .next()
                    .unwrap_or_default()
                    .to_string();
                let _ = tx.send(url);
            }
        }
    });
    rx.recv_timeout(Duration::from_secs(60))
        .with_context(|| format!("no line starting with {prefix:?} within 60 s"))
}

#[test]
fn the_viewer_shows_a_mission_trace_why_a_node_waits_and_replays_it() -> anyhow::Result<()> {
    let chromium = chromium()?;
    let dir = std::env::temp_dir().join(format!("xavier-view-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let trace = dir.join("mission.jsonl");
    let out = Command::new(env!("CARGO_BIN_EXE_xavier"))
        .args(["--scenario", "blocked-corridor", "--trace"])
        .arg(&trace)
        .output()?;
    ensure!(out.status.success(), "xavier failed: {out:?}");

    // What `tdl view FILE` does (crates/tdl-cli/src/serve.rs), on a free port.
    let text = std::fs::read(&trace)?;
    let model = tcm_view::RunModel::read("mission.jsonl", "mission.jsonl", &text[..]);
    ensure!(model.problem.is_none(), "{:?}", model.problem);
    let viewer = tcm_view::Viewer::serve(([127, 0, 0, 1], 0).into())?;
    viewer.add(model);
    let url = viewer.url();

    runtime().block_on(async {
        let mut b = Browser::start(&chromium, 1400, 850).await?;
        b.goto(&url).await?;
        // The tree shows the mission's nodes.
        b.wait_for(
            "document.querySelectorAll('#tree .row:not([hidden])').length > 20",
            Duration::from_secs(20),
        )
        .await?;
        let names = b
            .eval("[...document.querySelectorAll('#tree .row:not([hidden]) .name')].map(e => e.textContent).join(' ')")
            .await?;
        let names = names.as_str().unwrap_or_default().to_string();
        for want in ["deliver_all", "deliver_mail", "navigate_to_locn", "guardedMove"] {
            ensure!(names.contains(want), "{want} is not in the tree: {names}");
        }
        let status = b.eval("document.getElementById('status').textContent").await?;
        ensure!(
            status.as_str().is_some_and(|s| s.starts_with("finished")),
            "status: {status}"
        );

        // A node whose execution was held after its spawn: the cursor just before it was enabled.
        let found = b
            .eval(
                "(() => { for (const n of S.nodes) { if (!n || n.n === 0) continue; \
                   const s = n.m[0], e = n.m[7]; \
                   if (s >= 0 && e >= 0 && tOf(e) > tOf(s)) return [n.n, e, seqAt(tOf(e) - 1)]; } \
                   return null; })()",
            )
            .await?;
        // The node, the record enabling its execution, the last record before that time.
        let ids = found.as_array().map(|a| (a[0].as_u64(), a[1].as_u64(), a[2].as_u64()));
        let (node, enabled_at, before_that) = match ids {
            Some((Some(n), Some(e), Some(b))) => (n, e, b),
            _ => bail!("no node of the mission waits after its spawn: {found}"),
        };
        // Move the cursor with the slider, as a person drags it.
        let set_cursor = |seq: u64| {
            format!(
                "(() => {{ const c = document.getElementById('cursor'); c.value = {seq}; \
                 c.dispatchEvent(new Event('input')); return Number(c.value); }})()"
            )
        };
        b.eval(&set_cursor(before_that)).await?;
        // Bring its row into sight, then click it with the mouse.
        b.eval(&format!("reveal({node})")).await?;
        let row = format!("#tree .row[data-n=\"{node}\"]");
        b.wait_for(&format!("!!document.querySelector('{row}')"), Duration::from_secs(5))
            .await?;
        let before = b
            .eval(&format!("document.querySelector('{row}').dataset.e"))
            .await?;
        ensure!(before == "disabled", "execution of {{{node}}} before: {before}");
        // A click that lands while the rows are still being redrawn (a loaded machine) selects
        // nothing: click again, as a person would, where the row now is.
        let mut attempt = 0;
        let waits = loop {
            attempt += 1;
            b.click(&format!("{row} .name")).await?;
            let shown = b
                .wait_for(
                    "(() => { const w = document.querySelectorAll('#waits li'); \
                     return w.length ? [...w].map(e => e.textContent).join(' | ') : null; })()",
                    Duration::from_secs(5),
                )
                .await;
            match shown {
                Ok(w) => break w,
                Err(_) if attempt < 3 => continue,
                Err(e) => return Err(e),
            }
        };
        let waits = waits.as_str().unwrap_or_default().to_string();
        ensure!(
            waits.contains("execution:") && waits.contains("since"),
            "the waits of {{{node}}} do not name its execution's constraint: {waits}"
        );
        b.screenshot(&shots().join("xavier-why-waiting.png")).await?;

        // One record later the execution is enabled: the row's state changes.
        b.eval(&set_cursor(enabled_at)).await?;
        let after = b
            .wait_for(
                &format!(
                    "(() => {{ const r = document.querySelector('{row}'); \
                     return r && r.dataset.e !== 'disabled' ? r.dataset.e : null; }})()"
                ),
                Duration::from_secs(5),
            )
            .await?;
        ensure!(after != "disabled", "state after: {after}");
        let still_waiting = b
            .wait_for(
                "(() => { const w = document.getElementById('waits'); \
                 return w && !w.textContent.includes('execution:') ? 'ok' : null; })()",
                Duration::from_secs(10),
            )
            .await;
        ensure!(still_waiting.is_ok(), "the execution wait is still listed once enabled");

        // The whole run, a node that failed selected, for the README.
        b.eval(&set_cursor(1_000_000)).await?;
        let failed = b
            .eval("(() => { const n = S.nodes.find(n => n && n.m[15] >= 0); return n ? n.n : null; })()")
            .await?;
        let failed = failed.as_u64().context("the blocked-corridor run has a failed node")?;
        b.eval(&format!("reveal({failed})")).await?;
        b.click(&format!("#tree .row[data-n=\"{failed}\"] .name")).await?;
        b.wait_for(
            "[...document.querySelectorAll('#tab-node h3')].some(h => h.textContent === 'Failures')",
            Duration::from_secs(10),
        )
        .await?;
        b.screenshot(&shots().join("xavier-trace.png")).await?;

        // The exception's story: raised by the guarded move, the detour handler chosen.
        b.click("#tabs [data-tab=exceptions]").await?;
        let story = b
            .wait_for(
                "(() => { const e = document.querySelector('#tab-exceptions .exc'); \
                 return e ? e.textContent : null; })()",
                Duration::from_secs(10),
            )
            .await?;
        let story = story.as_str().unwrap_or_default();
        ensure!(
            story.contains("Blocked") && story.contains("guardedMove") && story.contains("chosen"),
            "exceptions tab: {story}"
        );
        b.screenshot(&shots().join("xavier-exceptions.png")).await?;

        // Counts and durations per task.
        b.click("#tabs [data-tab=stats]").await?;
        let stats = b
            .wait_for(
                "(() => { const r = [...document.querySelectorAll('#tab-stats tr')] \
                 .find(r => r.cells[0] && r.cells[0].textContent === 'guardedMove'); \
                 return r ? [...r.cells].map(c => c.textContent) : null; })()",
                Duration::from_secs(10),
            )
            .await?;
        // The column headed `failed` (columns: task, kind, nodes, ok, skipped, failed, …).
        let failed_at = b
            .eval(
                "[...document.querySelectorAll('#tab-stats th')].findIndex(h => h.textContent === 'failed')",
            )
            .await?
            .as_u64()
            .unwrap_or(5) as usize;
        let failed_moves = stats[failed_at].as_str().unwrap_or_default();
        ensure!(failed_moves == "1", "guardedMove's row: {stats}");

        // The event list, filtered by name and time range.
        b.click("#tabs [data-tab=events]").await?;
        b.eval(
            "document.getElementById('evname').value = 'planPath'; \
             document.getElementById('evfrom').value = '50'; \
             document.getElementById('evto').value = '60';",
        )
        .await?;
        b.click("#evfilter button").await?;
        let listed = b
            .wait_for(
                "(() => { const l = [...document.querySelectorAll('#evlist li')]; \
                 return l.length && l.length < 50 ? l.map(e => e.textContent) : null; })()",
                Duration::from_secs(10),
            )
            .await?;
        let listed: Vec<&str> = listed
            .as_array()
            .map(|a| a.iter().filter_map(|v| v.as_str()).collect())
            .unwrap_or_default();
        ensure!(
            listed.iter().all(|l| l.contains("planPath")),
            "only planPath's records: {listed:?}"
        );
        let times_ok = listed.iter().all(|l| {
            l.split_whitespace()
                .nth(1)
                .and_then(|t| t.parse::<f64>().ok())
                .is_some_and(|t| (50.0..=60.0).contains(&t))
        });
        ensure!(times_ok, "records between 50 s and 60 s: {listed:?}");
        b.screenshot(&shots().join("xavier-events.png")).await?;
        anyhow::Ok(())
    })?;
    viewer.stop();
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}

#[test]
fn the_live_demo_shows_nodes_appear_while_it_runs() -> anyhow::Result<()> {
    let chromium = chromium()?;
    let child = Command::new(env!("CARGO_BIN_EXE_xavier"))
        .args([
            "--view",
            "--listen",
            "127.0.0.1:0",
            "--speed",
            "25",
            "--rooms",
            "3,7",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .context("cannot start xavier --view")?;
    let mut child = Killed(child);
    let url = read_url(&mut child.0, "viewer: ")?;
    ensure!(url.starts_with("http://127.0.0.1:"), "url: {url}");

    runtime().block_on(async {
        let mut b = Browser::start(&chromium, 1400, 850).await?;
        b.goto(&url).await?;
        b.wait_for("S.records > 0", Duration::from_secs(20)).await?;
        // Counts of nodes seen over time, while the run is live.
        let mut counts = Vec::new();
        for _ in 0..40 {
            let c = b
                .eval("[S.nodes.filter(n => n).length, S.finished]")
                .await?;
            let n = c[0].as_u64().unwrap_or(0);
            let finished = c[1].as_bool().unwrap_or(true);
            if finished {
                break;
            }
            if counts.last() != Some(&n) {
                counts.push(n);
            }
            if counts.len() >= 3 {
                break;
            }
            tokio::time::sleep(Duration::from_millis(250)).await;
        }
        ensure!(
            counts.len() >= 3 && counts.windows(2).all(|w| w[0] < w[1]),
            "nodes did not appear while the run was live: {counts:?}"
        );
        b.screenshot(&shots().join("xavier-live.png")).await?;
        // It finishes, and the page says so.
        b.wait_for(
            "document.getElementById('status').textContent.startsWith('finished')",
            Duration::from_secs(120),
        )
        .await?;
        let rows = b
            .eval("document.querySelectorAll('#tree .row:not([hidden])').length")
            .await?;
        ensure!(rows.as_u64().unwrap_or(0) > 20, "rows at the end: {rows}");
        anyhow::Ok(())
    })?;
    Ok(())
}
