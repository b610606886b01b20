//! The page in a real headless browser (Debian's `chromium`, installed by the test setup when
//! missing): a page opened before a live run's first record builds its rows from the live
//! messages alone, and they are the rows the page reads from the snapshot when it opens the run
//! again after its end; both look the same. On a run with monitors, served as a trace file is:
//! a monitor's many activations fold into one row with their count, listed by a click; search
//! matches names, or paths when the query has a `/`; a node's details are those at the cursor;
//! an address with `?run=RUN&at=SEQ` opens that run with its cursor on that record;
//! the Exceptions tab tells a failure a waiting parent took as taken by it; a skipped node looks
//! skipped. On a run with state variables: a lane per variable with its value at the cursor, a
//! node's wait on a condition with the values that hold it, skipped nodes counted apart, and a
//! live page's lanes the same as the snapshot's. On a run whose bodies log: the Log tab lists
//! each line with its time and node, and dims those after the cursor.
//! Screenshots go to `target/viewer/`.

mod common;

use std::path::PathBuf;
use std::time::Duration;

use anyhow::ensure;
use tcm::TraceSink;
use tcm_trace::TraceEvent;
use tcm_view::{RunModel, Viewer};
use test_support::browser::Browser;

async fn mission() -> Vec<TraceEvent> {
    common::mission(true).await
}

/// Every node the page holds: number, parent, kind, name, marks, agent, children.
const NODES: &str =
    "JSON.stringify(S.nodes.map((n) => n && [n.n, n.p, n.k, n.name, n.m, n.agent, n.kids]))";

/// Opens the page on a live run, and once it is subscribed (it has the empty snapshot, so every
/// record comes live), feeds it `trace` through `sink` and waits until `done` holds. An
/// evaluation the navigation cut short is asked again.
async fn feed_live(
    b: &mut Browser,
    url: &str,
    sink: &mut impl TraceSink,
    trace: &[tcm::TraceEvent],
    done: &str,
) -> anyhow::Result<()> {
    b.goto(url).await?;
    let subscribed =
        "S.runId === 0 && document.getElementById('status').textContent.startsWith('live')";
    let mut tries = 0;
    while let Err(e) = b.wait_for(subscribed, Duration::from_secs(20)).await {
        tries += 1;
        ensure!(tries < 3, "the page did not open the run: {e}");
    }
    for ev in trace {
        sink.record(ev);
    }
    sink.flush();
    b.wait_for(done, Duration::from_secs(20)).await?;
    Ok(())
}

/// Clicks `selector` from the page's own script: a row of the tree is clicked where it is now,
/// even if the page's layout moved since the browser last measured it (the lanes of the state
/// variables are drawn once the snapshot came).
async fn js_click(b: &mut Browser, selector: &str) -> anyhow::Result<()> {
    let clicked = b
        .eval(&format!(
            "(() => {{ const e = document.querySelector('{selector}'); if (e) e.click(); return e !== null; }})()"
        ))
        .await?;
    anyhow::ensure!(clicked == true, "nothing matches {selector}");
    Ok(())
}

/// The browser tests of this file, one at a time: several Chromium instances drawing at once on a
/// loaded machine made their pages miss their own timers.
fn one_browser_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    static ONE: std::sync::Mutex<()> = std::sync::Mutex::new(());
    ONE.lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

