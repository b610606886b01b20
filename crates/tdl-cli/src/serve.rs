//! `tdl view TRACE.jsonl...`: serves the viewer (crate `tcm-view`) on the trace files, one run per
//! file, until interrupted. A file that cannot be read to its end is still shown up to the bad
//! line, and the problem is printed here and on the page. With `--at SEQ`, the address printed
//! opens the first file with the time cursor on its record SEQ (`tcm_view::Viewer::url_at`); a
//! SEQ past the file's records is refused before anything is served.

use std::net::SocketAddr;
use std::path::PathBuf;

use anyhow::Context as _;

pub(crate) fn view(
    files: &[PathBuf],
    listen: Option<SocketAddr>,
    at: Option<u64>,
) -> anyhow::Result<bool> {
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
    if let (Some(seq), Some(first), Some(model)) = (at, files.first(), models.first()) {
        check_at(seq, &first.display().to_string(), model.len())?;
    }
    let clean = models.iter().all(|m| m.problem.is_none());
    if let Some(warning) = listen.as_ref().and_then(tcm_view::exposure_warning) {
        eprintln!("tdl view: {warning}");
    }
    let viewer = tcm_view::Viewer::start(listen)?;
    let mut first_run = None;
    for model in models {
        let run = viewer.add(model);
        first_run.get_or_insert(run);
    }
    let url = match (at, first_run) {
        (Some(seq), Some(run)) => viewer.url_at(run, seq),
        _ => viewer.url(),
    };
    println!("tdl view: {url} (Ctrl-C to stop)");
    viewer.wait();
    Ok(clean)
}

/// Refuses `--at SEQ` past the records of `file` (`records` of them, numbered from 0).
fn check_at(seq: u64, file: &str, records: u64) -> anyhow::Result<()> {
    match records {
        _ if seq < records => Ok(()),
        0 => anyhow::bail!("--at {seq}: {file} has no record"),
        1 => anyhow::bail!("--at {seq}: {file} has 1 record (record 0)"),
        n => anyhow::bail!(
            "--at {seq}: {file} has {n} records (records 0 to {})",
            n - 1
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::check_at;

    #[test]
    fn a_record_past_the_end_is_refused_with_the_files_count() {
        assert!(check_at(0, "a.jsonl", 1).is_ok());
        assert!(check_at(411, "a.jsonl", 412).is_ok());
        let said = |seq, n| check_at(seq, "a.jsonl", n).map_err(|e| e.to_string());
        assert_eq!(
            said(412, 412),
            Err("--at 412: a.jsonl has 412 records (records 0 to 411)".into())
        );
        assert_eq!(
            said(3, 1),
            Err("--at 3: a.jsonl has 1 record (record 0)".into())
        );
        assert_eq!(said(0, 0), Err("--at 0: a.jsonl has no record".into()));
    }
}
