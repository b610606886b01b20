//! `tdl trace export --mcap`: an independent reader, the `mcap` package from PyPI in the
//! workspace's test venv, reads the file back: one message per record, on the channel of its kind,
//! JSON fitting the channel's JSON Schema, at the record's time. Bad input is an error naming the
//! file and line, and leaves nothing behind.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

use super::tdl;

/// A fresh directory for one test's files.
fn work_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("tdl-export-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("a work directory");
    dir
}

/// Reads an MCAP file with the Python `mcap` package and checks every message against its
/// channel's schema (a small validator of the JSON Schema keywords the export uses); prints what
/// it found as JSON.
const READER: &str = r#"
import json, sys
from mcap.reader import make_reader

def check(value, schema, root, at):
    if "$ref" in schema:
        return check(value, root["$defs"][schema["$ref"].split("/")[-1]], root, at)
    errors = []
    if "const" in schema and value != schema["const"]:
        errors.append(f"{at}: {value!r} is not {schema['const']!r}")
    if "enum" in schema and value not in schema["enum"]:
        errors.append(f"{at}: {value!r} is not one of {schema['enum']}")
    if "type" in schema:
        types = schema["type"] if isinstance(schema["type"], list) else [schema["type"]]
        kinds = {"integer": lambda v: isinstance(v, int) and not isinstance(v, bool),
                 "number": lambda v: isinstance(v, (int, float)) and not isinstance(v, bool),
                 "string": lambda v: isinstance(v, str), "boolean": lambda v: isinstance(v, bool),
                 "null": lambda v: v is None, "object": lambda v: isinstance(v, dict),
                 "array": lambda v: isinstance(v, list)}
        if not any(kinds[t](value) for t in types):
            errors.append(f"{at}: {value!r} is not {types}")
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        if "minimum" in schema and value < schema["minimum"]:
            errors.append(f"{at}: {value!r} is below {schema['minimum']}")
        if "maximum" in schema and value > schema["maximum"]:
            errors.append(f"{at}: {value!r} is above {schema['maximum']}")
    if "anyOf" in schema and not any(not check(value, s, root, at) for s in schema["anyOf"]):
        errors.append(f"{at}: {value!r} matches none of anyOf")
    if "oneOf" in schema:
        n = sum(1 for s in schema["oneOf"] if not check(value, s, root, at))
        if n != 1:
            errors.append(f"{at}: {value!r} matches {n} of oneOf")
    if isinstance(value, dict):
        for name in schema.get("required", []):
            if name not in value:
                errors.append(f"{at}: missing {name}")
        for name, v in value.items():
            if name in schema.get("properties", {}):
                errors += check(v, schema["properties"][name], root, f"{at}.{name}")
            elif schema.get("additionalProperties") is False:
                errors.append(f"{at}: unexpected {name}")
    if isinstance(value, list) and "items" in schema:
        for i, v in enumerate(value):
            errors += check(v, schema["items"], root, f"{at}[{i}]")
    return errors

found = {"count": 0, "topics": [], "errors": [], "times": [], "sequences": []}
with open(sys.argv[1], "rb") as f:
    reader = make_reader(f)
    for schema, channel, message in reader.iter_messages(log_time_order=False):
        found["count"] += 1
        if channel.topic not in found["topics"]:
            found["topics"].append(channel.topic)
        if channel.message_encoding != "json" or schema.encoding != "jsonschema":
            found["errors"].append(f"{channel.topic}: {channel.message_encoding}, {schema.encoding}")
        record = json.loads(message.data)
        if channel.topic != "/tdl/trace/" + record["ev"]:
            found["errors"].append(f"{record['ev']} on {channel.topic}")
        if message.log_time != record["t"] or message.publish_time != record["t"]:
            found["errors"].append(f"record {record['seq']}: log time {message.log_time}")
        found["sequences"].append(message.sequence)
        found["errors"] += check(record, json.loads(schema.data), json.loads(schema.data), record["ev"])
print(json.dumps(found))
"#;

/// What the Python reader found in `mcap`, or `None` (the test says "skipped") without Python.
fn read_back(mcap: &Path) -> Option<Value> {
    if test_support::find_on_path("python3").is_none() {
        println!("skipped: python3 is not on PATH, so the MCAP file cannot be read back");
        return None;
    }
    let python = test_support::python_venv(&["mcap"]).unwrap_or_else(|why| panic!("{why}"));
    let out = Command::new(python)
        .arg("-c")
        .arg(READER)
        .arg(mcap)
        .output()
        .expect("run the Python reader");
    assert!(
        out.status.success(),
        "the Python reader failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    Some(serde_json::from_slice(&out.stdout).expect("the reader's JSON"))
}

/// The `ev` of every record of a JSON-lines trace, in order.
fn kinds(trace: &str) -> Vec<String> {
    trace
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let v: Value = serde_json::from_str(l).expect("a record");
            v["ev"].as_str().expect("an ev").to_string()
        })
        .collect()
}