#[test]
fn a_live_page_builds_the_rows_a_page_reads_from_the_snapshot() -> anyhow::Result<()> {
    let _one = one_browser_at_a_time();
    let chromium =
        test_support::ensure_tool("chromium", "chromium").map_err(|e| anyhow::anyhow!(e))?;
    let trace = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .start_paused(true)
        .build()?
        .block_on(mission());
    let viewer = tcm_view::Viewer::serve(([127, 0, 0, 1], 0).into())?;
    let mut sink = viewer.live("mission");
    let url = viewer.url();
    let shots = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/viewer");
    let n = trace.len();
    let done = format!("S.finished && S.records === {n}");
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?
        .block_on(async {
            let mut b = Browser::start(&chromium, 1200, 700).await?;
            feed_live(&mut b, &url, &mut sink, &trace, &done).await?;
            let live = b.eval(NODES).await?;
            std::fs::create_dir_all(&shots)?;
            std::fs::write(
                shots.join("live-rows.json"),
                live.as_str().unwrap_or_default(),
            )?;
            b.eval("render()").await?;
            b.screenshot(&shots.join("live-built.png")).await?;

            // The same run opened again (state cleared, a new connection): everything from the
            // snapshot. `open` clears the page's rows at once, so `done` waits for the snapshot.
            b.eval("open(0)").await?;
            b.wait_for(&done, Duration::from_secs(20)).await?;
            let fresh = b.eval(NODES).await?;
            b.eval("render()").await?;
            b.screenshot(&shots.join("live-snapshot.png")).await?;

            let rows = live.as_str().unwrap_or_default();
            ensure!(
                rows.contains("\"arm\"") && rows.contains("\"shrug\""),
                "the live page lacks the agent or the handler: {rows}"
            );
            ensure!(
                live == fresh,
                "the live page's rows differ from the snapshot's:\nlive:  {live}\nfresh: {fresh}"
            );
            anyhow::Ok(())
        })?;
    viewer.stop();
    Ok(())
}

fn shots() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/viewer")
}

fn paused(
    f: impl std::future::Future<Output = Vec<TraceEvent>>,
) -> anyhow::Result<Vec<TraceEvent>> {
    Ok(tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .start_paused(true)
        .build()?
        .block_on(f))
}

/// `trace` served whole under the name `file`, as `tdl view` serves a file.
fn serve_trace(file: &str, trace: &[TraceEvent]) -> anyhow::Result<Viewer> {
    let mut model = RunModel::new(file);
    for ev in trace {
        model.apply(ev).map_err(anyhow::Error::msg)?;
    }
    model.finished = true;
    let viewer = Viewer::serve(([127, 0, 0, 1], 0).into())?;
    viewer.add(model);
    Ok(viewer)
}

/// The patrol's trace served whole; the viewer and the records.
fn serve_patrol() -> anyhow::Result<(Viewer, usize)> {
    let trace = paused(common::patrol())?;
    Ok((serve_trace("patrol.jsonl", &trace)?, trace.len()))
}

/// A browser on the viewer's page, once the run's `records` records are shown.
async fn open_page(url: &str, records: usize) -> anyhow::Result<Browser> {
    let chromium =
        test_support::ensure_tool("chromium", "chromium").map_err(|e| anyhow::anyhow!(e))?;
    let mut b = Browser::start(&chromium, 1200, 700).await?;
    b.goto(url).await?;
    let shown = format!(
        "S.finished && S.records === {records} && document.querySelectorAll('#tree .row:not([hidden])').length > 3"
    );
    b.wait_for(&shown, Duration::from_secs(20)).await?;
    Ok(b)
}

/// The rows in sight, top to bottom: a node's name, or a folded group as `name ×count`.
const ROWS: &str = "[...document.querySelectorAll('#tree .row:not([hidden])')]\
    .sort((a, b) => parseFloat(a.style.top) - parseFloat(b.style.top))\
    .map((r) => r.querySelector('.name').textContent \
        + (r.dataset.group ? ' ' + r.querySelector('.count').textContent : ''))";

async fn rows(b: &mut Browser) -> anyhow::Result<Vec<String>> {
    let v = b.eval(ROWS).await?;
    Ok(v.as_array()
        .map(|a| {
            a.iter()
                .filter_map(|s| s.as_str().map(String::from))
                .collect()
        })
        .unwrap_or_default())
}

/// Moves the time cursor with the slider, as a person drags it.
fn set_cursor(seq: u64) -> String {
    format!(
        "(() => {{ const c = document.getElementById('cursor'); c.value = {seq}; \
         c.dispatchEvent(new Event('input')); return Number(c.value); }})()"
    )
}

