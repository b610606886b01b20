//! Faults from a file (`--faults faults.json`; docs/semantics.md, "Steering a run", rule 4): a
//! JSON list of rules, each standing for the next ends of the nodes it matches, as
//! [`Runtime::inject`](crate::Runtime::inject) and [`Control::inject`](crate::Control::inject)
//! take them.
//!
//! ```json
//! [
//!   {"task": "follow_path", "times": 4, "exception": "Recoverable",
//!    "ancestry": ["NavFailure"], "message": "injected: no progress"},
//!   {"path": "**/spin", "never": true}
//! ]
//! ```
//!
//! Each rule names its nodes by `task` (a task name) or `path` (a path pattern), and says how many
//! of their starts it takes (`times`, 1 by default) and what stands for their ends: `exception`
//! (with an optional `message`, the exception's `ancestry`, nearest first, for handlers of its
//! ancestors, and `data`, the JSON it carries, which an interpreted handler reads as the
//! exception's fields), `value` (any JSON: the node succeeds with it, a `serde_json::Value`, which an
//! interpreted program and a task from an agent read as their own values; see [`json_value`]) or
//! `"never": true`.

use serde::Deserialize;
use std::path::Path;
use tcm_core::{Failure, Fault, FaultOutcome, Matcher};

/// Why a faults file cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum FaultsError {
    /// It cannot be read.
    #[error("{file}: cannot read it: {source}")]
    Read {
        /// The file.
        file: String,
        /// Why.
        source: std::io::Error,
    },
    /// It is not a JSON list of rules.
    #[error("{file}:{line}:{column}: {message}")]
    Json {
        /// The file.
        file: String,
        /// Where, from 1.
        line: usize,
        /// Where, from 1.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// A rule is not complete, or says two things at once.
    #[error("{file}: rule {rule} (counting from 1): {message}")]
    Rule {
        /// The file.
        file: String,
        /// Which rule, from 1.
        rule: usize,
        /// What is wrong, and what to write instead.
        message: String,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Rule {
    task: Option<String>,
    path: Option<String>,
    times: Option<u32>,
    exception: Option<String>,
    message: Option<String>,
    #[serde(default)]
    ancestry: Vec<String>,
    #[serde(default)]
    never: bool,
    // With `exception`: what the exception carries, for handlers that read it.
    data: Option<serde_json::Value>,
    // Present (even `null`): the node succeeds with this value.
    #[serde(default, deserialize_with = "present")]
    value: Option<serde_json::Value>,
}

/// A field given, whatever its value (`null` too), as `Some`.
fn present<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<serde_json::Value>, D::Error> {
    serde_json::Value::deserialize(d).map(Some)
}

/// Reads the faults of the file at `path`.
pub fn read_faults(path: &Path) -> Result<Vec<Fault>, FaultsError> {
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|source| FaultsError::Read {
        file: file.clone(),
        source,
    })?;
    parse_faults(&file, &text)
}

/// The faults of `text`, a faults file's content; `file` names it in errors.
pub fn parse_faults(file: &str, text: &str) -> Result<Vec<Fault>, FaultsError> {
    let rules: Vec<Rule> = serde_json::from_str(text).map_err(|e| FaultsError::Json {
        file: file.to_string(),
        line: e.line(),
        column: e.column(),
        message: e
            .to_string()
            .split(" at line ")
            .next()
            .unwrap_or("")
            .to_string(),
    })?;
    rules
        .into_iter()
        .enumerate()
        .map(|(i, r)| {
            rule(r).map_err(|message| FaultsError::Rule {
                file: file.to_string(),
                rule: i + 1,
                message,
            })
        })
        .collect()
}

fn rule(r: Rule) -> Result<Fault, String> {
    let on = match (r.task, r.path) {
        (Some(t), None) => Matcher::Task(t.into()),
        (None, Some(p)) => Matcher::Path(p),
        (Some(_), Some(_)) => return Err("give `task` or `path`, not both".into()),
        (None, None) => {
            return Err("say which nodes: `\"task\": NAME` or `\"path\": PATTERN`".into());
        }
    };
    let times = r.times.unwrap_or(1);
    if times == 0 {
        return Err("`times` is 0: the rule would do nothing; leave it out for 1".into());
    }
    let outcome = match (r.exception, r.never) {
        (None, false) if r.value.is_some() => {
            if r.message.is_some() || !r.ancestry.is_empty() {
                return Err(
                    "a node that succeeds raises nothing: leave out `message` and `ancestry`"
                        .into(),
                );
            }
            let value = r.value.unwrap_or_default();
            FaultOutcome::Succeed(Some(json_value(value)))
        }
        (_, _) if r.value.is_some() => {
            return Err("give one of `exception`, `value` and `\"never\": true`".into());
        }
        (Some(e), false) => {
            let mut f = Failure::new(e, r.message.unwrap_or_else(|| "injected".into()));
            f.ancestry = r.ancestry.into_iter().map(Into::into).collect();
            if let Some(data) = r.data {
                f.data = Some(std::sync::Arc::new(data));
            }
            FaultOutcome::Fail(f)
        }
        (None, _) if r.data.is_some() => {
            return Err("`data` goes with an `exception`, which carries it".into());
        }
        (None, true) if r.message.is_none() && r.ancestry.is_empty() => FaultOutcome::Never,
        (None, true) => {
            return Err(
                "a node that never ends raises nothing: leave out `message` and `ancestry`".into(),
            );
        }
        (Some(_), true) => return Err("give `exception` or `\"never\": true`, not both".into()),
        (None, false) => {
            return Err(
                "say what stands for the end: `\"exception\": NAME`, `\"value\": JSON` or `\"never\": true`"
                    .into(),
            );
        }
    };
    Ok(Fault { on, times, outcome })
}

/// A JSON value standing for an action's: the node's value is a `serde_json::Value`, which an
/// interpreted program, and a task from an agent, read as their own values.
pub fn json_value(value: serde_json::Value) -> tcm_core::FaultValue {
    let text = value.to_string();
    tcm_core::FaultValue::new(text, move || Box::new(value.clone()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rules_read_into_faults() {
        let faults = parse_faults(
            "f.json",
            r#"[{"task":"follow_path","times":4,"exception":"Recoverable","ancestry":["NavFailure"]},
                {"path":"**/spin","never":true}]"#,
        )
        .expect("valid");
        assert_eq!(faults.len(), 2);
        assert_eq!(faults[0].on, Matcher::Task("follow_path".into()));
        assert_eq!(faults[0].times, 4);
        match &faults[0].outcome {
            FaultOutcome::Fail(f) => {
                assert_eq!(f.exception, "Recoverable");
                assert_eq!(f.message, "injected");
                assert!(f.is_a("NavFailure"));
            }
            other => panic!("a failure: {other:?}"),
        }
        assert_eq!(faults[1].outcome, FaultOutcome::Never);
        assert_eq!(faults[1].times, 1);
        let faults = parse_faults(
            "f.json",
            r#"[{"task":"measure","value":{"range":2.5}},{"task":"ping","value":null}]"#,
        )
        .expect("valid");
        for (fault, json) in faults.iter().zip([r#"{"range":2.5}"#, "null"]) {
            let FaultOutcome::Succeed(Some(v)) = &fault.outcome else {
                panic!("a value: {fault:?}");
            };
            assert_eq!(v.text(), json);
            let made = v.make().downcast::<serde_json::Value>().expect("JSON");
            assert_eq!(made.to_string(), json);
        }
    }

    #[test]
    fn bad_files_say_where_and_what_to_write() {
        let err = |text: &str| parse_faults("f.json", text).err().map(|e| e.to_string());
        assert_eq!(
            err("[{\"task\":\"a\",\n \"exeption\":\"X\"}]").as_deref(),
            Some(
                "f.json:2:11: unknown field `exeption`, expected one of `task`, `path`, `times`, `exception`, `message`, `ancestry`, `never`, `data`, `value`"
            )
        );
        assert_eq!(
            err(r#"[{"task":"a","exception":"X"},{"exception":"X"}]"#).as_deref(),
            Some(
                "f.json: rule 2 (counting from 1): say which nodes: `\"task\": NAME` or `\"path\": PATTERN`"
            )
        );
        assert_eq!(
            err(r#"[{"task":"a"}]"#).as_deref(),
            Some(
                "f.json: rule 1 (counting from 1): say what stands for the end: `\"exception\": NAME`, `\"value\": JSON` or `\"never\": true`"
            )
        );
        assert!(
            err(r#"[{"task":"a","exception":"X","never":true}]"#)
                .is_some_and(|e| e.contains("not both"))
        );
        assert!(
            err(r#"[{"task":"a","exception":"X","times":0}]"#).is_some_and(|e| e.contains("is 0"))
        );
        assert!(
            read_faults(Path::new("/nonexistent/faults.json"))
                .err()
                .is_some_and(|e| e
                    .to_string()
                    .starts_with("/nonexistent/faults.json: cannot read it"))
        );
    }
}