/// Exports `trace` (a path relative to this crate) to `dir/out.mcap`; the exit code, stdout,
/// stderr and the output path.
fn export(trace: &str, dir: &Path) -> (i32, String, String, PathBuf) {
    let out = dir.join("out.mcap");
    let out_arg = out.display().to_string();
    let (code, stdout, stderr) = tdl(&["trace", "export", "--mcap", &out_arg, trace]);
    (code, stdout, stderr, out)
}

fn assert_read_back(mcap: &Path, trace: &str) {
    let Some(found) = read_back(mcap) else {
        return;
    };
    let kinds = kinds(trace);
    assert_eq!(found["errors"], Value::Array(Vec::new()), "{found}");
    assert_eq!(found["count"].as_u64(), Some(kinds.len() as u64), "{found}");
    let mut topics: Vec<String> = Vec::new();
    for kind in &kinds {
        let topic = format!("/tdl/trace/{kind}");
        if !topics.contains(&topic) {
            topics.push(topic);
        }
    }
    let mut found_topics: Vec<String> = found["topics"]
        .as_array()
        .expect("topics")
        .iter()
        .map(|t| t.as_str().expect("a topic").to_string())
        .collect();
    found_topics.sort();
    topics.sort();
    assert_eq!(found_topics, topics);
    let sequences: Vec<u64> = found["sequences"]
        .as_array()
        .expect("sequences")
        .iter()
        .filter_map(Value::as_u64)
        .collect();
    assert_eq!(sequences, (0..kinds.len() as u64).collect::<Vec<_>>());
}

#[test]
fn a_run_exported_as_mcap_reads_back_one_message_per_record() {
    let dir = work_dir("run");
    let (code, stdout, stderr, out) = export("tests/data/handled_run.jsonl", &dir);
    assert_eq!(code, 0, "{stderr}");
    let trace = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/handled_run.jsonl"),
    )
    .expect("the trace");
    let n = kinds(&trace).len();
    assert!(
        stdout.starts_with(&format!(
            "tests/data/handled_run.jsonl: wrote {n} records on "
        )),
        "{stdout}"
    );
    // The file is an MCAP file: magic at both ends; no temporary file is left beside it.
    let bytes = std::fs::read(&out).expect("the MCAP file");
    assert!(bytes.starts_with(b"\x89MCAP0\r\n") && bytes.ends_with(b"\x89MCAP0\r\n"));
    let left: Vec<_> = std::fs::read_dir(&dir)
        .expect("the work directory")
        .filter_map(Result::ok)
        .map(|e| e.file_name())
        .collect();
    assert_eq!(left, ["out.mcap"]);
    assert_read_back(&out, &trace);
}

/// Every kind of record and every constraint form, from the examples of docs/trace-format.md,
/// fits the schema of its channel as the Python reader checks it.
#[test]
fn every_documented_record_reads_back_and_fits_its_schema() {
    let doc = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/trace-format.md"),
    )
    .expect("docs/trace-format.md");
    let mut trace = String::new();
    let mut in_json = false;
    let mut seq = 0;
    for line in doc.lines() {
        match line {
            "```json" => in_json = true,
            "```" => in_json = false,
            _ if in_json => {
                // Renumbered so that `seq` counts 0, 1, 2, … as in a real trace.
                let mut record: Value = serde_json::from_str(line).expect("a documented record");
                record["seq"] = Value::from(seq);
                seq += 1;
                trace.push_str(&record.to_string());
                trace.push('\n');
            }
            _ => {}
        }
    }
    let dir = work_dir("documented");
    let file = dir.join("documented.jsonl");
    std::fs::write(&file, &trace).expect("write the trace");
    let (code, _, stderr, out) = export(&file.display().to_string(), &dir);
    assert_eq!(code, 0, "{stderr}");
    let kinds: std::collections::BTreeSet<String> = kinds(&trace).into_iter().collect();
    assert_eq!(kinds.len(), 50, "{kinds:?}");
    assert_read_back(&out, &trace);
}