#[test]
fn a_monitors_many_activations_fold_into_one_row_with_their_count() -> anyhow::Result<()> {
    let _one = one_browser_at_a_time();
    let (viewer, records) = serve_patrol()?;
    let url = viewer.url();
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?
        .block_on(async {
            let mut b = open_page(&url, records).await?;
            // `tick`'s ten activations are one row; `watch`'s three are listed, as few as they
            // are; the whole mission is on the first screen.
            let first = rows(&mut b).await?;
            b.screenshot(&shots().join("patrol-folded.png")).await?;
            let want = [
                "patrol", "watch", "ACT-watch", "ACT-watch", "ACT-watch", "tick", "ACT-tick ×10",
                "drive", "fetch", "probe",
            ];
            ensure!(first == want, "rows in sight: {first:?}");

            // A click lists them under the folded row; another folds them again.
            b.click("#tree .row[data-group]").await?;
            let listed = b
                .wait_for(
                    &format!("(() => {{ const r = {ROWS}; return r.filter((n) => n === 'ACT-tick').length === 10 ? r : null; }})()"),
                    Duration::from_secs(15),
                )
                .await?;
            ensure!(
                listed[6] == "ACT-tick ×10" && listed[7] == "ACT-tick" && listed[17] == "drive",
                "unfolded: {listed}"
            );
            b.screenshot(&shots().join("patrol-unfolded.png")).await?;
            b.click("#tree .row[data-group]").await?;
            b.wait_for(
                &format!("!{ROWS}.includes('ACT-tick')"),
                Duration::from_secs(15),
            )
            .await?;

            // At the second activation's spawn, the row counts two.
            let second = b
                .eval("S.nodes.filter((n) => n && n.name === 'ACT-tick').map((n) => n.m[0]).sort((a, b) => a - b)[1]")
                .await?;
            let second = second.as_u64().ok_or_else(|| anyhow::anyhow!("no second tick"))?;
            b.eval(&set_cursor(second)).await?;
            b.wait_for(
                &format!("{ROWS}.includes('ACT-tick ×2')"),
                Duration::from_secs(15),
            )
            .await?;

            // Revealing one activation (as the event list's links do) unfolds its group.
            b.eval(&set_cursor(1_000_000)).await?;
            let fifth = b
                .eval("S.nodes.filter((n) => n && n.name === 'ACT-tick')[4].n")
                .await?;
            b.eval(&format!("select({fifth}, true)")).await?;
            b.wait_for(
                &format!("!!document.querySelector('#tree .row.sel[data-n=\"{fifth}\"]')"),
                Duration::from_secs(15),
            )
            .await?;
            anyhow::Ok(())
        })?;
    viewer.stop();
    Ok(())
}

/// Types `text` in the search box, and waits until the page says how many rows match.
async fn search(b: &mut Browser, text: &str) -> anyhow::Result<String> {
    let text = serde_json::to_string(text)?;
    b.eval(&format!(
        "(() => {{ const s = document.getElementById('search'); s.value = {text}; \
         s.dispatchEvent(new Event('input')); }})()"
    ))
    .await?;
    let said = b
        .wait_for(
            &format!(
                "S.query === {text}.trim() && !S.dirty \
                 && [document.getElementById('matches').textContent]"
            ),
            Duration::from_secs(15),
        )
        .await?;
    Ok(said[0].as_str().unwrap_or_default().to_string())
}

