//! Versions of a program loaded at run time (docs/distributed.md, "A serving executive"): its
//! content hash, the version its nodes name in their `spawned` records, and a newer version that
//! supersedes it while it runs, whose definitions new spawns use from then on.

use std::sync::{Arc, PoisonError};

use crate::ir::{TaskDef, TaskIdx};
use crate::program::{Program, Shared};

impl Shared {
    /// The newest version's definition of the task `name`, when a newer version superseded this
    /// one and has it (with the same kind and parameters, as `Program::supersede` checked).
    pub(crate) fn newest(&self, name: &str) -> Option<(Arc<Shared>, TaskIdx)> {
        if !self.superseded.load(std::sync::atomic::Ordering::Acquire) {
            return None;
        }
        let next = self
            .successor
            .read()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()?;
        next.shared
            .newest(name)
            .or_else(|| Some((next.shared.clone(), *next.shared.by_name.get(name)?)))
    }
}

impl Program {
    /// The content hash of the program's sources: the first 12 hex digits of the SHA-256 of the
    /// files' texts, in order. Two loads of the same text have the same hash.
    pub fn hash(&self) -> &str {
        &self.shared.hash
    }

    /// The program whose tasks name `version` in their nodes' `spawned` records (a serving
    /// executive gives `name@hash`), so a trace tells which version each node ran. Set once: a
    /// program already stamped keeps its first version.
    pub fn stamped(self, version: &str) -> Program {
        let _ = self.shared.version.set(Arc::from(version));
        self
    }

    /// The version set by [`Program::stamped`], if any.
    pub fn version(&self) -> Option<&str> {
        self.shared.version.get().map(|v| &**v)
    }

    /// What keeps `newer` from replacing this program's definitions in runs under way: a task
    /// of this program that `newer` has with another kind or other parameter types (the bodies
    /// already running would spawn it with arguments it does not take). Empty: it can.
    pub fn incompatible(&self, newer: &Program) -> Vec<String> {
        let mut out = Vec::new();
        for def in &self.shared.tasks {
            let Some(&j) = newer.shared.by_name.get(def.name) else {
                continue;
            };
            let new = &newer.shared.tasks[j];
            if new.kind != def.kind {
                out.push(format!("`{}` changes kind", def.name));
                continue;
            }
            let types = |d: &TaskDef| {
                d.params
                    .iter()
                    .map(|(_, t)| t.describe())
                    .collect::<Vec<_>>()
            };
            if types(def) != types(new) {
                out.push(format!(
                    "`{}` changes parameters: ({}) becomes ({})",
                    def.name,
                    types(def).join(", "),
                    types(new).join(", ")
                ));
            }
        }
        out
    }

    /// Makes `newer` replace this program's definitions from now on: every task this program
    /// builds afterwards (a body's spawn, a retry's fresh run excepted, which re-runs its node)
    /// is built from the newest version that has a task of that name; tasks it no longer has
    /// keep this version's. Refused, with what stands in the way, when they are incompatible
    /// ([`Program::incompatible`]).
    pub fn supersede(&self, newer: &Program) -> Result<(), Vec<String>> {
        let problems = self.incompatible(newer);
        if !problems.is_empty() {
            return Err(problems);
        }
        *self
            .shared
            .successor
            .write()
            .unwrap_or_else(PoisonError::into_inner) = Some(newer.clone());
        self.shared
            .superseded
            .store(true, std::sync::atomic::Ordering::Release);
        Ok(())
    }
}
