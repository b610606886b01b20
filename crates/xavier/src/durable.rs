//! `xavier --journal` and `--resume` (docs/semantics.md, "Durable runs"): the run's journal
//! created, or read and reopened to go on, for `xavier::run_journaled`. A journal names the
//! mission's program and the seed, scenario and rooms it was started with; a resumption with
//! others is refused.

use anyhow::{Context as _, bail};
use std::path::PathBuf;
use tcm_journal::{Durability, Header, Writer};
use xavier::{Journaling, Setup};

/// The program a journal of this mission names: its version.
const PROGRAM: &str = concat!("xavier-mission@", env!("CARGO_PKG_VERSION"));

/// Whether the tree runs on one thread (a journaled run).
pub(crate) fn one_thread(journal: &Option<PathBuf>, resume: &Option<PathBuf>) -> bool {
    journal.is_some() || resume.is_some()
}

/// `--journal-sync` read.
fn durability(text: &str) -> anyhow::Result<Durability> {
    text.parse().map_err(anyhow::Error::msg)
}

/// What a run started with, as its journal's header says it.
fn started(setup: &Setup) -> serde_json::Value {
    serde_json::json!({
        "seed": setup.seed,
        "scenario": setup.scenario.to_string(),
        "rooms": setup.rooms,
    })
}

/// The journal a run writes (`journal`) or resumes (`resume`), if either is given.
pub(crate) fn journaling(
    journal: &Option<PathBuf>,
    resume: &Option<PathBuf>,
    sync: &str,
    setup: &Setup,
) -> anyhow::Result<Option<Journaling>> {
    let sync = durability(sync)?;
    if let Some(path) = resume {
        let journal = tcm_journal::read(path, Some(PROGRAM))
            .with_context(|| format!("cannot resume from {}", path.display()))?;
        if let Some(w) = &journal.warning {
            eprintln!("xavier: {w}");
        }
        let want = started(setup);
        if journal.header.start.as_ref() != Some(&want) {
            bail!(
                "{} recorded a run started with {}, not {want}: give the seed, scenario and rooms \
                 it was started with",
                path.display(),
                journal
                    .header
                    .start
                    .as_ref()
                    .map_or("nothing".to_string(), |s| s.to_string())
            );
        }
        let writer = Writer::reopen(path, &journal, sync)
            .with_context(|| format!("cannot go on writing {}", path.display()))?;
        println!(
            "xavier: resuming from {} ({} inputs)",
            path.display(),
            journal.entries.len()
        );
        return Ok(Some(Journaling::resume(writer, journal)));
    }
    let Some(path) = journal else {
        return Ok(None);
    };
    let header = Header::new(PROGRAM).starting(started(setup));
    let writer = Writer::create_with(path, header, sync)
        .with_context(|| format!("cannot create the journal {}", path.display()))?;
    Ok(Some(Journaling::new(writer)))
}