#[test]
fn search_matches_names_and_paths_when_asked() -> anyhow::Result<()> {
    let _one = one_browser_at_a_time();
    let (viewer, records) = serve_patrol()?;
    let url = viewer.url();
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?
        .block_on(async {
            let mut b = open_page(&url, records).await?;
            // The top goal's name is in every path, but only its own row matches it.
            ensure!(search(&mut b, "patrol").await? == "1 match");
            let shown = rows(&mut b).await?;
            ensure!(shown == ["patrol"], "rows shown: {shown:?}");

            // A name shared by a monitor's activations: their group, listed.
            ensure!(search(&mut b, "TICK").await? == "11 matches");
            let shown = rows(&mut b).await?;
            ensure!(
                shown.len() == 13 && shown[..3] == ["patrol", "tick", "ACT-tick ×10"],
                "rows shown: {shown:?}"
            );

            // With a `/`, paths: what is under `patrol` whose name starts with `dr`, and the
            // child of `fetch`.
            ensure!(search(&mut b, "patrol/dr").await? == "1 match");
            ensure!(rows(&mut b).await? == ["patrol", "drive"]);
            ensure!(search(&mut b, "fetch/").await? == "1 match");
            ensure!(rows(&mut b).await? == ["patrol", "fetch", "probe"]);
            // Enter goes to the match and selects it.
            b.eval("document.getElementById('search').dispatchEvent(new KeyboardEvent('keydown', { key: 'Enter' }))")
                .await?;
            b.wait_for(
                "(() => { const r = document.querySelector('#tree .row.sel .name'); return r && r.textContent === 'probe'; })()",
                Duration::from_secs(15),
            )
            .await?;

            // Cleared, every row is back.
            ensure!(search(&mut b, "").await?.is_empty());
            ensure!(rows(&mut b).await?.len() == 10);
            anyhow::Ok(())
        })?;
    viewer.stop();
    Ok(())
}

/// The Node tab's value for `key`, once shown.
fn detail(key: &str) -> String {
    format!(
        "(() => {{ const d = [...document.querySelectorAll('#tab-node dt')].find((d) => d.textContent === '{key}'); \
         return d ? d.nextElementSibling.textContent : null; }})()"
    )
}

#[test]
fn a_nodes_details_are_those_at_the_cursor() -> anyhow::Result<()> {
    let _one = one_browser_at_a_time();
    let (viewer, records) = serve_patrol()?;
    let url = viewer.url();
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?
        .block_on(async {
            let mut b = open_page(&url, records).await?;
            // The cursor at `watch`'s first activation (the record after its node's spawn).
            let first = b
                .eval("S.nodes.find((n) => n && n.name === 'ACT-watch').m[0] + 1")
                .await?;
            let first = first
                .as_u64()
                .ok_or_else(|| anyhow::anyhow!("no activation"))?;
            b.eval(&set_cursor(first)).await?;
            let watch = "#tree .row:not([hidden])[data-n=\"2\"] .name";
            ensure!(
                b.eval(&format!("document.querySelector('{watch}').textContent"))
                    .await?
                    == "watch"
            );
            js_click(&mut b, watch).await?;
            let at_first = format!("{0} === '1 · 0' && {0}", detail("activations · triggers"));
            if let Err(e) = b.wait_for(&at_first, Duration::from_secs(15)).await {
                let d = b.eval(&detail("activations · triggers")).await?;
                let tab = b
                    .eval("document.getElementById('tab-node').innerText.slice(0, 200)")
                    .await?;
                anyhow::bail!("{e}: the detail reads {d}; the node tab: {tab}");
            }
            ensure!(b.eval(&detail("children")).await? == "1");
            b.screenshot(&shots().join("patrol-first-activation.png"))
                .await?;

            // At the end, all three.
            b.eval(&set_cursor(1_000_000)).await?;
            let at_end = format!(
                "{0}.startsWith('3 · ') && {0}",
                detail("activations · triggers")
            );
            b.wait_for(&at_end, Duration::from_secs(15)).await?;
            ensure!(b.eval(&detail("children")).await? == "3");
            anyhow::Ok(())
        })?;
    viewer.stop();
    Ok(())
}

