//! `tdl trace export --mcap`: a trace as an MCAP file, for robotics log tools (Foxglove and the
//! like) to show beside the robot's own recordings.
//!
//! One channel per kind of record, topic `/tdl/trace/<ev>` (`/tdl/trace/spawned`, …), created
//! when the first record of that kind comes; message encoding `json`, each message one record
//! exactly as the JSON-lines trace writes it (docs/trace-format.md; a trace of an older format
//! version is written in the current shape); schema `tdl.trace.<ev>`, encoding `jsonschema`, a JSON
//! Schema of that kind of record. Log and publish time are the record's `t` (nanoseconds of virtual
//! time since the run started), the sequence number its `seq`.
//!
//! The file is written next to its destination under a temporary name and renamed when complete,
//! so a failed export leaves nothing behind.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use anyhow::Context as _;
use serde_json::{Value, json};
use tcm_trace::TraceEvent;

/// What an export wrote.
pub(crate) struct Written {
    /// Messages, one per record.
    pub(crate) messages: usize,
    /// Channels, one per kind of record present.
    pub(crate) channels: usize,
}

/// Writes `trace` to `out` as MCAP.
pub(crate) fn mcap(trace: &[TraceEvent], out: &Path) -> anyhow::Result<Written> {
    let tmp = temporary(out);
    let file = File::create(&tmp).with_context(|| format!("cannot create {}", tmp.display()))?;
    let written = write(trace, file)
        .with_context(|| format!("cannot write {}", out.display()))
        .and_then(|written| {
            std::fs::rename(&tmp, out)
                .with_context(|| format!("cannot rename {} to {}", tmp.display(), out.display()))?;
            Ok(written)
        });
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written
}

/// `.<name>.tmp-<pid>` in the destination's directory (a rename stays on one file system).
fn temporary(out: &Path) -> PathBuf {
    let name = out
        .file_name()
        .map_or_else(|| "trace.mcap".into(), |n| n.to_string_lossy().into_owned());
    out.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}

fn write(trace: &[TraceEvent], file: File) -> anyhow::Result<Written> {
    let mut writer = mcap::Writer::new(BufWriter::new(file))?;
    let mut channels: BTreeMap<String, u16> = BTreeMap::new();
    for ev in trace {
        let line = tcm_trace::to_line(ev);
        let kind = serde_json::from_str::<Value>(&line)
            .ok()
            .and_then(|v| v.get("ev").and_then(Value::as_str).map(str::to_string))
            .with_context(|| format!("record {}: no `ev` field in {line}", ev.seq))?;
        let channel_id = match channels.get(&kind) {
            Some(&id) => id,
            None => {
                let schema = schema(&kind).with_context(|| {
                    format!("record {}: no schema for `{kind}` records", ev.seq)
                })?;
                let schema_id = writer.add_schema(
                    &format!("tdl.trace.{kind}"),
                    "jsonschema",
                    &serde_json::to_vec(&schema)?,
                )?;
                let id = writer.add_channel(
                    schema_id,
                    &format!("/tdl/trace/{kind}"),
                    "json",
                    &BTreeMap::new(),
                )?;
                channels.insert(kind, id);
                id
            }
        };
        let sequence = u32::try_from(ev.seq)
            .with_context(|| format!("record {}: MCAP sequence numbers have 32 bits", ev.seq))?;
        writer.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id,
                sequence,
                log_time: ev.t,
                publish_time: ev.t,
            },
            line.as_bytes(),
        )?;
    }
    writer.finish()?;
    let file = writer
        .into_inner()
        .into_inner()
        .map_err(|err| err.into_error())?;
    file.sync_all()?;
    Ok(Written {
        messages: trace.len(),
        channels: channels.len(),
    })
}

