//! The page in a real headless browser (Debian's `chromium`, installed by the test setup when
//! missing): a page opened before a live run's first record builds its rows from the live
//! messages alone, and they are the rows the page reads from the snapshot when it opens the run
//! again after its end; both look the same. Screenshots go to `target/viewer/`.

mod common;

use std::path::PathBuf;
use std::time::Duration;

use anyhow::ensure;
use tcm::TraceSink;
use tcm_trace::TraceEvent;
use test_support::browser::Browser;

async fn mission() -> Vec<TraceEvent> {
    common::mission(true).await
}

/// Every node the page holds: number, parent, kind, name, marks, agent, children.
const NODES: &str =
    "JSON.stringify(S.nodes.map((n) => n && [n.n, n.p, n.k, n.name, n.m, n.agent, n.kids]))";

#[test]
fn a_live_page_builds_the_rows_a_page_reads_from_the_snapshot() -> anyhow::Result<()> {
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
            b.goto(&url).await?;
            // The page has the (empty) snapshot, so it is subscribed: every record comes live.
            // An evaluation that the navigation cut short is asked again.
            let subscribed =
                "S.runId === 0 && document.getElementById('status').textContent.startsWith('live')";
            let mut tries = 0;
            while let Err(e) = b.wait_for(subscribed, Duration::from_secs(20)).await {
                tries += 1;
                ensure!(tries < 3, "the page did not open the run: {e}");
            }
            for ev in &trace {
                sink.record(ev);
            }
            sink.flush();
            b.wait_for(&done, Duration::from_secs(20)).await?;
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