/// The address `tdl view --at` prints, `?run=RUN&at=SEQ`: the page opens that run with its cursor
/// on that record, and keeps it there (a finished run opens on its last record otherwise).
#[test]
fn an_address_with_run_and_at_opens_that_run_on_that_record() -> anyhow::Result<()> {
    let _one = one_browser_at_a_time();
    let (viewer, records) = serve_patrol()?;
    // A second run, the same records under another name: the address chooses it.
    let mut again = RunModel::new("again.jsonl");
    for ev in &paused(common::patrol())? {
        again.apply(ev).map_err(anyhow::Error::msg)?;
    }
    again.finished = true;
    let run = viewer.add(again);
    ensure!(run == 1, "the second run is {run}");
    let at = records as u64 / 2;
    let url = viewer.url_at(run, at);
    ensure!(url.ends_with(&format!("/?run=1&at={at}")), "{url}");
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?
        .block_on(async {
            let mut b = open_page(&url, records).await?;
            ensure!(b.eval("S.runId").await? == 1, "another run is open");
            let shown = b
                .wait_for(
                    &format!(
                        "(() => {{ const c = document.getElementById('cursor'); \
                         return Number(c.value) === {at} && \
                         [c.value, document.getElementById('cursorlabel').textContent]; }})()"
                    ),
                    Duration::from_secs(15),
                )
                .await?;
            let label = shown[1].as_str().unwrap_or_default();
            ensure!(
                label.starts_with(&format!("record {at} of {records} ")),
                "the cursor's label: {label}"
            );
            ensure!(b.eval("S.follow").await? == false, "it follows the tail");
            b.screenshot(&shots().join("patrol-opened-at.png")).await?;
            anyhow::Ok(())
        })?;
    viewer.stop();
    Ok(())
}

#[test]
fn the_exceptions_tab_tells_a_failure_a_waiting_parent_took() -> anyhow::Result<()> {
    let _one = one_browser_at_a_time();
    let (viewer, records) = serve_patrol()?;
    let url = viewer.url();
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?
        .block_on(async {
            let mut b = open_page(&url, records).await?;
            b.click("#tabs [data-tab=exceptions]").await?;
            let told = b
                .wait_for(
                    "(() => { const e = [...document.querySelectorAll('#tab-exceptions .exc')]; \
                     return e.length === 2 ? e.map((x) => x.textContent) : null; })()",
                    Duration::from_secs(10),
                )
                .await?;
            b.screenshot(&shots().join("patrol-exceptions.png")).await?;
            let probe = told[0].as_str().unwrap_or_default();
            ensure!(
                probe.contains("raised by patrol/fetch/probe")
                    && probe.contains("taken by its parent fetch {5}, which failed with it")
                    && !probe.contains("pending"),
                "probe's story: {probe}"
            );
            let fetch = told[1].as_str().unwrap_or_default();
            ensure!(
                fetch.contains("raised by patrol/fetch {5}") && fetch.contains("unhandled"),
                "fetch's story: {fetch}"
            );
            // The parent's link selects it.
            b.click("#tab-exceptions .exc .steps a.node").await?;
            b.wait_for(
                "(() => { const r = document.querySelector('#tree .row.sel .name'); return r && r.textContent === 'fetch'; })()",
                Duration::from_secs(15),
            )
            .await?;
            anyhow::Ok(())
        })?;
    viewer.stop();
    Ok(())
}

/// A patrol whose bodies log: the goal at once, `drive` after 1 s, `look` after 2 s; `dock`
/// logs nothing. `drive` is given an argument, which its task describes.
async fn logging() -> Vec<TraceEvent> {
    use tcm::{Runtime, Task};
    let after = |name: &'static str, s: u64, line: Option<&'static str>| {
        Task::command(name, move |ctx| async move {
            tokio::time::sleep(Duration::from_secs(s)).await;
            if let Some(line) = line {
                ctx.log(line)?;
            }
            Ok(())
        })
    };
    let task = Task::goal("patrol", move |ctx| async move {
        ctx.log("patrol begins")?;
        let drive = after("drive", 1, Some("at the door"))
            .with_args(("door".to_string(),))
            .describe_args(|a| {
                a.downcast_ref::<(String,)>()
                    .map(|(to,)| format!("to = {to:?}"))
            });
        ctx.spawn(drive).start()?;
        ctx.spawn(after("look", 2, Some("nobody in"))).start()?;
        ctx.spawn(after("dock", 3, None)).start()?;
        Ok(())
    });
    tcm::testing::run_checked(Runtime::new(), task).await.1
}