/// The JSON Schema (draft 2020-12) of the records of kind `ev`, after docs/trace-format.md.
pub(crate) fn schema(ev: &str) -> Option<Value> {
    let count = || json!({"type": "integer", "minimum": 0});
    let u32_ = || json!({"type": "integer", "minimum": 0, "maximum": u32::MAX});
    let node = || json!({"type": "integer", "minimum": 0, "description": "display number of a node ({id} in TCM's log)"});
    let maybe_node = || json!({"type": ["integer", "null"], "minimum": 0});
    let string = || json!({"type": "string"});
    let resource_uses = || {
        json!({"type": "array", "items": {
            "type": "object",
            "properties": {"resource": {"type": "string"}, "amount": {"type": "integer", "minimum": 1, "maximum": u32::MAX}},
            "required": ["resource", "amount"],
            "additionalProperties": false,
        }})
    };
    let mut uses_defs = false;
    let (description, fields): (&str, Vec<(&str, Value)>) = match ev {
        "run_started" => (
            "The run began; always the first record.",
            vec![("version", u32_()), ("run", u32_())],
        ),
        "reserved" => (
            "A display number was allocated for a node the body will spawn later.",
            vec![("node", node()), ("parent", node()), ("name", string())],
        ),
        "spawned" => (
            "A node was inserted into the tree, every facet disabled (a command-like node's expansion completed).",
            vec![
                ("node", node()),
                ("parent", node()),
                (
                    "kind",
                    json!({"enum": ["goal", "command", "monitor", "handler"]}),
                ),
                ("name", string()),
            ],
        ),
        "constrained" => {
            uses_defs = true;
            (
                "A constraint was applied to the node.",
                vec![
                    ("node", node()),
                    ("constraint", json!({"$ref": "#/$defs/constraint"})),
                ],
            )
        }
        "constraint_void" => (
            "A constraint on the node was dropped; reason says why.",
            vec![("node", node()), ("reason", string())],
        ),
        "transition" => {
            uses_defs = true;
            (
                "A facet of the node moved from one state to a later one.",
                vec![
                    ("node", node()),
                    ("facet", json!({"$ref": "#/$defs/facet"})),
                    ("from", json!({"$ref": "#/$defs/state"})),
                    ("to", json!({"$ref": "#/$defs/state"})),
                ],
            )
        }
        "terminating" => ("The node was asked to terminate.", vec![("node", node())]),
        "terminated" => (
            "The node and its subtree are terminated.",
            vec![("node", node())],
        ),
        "suspended" => ("The node was suspended.", vec![("node", node())]),
        "unsuspended" => ("The node was resumed.", vec![("node", node())]),
        "failed" => (
            "The node's action failed with an exception of type `exception`.",
            vec![
                ("node", node()),
                ("exception", string()),
                ("message", string()),
            ],
        ),
        "dead" => (
            "A reserved node will never be spawned.",
            vec![("node", node())],
        ),
        "external" => (
            "A named external event was raised.",
            vec![("name", string())],
        ),
        "reclaimed" => (
            "A completed or terminated node was freed; no later record names it.",
            vec![("node", node())],
        ),
        "placed" => (
            "The node's action runs on another process of a distributed system, the agent named.",
            vec![("node", node()), ("agent", string())],
        ),
        "warning" => (
            "Something worth a person's attention; the run goes on.",
            vec![("node", maybe_node()), ("message", string())],
        ),
        "monitor_params" => (
            "A monitor's parameters, after its spawn and whenever they change; null is unlimited (period: not polling).",
            vec![
                ("node", node()),
                (
                    "max_activations",
                    json!({"type": ["integer", "null"], "minimum": 0, "maximum": u32::MAX}),
                ),
                (
                    "max_triggers",
                    json!({"type": ["integer", "null"], "minimum": 0, "maximum": u32::MAX}),
                ),
                (
                    "period_ns",
                    json!({"type": ["integer", "null"], "minimum": 0}),
                ),
                ("initial_wait", json!({"type": "boolean"})),
            ],
        ),
        "activated" => (
            "A monitor made an activation: node is the new activation node, number counts from 1.",
            vec![
                ("monitor", node()),
                ("node", node()),
                (
                    "number",
                    json!({"type": "integer", "minimum": 1, "maximum": u32::MAX}),
                ),
            ],
        ),
        "triggered" => (
            "A monitor counted a trigger (count so far).",
            vec![("monitor", node()), ("count", u32_())],
        ),
        "handler_chosen" => (
            "The handler search found a handler: node is the new handler node.",
            vec![
                ("node", node()),
                ("failing", node()),
                ("attached", node()),
                ("exception", string()),
                ("handler", string()),
            ],
        ),
        "bypassed" => (
            "A handler node passed its exception on.",
            vec![("node", node()), ("exception", string())],
        ),
        "retried" => (
            "A handler asked for a fresh run of the failed task: node is the new node, of the one that failed.",
            vec![("node", node()), ("of", node())],
        ),
        "tapped" => (
            "A wiretap check started on the node, before its action or after it returned.",
            vec![
                ("node", node()),
                ("tap", u32_()),
                ("when", json!({"enum": ["before", "after"]})),
            ],
        ),
        "callback_set" => {
            uses_defs = true;
            (
                "A timer callback was set; it runs once, at `when`.",
                vec![
                    ("callback", count()),
                    ("name", string()),
                    ("node", maybe_node()),
                    ("when", json!({"$ref": "#/$defs/when"})),
                ],
            )
        }
        "callback_ran" => (
            "The callback's event happened or its time came; the shell runs it now.",
            vec![("callback", count()), ("name", string())],
        ),
        "resource" => (
            "A resource was declared: its capacity, and how many requests may wait for it (null: no limit).",
            vec![
                ("resource", string()),
                ("capacity", u32_()),
                (
                    "pending_limit",
                    json!({"type": ["integer", "null"], "minimum": 0, "maximum": u32::MAX}),
                ),
            ],
        ),
        "requested" => (
            "A node asks for resources, all at once: its handling is enabled and it would start.",
            vec![
                ("node", node()),
                ("uses", resource_uses()),
                (
                    "priority",
                    json!({"type": "integer", "minimum": i32::MIN, "maximum": i32::MAX}),
                ),
            ],
        ),
        "granted" => (
            "A node's request was granted: it holds the resources until its action ends.",
            vec![("node", node()), ("uses", resource_uses())],
        ),
        "released" => (
            "A node gave back what it was granted.",
            vec![("node", node()), ("uses", resource_uses())],
        ),
        "withdrawn" => (
            "A waiting request was withdrawn: its node was terminated before it was granted.",
            vec![("node", node())],
        ),
        "denied" => (
            "A request was refused; its node fails with ResourceDenied.",
            vec![("node", node()), ("resource", string())],
        ),
        "dropped" => (
            "A waiting request was dropped past the resource's pending limit; its node fails with ResourceDropped.",
            vec![("node", node()), ("resource", string())],
        ),
        "resource_reserved" => (
            "A resource was reserved for a node's subtree.",
            vec![("resource", string()), ("holder", node())],
        ),
        "resource_unreserved" => (
            "A resource's reservation ended.",
            vec![("resource", string())],
        ),
        "resource_locked" => (
            "A resource was locked: nobody is granted it until it is unlocked.",
            vec![("resource", string())],
        ),
        "resource_unlocked" => ("A resource was unlocked.", vec![("resource", string())]),
        _ => return None,
    };
    let mut properties = serde_json::Map::new();
    properties.insert(
        "seq".into(),
        json!({"type": "integer", "minimum": 0, "description": "position in the trace: 0, 1, 2, ... without gaps"}),
    );
    properties.insert(
        "t".into(),
        json!({"type": "integer", "minimum": 0, "description": "virtual time in nanoseconds since the run started"}),
    );
    properties.insert("ev".into(), json!({"const": ev}));
    let mut required = vec!["seq", "t", "ev"];
    for (name, field) in fields {
        properties.insert(name.into(), field);
        required.push(name);
    }
    let mut schema = json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": format!("tdl.trace.{ev}"),
        "description": description,
        "type": "object",
        "properties": properties,
        "required": required,
        "additionalProperties": false,
    });
    if uses_defs {
        schema["$defs"] = defs();
    }
    Some(schema)
}