#[test]
fn bad_input_names_the_file_and_line_and_leaves_nothing() {
    let dir = work_dir("bad");
    // A missing trace.
    let (code, _, stderr, out) = export("tests/data/missing.jsonl", &dir);
    assert_eq!(code, 2);
    assert!(
        stderr.contains("cannot read tests/data/missing.jsonl"),
        "{stderr}"
    );
    assert!(!out.exists());
    // A garbage line: an older export at the destination is kept as it was.
    let good =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/run.jsonl"))
            .expect("a trace");
    let mut lines: Vec<&str> = good.lines().collect();
    lines[2] = "{\"seq\":2,\"t\":0,\"ev\":\"transition\",";
    let file = dir.join("garbage.jsonl");
    std::fs::write(&file, lines.join("\n")).expect("write the trace");
    std::fs::write(dir.join("out.mcap"), "older").expect("an older export");
    let (code, _, stderr, out) = export(&file.display().to_string(), &dir);
    assert_eq!(code, 2);
    assert!(
        stderr.contains(&format!("{} is not a trace: line 3: ", file.display())),
        "{stderr}"
    );
    assert_eq!(
        std::fs::read_to_string(&out).expect("the older export"),
        "older"
    );
    let mut left: Vec<_> = std::fs::read_dir(&dir)
        .expect("the work directory")
        .filter_map(Result::ok)
        .map(|e| e.file_name())
        .collect();
    left.sort();
    assert_eq!(left, ["garbage.jsonl", "out.mcap"]);
    // `--mcap` is required.
    let (code, _, _) = tdl(&["trace", "export", "tests/data/run.jsonl"]);
    assert_eq!(code, 2);
}

/// The trace of a real run: a seeded simulation of the Xavier mission (with failures), written by
/// `tdl sim` when a property fails at the end of its first delivery. Exported, each record carries
/// exactly the fields the schema of its channel names (read here, without Python), and fits that
/// schema as the Python reader checks it.
#[test]
fn a_simulated_run_of_the_mission_exports_records_its_schemas_describe() {
    let dir = work_dir("sim");
    let sim_out = dir.join("sim").display().to_string();
    let (code, out, err) = tdl(&[
        "sim",
        "-p",
        "xavier",
        "--seeds",
        "20",
        "--fail",
        "0.1",
        "--property",
        "completed(give_up_door_not_found) before completed(notify_sender)",
        "--out",
        &sim_out,
    ]);
    assert_eq!(code, 1, "a violation is expected: {out}{err}");
    let trace_file = std::fs::read_dir(&sim_out)
        .expect("the simulation's traces")
        .filter_map(Result::ok)
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|e| e == "jsonl"))
        .expect("a trace written");
    let trace = std::fs::read_to_string(&trace_file).expect("the trace");
    let (code, _, stderr, mcap) = export(&trace_file.display().to_string(), &dir);
    assert_eq!(code, 0, "{stderr}");
    let bytes = std::fs::read(&mcap).expect("the MCAP file");
    let mut seen = std::collections::BTreeSet::new();
    let mut count = 0;
    for message in mcap::MessageStream::new(&bytes).expect("an MCAP file") {
        let message = message.expect("a message");
        let schema = message.channel.schema.as_ref().expect("a schema");
        assert_eq!(schema.encoding, "jsonschema");
        let schema: Value = serde_json::from_slice(&schema.data).expect("a JSON schema");
        let record: Value = serde_json::from_slice(&message.data).expect("a JSON record");
        let ev = record["ev"].as_str().expect("an ev").to_string();
        assert_eq!(schema["title"], format!("tdl.trace.{ev}"));
        let properties = schema["properties"].as_object().expect("properties");
        let fields = record.as_object().expect("an object");
        for name in fields.keys() {
            assert!(
                properties.contains_key(name),
                "`{name}` of {record} is not in the schema of `{ev}`"
            );
        }
        for name in schema["required"].as_array().expect("required") {
            let name = name.as_str().expect("a name");
            assert!(
                fields.contains_key(name),
                "{record} lacks `{name}`, required by the schema of `{ev}`"
            );
        }
        assert_eq!(properties["ev"]["const"], Value::from(ev.as_str()));
        seen.insert(ev);
        count += 1;
    }
    assert_eq!(count, kinds(&trace).len());
    // A run, not a sample: constraints, resources, monitors and a handled failure.
    for kind in [
        "constrained",
        "requested",
        "granted",
        "monitor_params",
        "activated",
        "failed",
        "handler_chosen",
    ] {
        assert!(seen.contains(kind), "no `{kind}` record in {seen:?}");
    }
    assert_read_back(&mcap, &trace);
}