#[test]
fn the_log_tab_lists_the_lines_bodies_wrote_and_a_nodes_details_its_arguments() -> anyhow::Result<()>
{
    let _one = one_browser_at_a_time();
    let trace = paused(logging())?;
    let viewer = serve_trace("logging.jsonl", &trace)?;
    let url = viewer.url();
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?
        .block_on(async {
            let mut b = open_page(&url, trace.len()).await?;
            b.click("#tabs [data-tab=log]").await?;
            let lines = b
                .wait_for(
                    "(() => { const l = [...document.querySelectorAll('#loglist li')]; \
                     return l.length === 3 ? l.map((x) => x.textContent) : null; })()",
                    Duration::from_secs(10),
                )
                .await?;
            let line = |i: usize| lines[i].as_str().unwrap_or_default().to_string();
            for (i, (node, text)) in [
                ("patrol {1}", "patrol begins"),
                ("drive {2}", "at the door"),
                ("look {3}", "nobody in"),
            ]
            .into_iter()
            .enumerate()
            {
                ensure!(
                    line(i).contains(&format!("{node}: {text}")),
                    "line {i}: {}",
                    line(i)
                );
            }
            // The cursor at the run's end: no line is after it. A click on the first moves the
            // cursor there, and the two written later are dimmed.
            let later = "document.querySelectorAll('#loglist li.later').length";
            ensure!(b.eval(later).await? == 0, "no line after the end");
            js_click(&mut b, "#loglist li").await?;
            b.wait_for(&format!("{later} === 2"), Duration::from_secs(10))
                .await?;
            b.screenshot(&shots().join("logging-log.png")).await?;
            // `drive`'s details tell the argument it was spawned with; `look` was given none.
            b.eval(&set_cursor(1_000_000)).await?;
            b.click("#tabs [data-tab=node]").await?;
            js_click(&mut b, "#tree .row:not([hidden])[data-n=\"2\"] .name").await?;
            b.wait_for(
                &format!("{} === 'to = \"door\"'", detail("arguments")),
                Duration::from_secs(10),
            )
            .await?;
            js_click(&mut b, "#tree .row:not([hidden])[data-n=\"3\"] .name").await?;
            b.wait_for(
                &format!(
                    "document.querySelector('#tab-node h3').textContent.startsWith('look') && {} === null",
                    detail("arguments")
                ),
                Duration::from_secs(10),
            )
            .await?;
            anyhow::Ok(())
        })?;
    viewer.stop();
    Ok(())
}

/// `dock`, skipped (the robot is docked already), beside `undock` (1 s).
async fn skipping() -> Vec<TraceEvent> {
    use tcm::{Constraint, Expr, Runtime, StateType, StateVar, Task};
    let task = Task::goal("mission", |ctx| async move {
        let docked = StateVar::new("docked", StateType::Bool, true);
        let cond = ctx.condition(&[docked], Expr::Var("docked".into()))?;
        ctx.spawn(Task::command("dock", |_| async { Ok(()) }))
            .with(Constraint::skip_if(cond))
            .start()?;
        ctx.spawn(Task::command("undock", |_| async {
            tokio::time::sleep(Duration::from_secs(1)).await;
            Ok(())
        }))
        .start()?;
        Ok(())
    });
    tcm::testing::run_checked(Runtime::new(), task).await.1
}

