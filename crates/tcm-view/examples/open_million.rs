//! Benchmark: how long a trace of a million records takes to open in the viewer, from reading the
//! file to the tree shown in a headless browser (Debian's chromium, installed when missing and
//! run as root). `cargo run --release -p tcm-view --example open_million [RECORDS]`.
//!
//! The trace is a real run on virtual time (a mission of legs, each a sequence of steps), written
//! as `--trace` writes it. Printed: the file's size, the time to read it into the viewer's model
//! (what `tdl view` does before it serves), the page's time from navigation to the tree's rows
//! shown (fetching and applying the snapshot included), and their sum.

use std::time::{Duration, Instant};

use anyhow::Context as _;
use tcm::{Facet, JsonLines, NodeRef, Runtime, Task};
use test_support::browser::Browser;

fn mission(legs: usize, steps: usize) -> Task {
    Task::goal("mission", move |ctx| async move {
        for _ in 0..legs {
            ctx.spawn(Task::goal("leg", move |ctx| async move {
                for i in 0..steps {
                    let step = Task::command("step", |_| async {
                        tokio::time::sleep(Duration::from_millis(3)).await;
                        Ok(())
                    });
                    let s = ctx.spawn(step);
                    if i > 0 {
                        s.sequential(Facet::Execution, NodeRef::Previous).start()?;
                    } else {
                        s.start()?;
                    }
                }
                Ok(())
            }))
            .start()?;
        }
        Ok(())
    })
}

fn main() -> anyhow::Result<()> {
    let want: u64 = std::env::args()
        .nth(1)
        .map(|a| a.parse())
        .transpose()
        .context("RECORDS is a number")?
        .unwrap_or(1_000_000);
    // About 9 records per step; a few more legs than that makes for at least `want`.
    let steps = 300usize;
    let legs = (want as usize).div_ceil(8 * steps).max(1);
    let path = std::env::temp_dir().join(format!("open-million-{}.jsonl", std::process::id()));
    let file = std::fs::File::create(&path)?;
    let t0 = Instant::now();
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .start_paused(true)
        .build()?
        .block_on(async {
            Runtime::new()
                .with_sink(JsonLines(std::io::BufWriter::new(file)))
                .run(mission(legs, steps))
                .await
        })?;
    let made = t0.elapsed();
    let size = std::fs::metadata(&path)?.len();

    let t1 = Instant::now();
    let text = std::fs::File::open(&path)?;
    let name = path.display().to_string();
    let model = tcm_view::RunModel::read(name.clone(), &name, std::io::BufReader::new(text));
    let read = t1.elapsed();
    anyhow::ensure!(model.problem.is_none(), "{:?}", model.problem);
    let records = model.len();
    let nodes = model.rows().len();

    let viewer = tcm_view::Viewer::serve(([127, 0, 0, 1], 0).into())?;
    viewer.add(model);
    let chromium =
        test_support::ensure_tool("chromium", "chromium").map_err(|e| anyhow::anyhow!(e))?;
    let page = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?
        .block_on(async {
            let mut b = Browser::start(&chromium, 1400, 850).await?;
            b.goto(&viewer.url()).await?;
            let shown = b
                .wait_for("window.treeShownAt", Duration::from_secs(120))
                .await?;
            let rows = b
                .eval("document.querySelectorAll('#tree .row:not([hidden])').length")
                .await?;
            anyhow::ensure!(rows.as_u64().unwrap_or(0) > 10, "rows shown: {rows}");
            anyhow::Ok(Duration::from_secs_f64(
                shown.as_f64().unwrap_or(0.0) / 1000.0,
            ))
        })?;
    let _ = std::fs::remove_file(&path);
    println!(
        "trace: {records} records, {nodes} nodes, {:.1} MB (made in {:.2} s)",
        size as f64 / 1e6,
        made.as_secs_f64()
    );
    println!("read into the model: {:.2} s", read.as_secs_f64());
    println!(
        "page, navigation to tree shown: {:.2} s",
        page.as_secs_f64()
    );
    println!(
        "open to tree shown: {:.2} s (target: at most 3 s)",
        (read + page).as_secs_f64()
    );
    Ok(())
}
