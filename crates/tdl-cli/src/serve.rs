//! `tdl view TRACE.jsonl...`: serves the viewer (crate `tcm-view`) on the trace files, one run per
//! file, until interrupted. A file that cannot be read to its end is still shown up to the bad
//! line, and the problem is printed here and on the page.

use std::net::SocketAddr;
use std::path::PathBuf;

use anyhow::Context as _;

pub(crate) fn view(files: &[PathBuf], listen: Option<SocketAddr>) -> anyhow::Result<bool> {
    let mut models = Vec::new();
    for file in files {
        let f =
            std::fs::File::open(file).with_context(|| format!("cannot read {}", file.display()))?;
        let name = file.display().to_string();
        let model = tcm_view::RunModel::read(name.clone(), &name, std::io::BufReader::new(f));
        if let Some(problem) = &model.problem {
            eprintln!("tdl view: {problem}");
        }
        models.push(model);
    }
    let clean = models.iter().all(|m| m.problem.is_none());
    if let Some(warning) = listen.as_ref().and_then(tcm_view::exposure_warning) {
        eprintln!("tdl view: {warning}");
    }
    let viewer = tcm_view::Viewer::start(listen)?;
    for model in models {
        viewer.add(model);
    }
    println!("tdl view: {} (Ctrl-C to stop)", viewer.url());
    viewer.wait();
    Ok(clean)
}