#[test]
fn a_skipped_node_looks_skipped() -> anyhow::Result<()> {
    let _one = one_browser_at_a_time();
    let trace = paused(skipping())?;
    let mut model = RunModel::new("skipping.jsonl");
    for ev in &trace {
        model.apply(ev).map_err(anyhow::Error::msg)?;
    }
    model.finished = true;
    let dock = model
        .rows()
        .iter()
        .find(|r| r.name == "dock")
        .map(|r| r.number)
        .ok_or_else(|| anyhow::anyhow!("no dock"))?;
    let skipped = model.node(dock).and_then(|r| r.marks[tcm_view::M_SKIPPED]);
    let skipped = skipped.ok_or_else(|| anyhow::anyhow!("dock was not skipped"))?;
    let viewer = Viewer::serve(([127, 0, 0, 1], 0).into())?;
    viewer.add(model);
    let url = viewer.url();
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?
        .block_on(async {
            let mut b = Browser::start(
                &test_support::ensure_tool("chromium", "chromium")
                    .map_err(|e| anyhow::anyhow!(e))?,
                1200,
                700,
            )
            .await?;
            b.goto(&url).await?;
            let row = |n: u64| format!("document.querySelector('#tree .row[data-n=\"{n}\"]')");
            let look = |n: u64| {
                format!(
                    "(() => {{ const r = {}; return r && [r.classList.contains('skipped'), \
                     r.querySelector('.sq').className, (r.querySelector('.tag') || {{}}).textContent || ''] }})()",
                    row(n)
                )
            };
            b.wait_for(&format!("S.finished && {}", row(dock)), Duration::from_secs(20))
                .await?;
            let undock = dock + 1;
            // Drawn once the page has redrawn after the last record.
            let dock_look = format!(
                "JSON.stringify({}) === JSON.stringify([true, 'sq s-skipped', 'skipped'])",
                look(dock)
            );
            if b.wait_for(&dock_look, Duration::from_secs(15)).await.is_err() {
                anyhow::bail!("dock: {}", b.eval(&look(dock)).await?);
            }
            ensure!(
                b.eval(&look(undock)).await? == serde_json::json!([false, "sq s-completed", ""]),
                "undock: {}",
                b.eval(&look(undock)).await?
            );
            b.screenshot(&shots().join("skipped.png")).await?;
            // Before its skip, it is not.
            b.eval(&set_cursor(skipped.seq - 1)).await?;
            b.wait_for(
                &format!("{0} && !{0}.classList.contains('skipped')", row(dock)),
                Duration::from_secs(15),
            )
            .await?;
            // Its history says so.
            b.eval(&set_cursor(1_000_000)).await?;
            // The row as drawn at that cursor (a pooled row keeps the number it last showed).
            let dock_row = format!("#tree .row:not([hidden])[data-n=\"{dock}\"] .name");
            b.wait_for(
                &format!("document.querySelector('{dock_row}') !== null"),
                Duration::from_secs(15),
            )
            .await?;
            js_click(&mut b, &dock_row).await?;
            b.wait_for(
                "[...document.querySelectorAll('#tab-node td')].some((d) => d.textContent.startsWith('skipped'))",
                Duration::from_secs(15),
            )
            .await?;
            anyhow::Ok(())
        })?;
    viewer.stop();
    Ok(())
}

/// The text of `battery_ok`'s label under the timeline: its value at the cursor and since when.
const BATTERY: &str = "(() => { const d = document.querySelector('#statelabels [data-var=\"battery_ok\"]'); \
    return d && [d.querySelector('.val').textContent, (d.querySelector('.since') || {}).textContent || '']; })()";

