//! `tdl trace export --mcap`: a trace as an MCAP file, for robotics log tools (Foxglove and the
//! like) to show beside the robot's own recordings.
//!
//! One channel per kind of record, topic `/tdl/trace/<ev>` (`/tdl/trace/spawned`, …), created
//! when the first record of that kind comes; message encoding `json`, each message one record
//! exactly as the JSON-lines trace writes it (docs/trace-format.md; a trace of an older format
//! version is written in the current shape); schema `tdl.trace.<ev>`, encoding `jsonschema`, a JSON
//! Schema of that kind of record, derived from the record types by `schemars` (`tcm-trace`'s
//! `schema` feature). Log and publish time are the record's `t` (nanoseconds of virtual
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

/// The JSON Schema (draft 2020-12) of the records of kind `ev`, derived from the record types
/// (`TraceEvent`, as it serialises: `schemars` follows serde's renames, tags, flattening and
/// skipped fields): the variant of that kind, with the fields every record has (`seq`, `t`), no
/// other field allowed, and the definitions it refers to.
pub(crate) fn schema(ev: &str) -> Option<Value> {
    let root = schemars::generate::SchemaSettings::draft2020_12()
        .for_serialize()
        .into_generator()
        .into_root_schema_for::<TraceEvent>()
        .to_value();
    let variant = root
        .get("oneOf")?
        .as_array()?
        .iter()
        .find(|v| v.pointer("/properties/ev/const").and_then(Value::as_str) == Some(ev))?;
    let mut properties = root.get("properties")?.as_object()?.clone();
    properties.extend(variant.get("properties")?.as_object()?.clone());
    let mut required = root.get("required")?.as_array()?.clone();
    required.extend(variant.get("required")?.as_array()?.iter().cloned());
    let mut schema = json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": format!("tdl.trace.{ev}"),
        "description": variant.get("description").cloned().unwrap_or(Value::Null),
        "type": "object",
        "properties": properties,
        "required": required,
        "additionalProperties": false,
    });
    // The definitions it refers to, and those they refer to.
    let all = root.get("$defs").and_then(Value::as_object);
    let mut defs = serde_json::Map::new();
    let mut todo = Vec::new();
    refs(&schema, &mut todo);
    while let Some(name) = todo.pop() {
        if defs.contains_key(&name) {
            continue;
        }
        let def = all.and_then(|a| a.get(&name))?.clone();
        refs(&def, &mut todo);
        defs.insert(name, def);
    }
    if !defs.is_empty() {
        schema["$defs"] = Value::Object(defs);
    }
    ranges(&mut schema);
    Some(schema)
}

/// Gives 32-bit integers their range: `schemars` names it only as a `format` (an annotation a
/// validator need not check).
fn ranges(schema: &mut Value) {
    match schema {
        Value::Object(map) => {
            match map.get("format").and_then(Value::as_str) {
                Some("uint32") => {
                    map.insert("maximum".into(), u32::MAX.into());
                }
                Some("int32") => {
                    map.insert("minimum".into(), i32::MIN.into());
                    map.insert("maximum".into(), i32::MAX.into());
                }
                _ => {}
            }
            map.values_mut().for_each(ranges);
        }
        Value::Array(items) => items.iter_mut().for_each(ranges),
        _ => {}
    }
}

/// The names of the definitions `schema` refers to (`"$ref": "#/$defs/<name>"`).
fn refs(schema: &Value, out: &mut Vec<String>) {
    match schema {
        Value::Object(map) => {
            for (key, value) in map {
                match (key.as_str(), value.as_str()) {
                    ("$ref", Some(r)) => {
                        if let Some(name) = r.strip_prefix("#/$defs/") {
                            out.push(name.to_string());
                        }
                    }
                    _ => refs(value, out),
                }
            }
        }
        Value::Array(items) => items.iter().for_each(|v| refs(v, out)),
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small JSON Schema validator for what [`schema`] uses: `type`, `const`, `enum`,
    /// `properties`, `required`, `additionalProperties: false`, `items`, `oneOf`, `anyOf`,
    /// `minimum`, `maximum`, and `$ref` to `#/$defs/…` (`format` is an annotation). `Err` says
    /// where the value breaks the schema.
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
                "number" => value.is_number(),
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
        if let Some(options) = schema.get("anyOf").and_then(Value::as_array) {
            if !options.iter().any(|o| validate(value, o, root, at).is_ok()) {
                return Err(format!("{at}: {value} matches none of anyOf"));
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
        assert_eq!(kinds.len(), 50, "{kinds:?}");
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
                json!({"seq": 1, "t": 0, "ev": "spawned", "node": 1, "parent": 0, "kind": "robot", "name": "r"}),
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
            (
                "tapped",
                json!({"seq": 1, "t": 0, "ev": "tapped", "node": 1, "tap": 0, "when": "during"}),
            ),
            (
                "requested",
                json!({"seq": 1, "t": 0, "ev": "requested", "node": 1, "uses": [{"resource": "base", "amount": 1, "extra": 0}], "priority": 0}),
            ),
            (
                "callback_set",
                json!({"seq": 1, "t": 0, "ev": "callback_set", "callback": 0, "name": "c", "node": null, "when": {"event": {"node": 1, "facet": "handling", "point": "active", "outcome": "lost"}}}),
            ),
            (
                "monitor_params",
                json!({"seq": 1, "t": 0, "ev": "monitor_params", "node": 1, "max_activations": 4294967296_u64, "max_triggers": null, "period_ns": null, "initial_wait": false}),
            ),
        ];
        for (ev, value) in bad {
            let schema = schema_of(ev);
            assert!(validate(&value, &schema, &schema, ev).is_err(), "{value}");
        }
        assert_eq!(schema("no_such_record"), None);
    }
}