/// The shared definitions: facets, states, events, and the constraint forms.
fn defs() -> Value {
    let count = json!({"type": "integer", "minimum": 0});
    let object = |name: &str, value: Value| {
        json!({
            "type": "object",
            "properties": {name: value},
            "required": [name],
            "additionalProperties": false,
        })
    };
    json!({
        "facet": {"enum": ["handling", "expansion", "execution"]},
        "state": {"enum": ["disabled", "enabled", "active", "completed"]},
        "event": {
            "description": "The moment the node's facet reaches the point (with an outcome: only if the execution ends that way).",
            "type": "object",
            "properties": {
                "node": count,
                "facet": {"$ref": "#/$defs/facet"},
                "point": {"enum": ["enabled", "active", "completed"]},
                "outcome": {"enum": ["succeeded", "failed", "terminated"]},
            },
            "required": ["node", "facet", "point"],
            "additionalProperties": false,
        },
        "when": {
            "oneOf": [
                {"const": "now"},
                object("at", count.clone()),
                object("event", json!({"$ref": "#/$defs/event"})),
                object("after", json!({
                    "type": "object",
                    "properties": {"delay_ns": count, "event": {"$ref": "#/$defs/event"}},
                    "required": ["delay_ns", "event"],
                    "additionalProperties": false,
                })),
                object("external", json!({"type": "string"})),
                object("all", json!({
                    "type": "object",
                    "properties": {
                        "events": {"type": "array", "items": {"$ref": "#/$defs/event"}},
                        "delay_ns": count,
                    },
                    "required": ["events"],
                    "additionalProperties": false,
                })),
            ],
        },
        "then": {
            "oneOf": [
                {"enum": ["terminate", "activate"]},
                object("enable", json!({"$ref": "#/$defs/facet"})),
            ],
        },
        "constraint": {
            "oneOf": [
                object("form", json!({"const": "expand_first"})),
                object("form", json!({"const": "delay_expansion"})),
                {
                    "type": "object",
                    "properties": {
                        "form": {"const": "trigger"},
                        "when": {"$ref": "#/$defs/when"},
                        "then": {"$ref": "#/$defs/then"},
                    },
                    "required": ["form", "when", "then"],
                    "additionalProperties": false,
                },
            ],
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small JSON Schema validator for what [`schema`] uses: `type`, `const`, `enum`,
    /// `properties`, `required`, `additionalProperties: false`, `items`, `oneOf`, `minimum`,
    /// `maximum`, and `$ref` to `#/$defs/…`. `Err` says where the value breaks the schema.
    fn validate(value: &Value, schema: &Value, root: &Value, at: &str) -> Result<(), String> {
        if let Some(r) = schema.get("$ref").and_then(Value::as_str) {
            let name = r
                .strip_prefix("#/$defs/")
                .ok_or(format!("{at}: bad $ref {r}"))?;
            let target = root
                .get("$defs")
                .and_then(|d| d.get(name))
                .ok_or(format!("{at}: no $defs/{name}"))?;
            return validate(value, target, root, at);
        }
        if let Some(c) = schema.get("const") {
            if value != c {
                return Err(format!("{at}: {value} is not {c}"));
            }
        }
        if let Some(options) = schema.get("enum").and_then(Value::as_array) {
            if !options.contains(value) {
                return Err(format!("{at}: {value} is not one of {options:?}"));
            }
        }
        if let Some(types) = schema.get("type") {
            let types: Vec<&str> = match types {
                Value::String(s) => vec![s.as_str()],
                Value::Array(a) => a.iter().filter_map(Value::as_str).collect(),
                _ => return Err(format!("{at}: bad type {types}")),
            };
            let ok = types.iter().any(|t| match *t {
                "integer" => value.is_u64() || value.is_i64(),
                "string" => value.is_string(),
                "boolean" => value.is_boolean(),
                "null" => value.is_null(),
                "object" => value.is_object(),
                "array" => value.is_array(),
                _ => false,
            });
            if !ok {
                return Err(format!("{at}: {value} is not of type {types:?}"));
            }
        }
        if let Some(n) = value.as_f64() {
            if schema
                .get("minimum")
                .and_then(Value::as_f64)
                .is_some_and(|m| n < m)
            {
                return Err(format!("{at}: {value} is below the minimum"));
            }
            if schema
                .get("maximum")
                .and_then(Value::as_f64)
                .is_some_and(|m| n > m)
            {
                return Err(format!("{at}: {value} is above the maximum"));
            }
        }
        if let Some(options) = schema.get("oneOf").and_then(Value::as_array) {
            let matching = options
                .iter()
                .filter(|o| validate(value, o, root, at).is_ok())
                .count();
            if matching != 1 {
                return Err(format!("{at}: {value} matches {matching} of oneOf"));
            }
        }
        if let Some(object) = value.as_object() {
            let properties = schema.get("properties").and_then(Value::as_object);
            for name in schema
                .get("required")
                .and_then(Value::as_array)
                .into_iter()
                .flatten()
                .filter_map(Value::as_str)
            {
                if !object.contains_key(name) {
                    return Err(format!("{at}: missing `{name}`"));
                }
            }
            for (name, v) in object {
                match properties.and_then(|p| p.get(name)) {
                    Some(s) => validate(v, s, root, &format!("{at}.{name}"))?,
                    None if schema.get("additionalProperties") == Some(&Value::Bool(false)) => {
                        return Err(format!("{at}: unexpected `{name}`"));
                    }
                    None => {}
                }
            }
        }
        if let (Some(items), Some(array)) = (schema.get("items"), value.as_array()) {
            for (i, v) in array.iter().enumerate() {
                validate(v, items, root, &format!("{at}[{i}]"))?;
            }
        }
        Ok(())
    }

    fn check(line: &str) -> Result<String, String> {
        let ev = tcm_trace::read_jsonl(line.as_bytes())
            .map_err(|e| format!("{line}: {e}"))?
            .pop()
            .ok_or("no record")?;
        let value: Value =
            serde_json::from_str(&tcm_trace::to_line(&ev)).map_err(|e| e.to_string())?;
        let kind = value["ev"].as_str().ok_or("no ev")?.to_string();
        let schema = schema(&kind).ok_or(format!("no schema for {kind}"))?;
        validate(&value, &schema, &schema, &kind)?;
        Ok(kind)
    }

    /// Every example record of docs/trace-format.md (one of every kind and every constraint form)
    /// and every record of the CLI's test traces fits the schema of its kind.
    #[test]
    fn every_documented_record_fits_its_schema() {
        let doc = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../docs/trace-format.md"
        ))
        .expect("docs/trace-format.md");
        let mut kinds = std::collections::BTreeSet::new();
        let mut in_json = false;
        for line in doc.lines() {
            match line {
                "```json" => in_json = true,
                "```" => in_json = false,
                _ if in_json => {
                    kinds.insert(check(line).unwrap_or_else(|e| panic!("{e}")));
                }
                _ => {}
            }
        }
        assert_eq!(kinds.len(), 36, "{kinds:?}");
        for file in ["run.jsonl", "handled_run.jsonl"] {
            let path = format!("{}/tests/data/{file}", env!("CARGO_MANIFEST_DIR"));
            let text = std::fs::read_to_string(&path).expect("a test trace");
            for line in text.lines().filter(|l| !l.trim().is_empty()) {
                check(line).unwrap_or_else(|e| panic!("{path}: {e}"));
            }
        }
    }

    /// The validator is no formality: records that break the schemas are refused.
    #[test]
    fn records_that_break_the_schema_are_refused() {
        let schema_of = |ev: &str| schema(ev).expect("a schema");
        let bad = [
            (
                "terminated",
                json!({"seq": 1, "t": 0, "ev": "terminated", "node": 1, "extra": 2}),
            ),
            ("terminated", json!({"seq": 1, "t": 0, "ev": "terminated"})),
            (
                "spawned",
                json!({"seq": 1, "t": 0, "ev": "spawned", "node": 1, "parent": 0, "kind": "root", "name": "r"}),
            ),
            (
                "transition",
                json!({"seq": 1, "t": 0, "ev": "transition", "node": 1, "facet": "handling", "from": "idle", "to": "active"}),
            ),
            (
                "constrained",
                json!({"seq": 1, "t": 0, "ev": "constrained", "node": 1, "constraint": {"form": "trigger", "when": "soon", "then": "terminate"}}),
            ),
            (
                "warning",
                json!({"seq": -1, "t": 0, "ev": "warning", "node": null, "message": "m"}),
            ),
        ];
        for (ev, value) in bad {
            let schema = schema_of(ev);
            assert!(validate(&value, &schema, &schema, ev).is_err(), "{value}");
        }
        assert_eq!(schema("no_such_record"), None);
    }
}