#[test]
fn state_variables_show_their_value_at_the_cursor_and_a_wait_names_them() -> anyhow::Result<()> {
    let _one = one_browser_at_a_time();
    let trace = paused(common::powered())?;
    let mut model = RunModel::new("powered.jsonl");
    for ev in &trace {
        model.apply(ev).map_err(anyhow::Error::msg)?;
    }
    model.finished = true;
    let at = |s: u64| model.seq_at(s * 1_000_000_000);
    let (three, four, six) = (at(3), at(4), at(6));
    let drive = model
        .rows()
        .iter()
        .find(|r| r.name == "drive")
        .map(|r| r.number)
        .ok_or_else(|| anyhow::anyhow!("no drive"))?;
    let records = trace.len();
    let viewer = Viewer::serve(([127, 0, 0, 1], 0).into())?;
    viewer.add(model);
    let url = viewer.url();
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?
        .block_on(async {
            let mut b = open_page(&url, records).await?;
            // A lane per variable, in the order declared.
            let names = b
                .wait_for(
                    "(() => { const l = [...document.querySelectorAll('#statelabels .lane')]; \
                     return l.length === 5 && !document.getElementById('states').hidden \
                     && l.map((d) => d.dataset.var); })()",
                    Duration::from_secs(15),
                )
                .await?;
            ensure!(
                names == serde_json::json!(["battery_ok", "fault", "charge", "position", "docked"]),
                "lanes: {names}"
            );
            // At 3 s, false since 2 s; at 6 s, true since 5 s; `position` unknown.
            b.eval(&set_cursor(three)).await?;
            let value = b
                .wait_for(
                    &format!("(() => {{ const v = {BATTERY}; return v && v[0] === 'false' && v; }})()"),
                    Duration::from_secs(15),
                )
                .await?;
            ensure!(value == serde_json::json!(["false", "since 2.000 s"]), "at 3 s: {value}");
            b.screenshot(&shots().join("state-lanes.png")).await?;
            b.eval(&set_cursor(six)).await?;
            let value = b
                .wait_for(
                    &format!("(() => {{ const v = {BATTERY}; return v && v[0] === 'true' && v; }})()"),
                    Duration::from_secs(15),
                )
                .await?;
            ensure!(value == serde_json::json!(["true", "since 5.000 s"]), "at 6 s: {value}");
            let position = b
                .eval("document.querySelector('#statelabels [data-var=\"position\"] .val').textContent")
                .await?;
            ensure!(position == "unknown", "position: {position}");

            // `drive` at 4 s waits for its condition, held by `battery_ok`.
            b.eval(&set_cursor(four)).await?;
            b.eval(&format!("select({drive}, true)")).await?;
            let waits = b
                .wait_for(
                    "(() => { const w = document.getElementById('waits'); \
                     return w && w.textContent.includes('waits for') && w.textContent; })()",
                    Duration::from_secs(15),
                )
                .await?;
            let waits = waits.as_str().unwrap_or_default();
            ensure!(
                waits.contains(
                    "handling: waits for `battery_ok && !fault` (false): battery_ok = false \
                     since 2.000 s, fault = false since 0.000 s"
                ),
                "drive's waits: {waits}"
            );
            let conds = b.eval("document.getElementById('conds').textContent").await?;
            ensure!(
                conds.as_str().unwrap_or_default().contains("invariant charge > 10.0 is true"),
                "drive's conditions: {conds}"
            );
            b.screenshot(&shots().join("state-waiting.png")).await?;

            // Counts & durations: `dock` skipped, not ok.
            b.click("#tabs [data-tab=stats]").await?;
            let dock = b
                .wait_for(
                    "(() => { const r = [...document.querySelectorAll('#tab-stats tr')].find((r) => r.cells[0].textContent === 'dock'); \
                     return r && [...r.cells].slice(3, 5).map((c) => c.textContent); })()",
                    Duration::from_secs(15),
                )
                .await?;
            ensure!(dock == serde_json::json!(["0", "1"]), "dock's ok and skipped: {dock}");
            anyhow::Ok(())
        })?;
    viewer.stop();
    Ok(())
}

#[test]
fn a_live_page_builds_the_state_lanes_a_page_reads_from_the_snapshot() -> anyhow::Result<()> {
    let _one = one_browser_at_a_time();
    let chromium =
        test_support::ensure_tool("chromium", "chromium").map_err(|e| anyhow::anyhow!(e))?;
    let trace = paused(common::powered())?;
    let viewer = Viewer::serve(([127, 0, 0, 1], 0).into())?;
    let mut sink = viewer.live("powered");
    let url = viewer.url();
    let done = format!("S.finished && S.records === {}", trace.len());
    let states = "JSON.stringify(S.states)";
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?
        .block_on(async {
            let mut b = Browser::start(&chromium, 1200, 700).await?;
            feed_live(&mut b, &url, &mut sink, &trace, &done).await?;
            let live = b.eval(states).await?;
            b.eval("open(0)").await?;
            b.wait_for(&done, Duration::from_secs(20)).await?;
            let fresh = b.eval(states).await?;
            let text = live.as_str().unwrap_or_default();
            ensure!(
                text.contains(r#"{"name":"charge","ty":"float","ch":["#),
                "the live page lacks the lanes: {text}"
            );
            ensure!(
                live == fresh,
                "the live page's lanes differ from the snapshot's:\nlive:  {live}\nfresh: {fresh}"
            );
            anyhow::Ok(())
        })?;
    viewer.stop();
    Ok(())
}
