//! `tdl view`: the binary serves its trace files on the address it prints, and names a file's bad
//! line on the terminal (and still serves what came before it); with `--at SEQ`, the address it
//! prints opens the first file on that record, and a SEQ past the file's records is refused.
//! Each test talks HTTP/1.1 to the server on 127.0.0.1 and kills it at the end (one refused stops
//! by itself). (The warning for a non-loopback `--listen` is tested without a socket, in
//! tcm-view.)

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// A `tdl view` process, killed when dropped.
struct Served {
    child: Child,
    /// The address it listens on (`127.0.0.1:PORT`).
    url: String,
    /// The whole address it printed.
    printed: String,
    stderr: String,
}

impl Drop for Served {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `tdl view ARGS --listen 127.0.0.1:0`, started, its output piped.
fn view(args: &[&str]) -> std::process::Child {
    Command::new(env!("CARGO_BIN_EXE_tdl"))
        .arg("view")
        .args(args)
        .args(["--listen", "127.0.0.1:0"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run tdl view")
}

/// Starts `tdl view ARGS --listen 127.0.0.1:0` and reads the address it prints.
fn serve(args: &[&str]) -> Served {
    let mut child = view(args);
    let stdout = child.stdout.take().expect("stdout");
    let stderr = child.stderr.take().expect("stderr");
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if let Some(rest) = line.strip_prefix("tdl view: ") {
                let _ = tx.send(rest.split(' ').next().unwrap_or_default().to_string());
            }
        }
    });
    let printed = rx
        .recv_timeout(Duration::from_secs(30))
        .expect("tdl view prints its address within 30 s");
    let url = printed
        .strip_prefix("http://")
        .and_then(|rest| rest.split('/').next())
        .unwrap_or_default()
        .to_string();
    // What it said on stderr before serving (problems, warnings): read what is there.
    let (etx, erx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = etx.send(line);
        }
    });
    std::thread::sleep(Duration::from_millis(100));
    let stderr: Vec<String> = erx.try_iter().collect();
    Served {
        child,
        url,
        printed,
        stderr: stderr.join("\n"),
    }
}

/// The body of `GET path`.
pub(crate) fn get(addr: &str, path: &str) -> String {
    let mut s = TcpStream::connect(addr).expect("connect");
    s.set_read_timeout(Some(Duration::from_secs(10)))
        .expect("timeout");
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .expect("send");
    let mut text = String::new();
    s.read_to_string(&mut text).expect("read");
    let (head, body) = text.split_once("\r\n\r\n").expect("a response");
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    body.to_string()
}

#[test]
fn view_serves_each_file_as_a_run_and_the_page() {
    let served = serve(&["tests/data/run.jsonl", "tests/data/handled_run.jsonl"]);
    assert!(served.url.starts_with("127.0.0.1:"), "{}", served.url);
    let runs = get(&served.url, "/api/runs");
    assert!(runs.contains("\"name\":\"tests/data/run.jsonl\""), "{runs}");
    assert!(
        runs.contains("\"name\":\"tests/data/handled_run.jsonl\""),
        "{runs}"
    );
    assert!(runs.contains("\"problem\":null"), "{runs}");
    let records = std::fs::read_to_string("tests/data/run.jsonl")
        .or_else(|_| {
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/run.jsonl"))
        })
        .expect("the trace")
        .lines()
        .filter(|l| !l.trim().is_empty())
        .count();
    assert!(runs.contains(&format!("\"records\":{records}")), "{runs}");
    let page = get(&served.url, "/");
    assert!(page.contains("<title>TDL viewer</title>"), "{page}");
    let trace = get(&served.url, "/api/runs/0/trace.jsonl");
    assert_eq!(trace.lines().count(), records);
}

#[test]
fn a_bad_line_is_named_and_what_came_before_is_still_served() {
    // The first ten records of a run, then a line cut by a crash.
    let good =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/run.jsonl"))
            .expect("the trace");
    let mut text: String = good.lines().take(10).map(|l| format!("{l}\n")).collect();
    text.push_str("{\"seq\":10,\"t\":0,\"ev\":\"transi");
    let path = std::env::temp_dir().join(format!("tdl-view-cut-{}.jsonl", std::process::id()));
    std::fs::write(&path, text).expect("write the cut trace");
    let file = path.display().to_string();
    let served = serve(&[&file]);
    let _ = std::fs::remove_file(&path);
    assert!(
        served.stderr.contains(&format!("{file}:11: ")),
        "{}",
        served.stderr
    );
    let runs = get(&served.url, "/api/runs");
    assert!(runs.contains("\"records\":10"), "{runs}");
    assert!(
        runs.contains(&format!("\"problem\":\"{file}:11: ")),
        "{runs}"
    );
}

/// The records of `tests/data/run.jsonl`.
fn run_records() -> usize {
    std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/run.jsonl"))
        .expect("the trace")
        .lines()
        .filter(|l| !l.trim().is_empty())
        .count()
}

#[test]
fn at_prints_the_address_that_opens_the_first_file_on_that_record() {
    let served = serve(&[
        "tests/data/run.jsonl",
        "tests/data/handled_run.jsonl",
        "--at",
        "3",
    ]);
    assert_eq!(
        served.printed,
        format!("http://{}/?run=0&at=3", served.url),
        "{}",
        served.stderr
    );
    // It serves the runs as without `--at`.
    let runs = get(&served.url, "/api/runs");
    assert!(
        runs.contains(&format!("\"records\":{}", run_records())),
        "{runs}"
    );
}

#[test]
fn at_past_the_last_record_is_refused_with_the_files_count() {
    let records = run_records();
    let at = records.to_string();
    let mut child = view(&["tests/data/run.jsonl", "--at", &at]);
    // It stops by itself; a server is killed after 30 s.
    let start = std::time::Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait") {
            break status;
        }
        if start.elapsed() > Duration::from_secs(30) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("tdl view --at {at} served instead of refusing");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut out = String::new();
    let mut err = String::new();
    child
        .stdout
        .take()
        .expect("stdout")
        .read_to_string(&mut out)
        .expect("read");
    child
        .stderr
        .take()
        .expect("stderr")
        .read_to_string(&mut err)
        .expect("read");
    assert_eq!(status.code(), Some(2), "{out}{err}");
    assert_eq!(
        err.trim_end(),
        format!(
            "tdl: --at {at}: tests/data/run.jsonl has {records} records (records 0 to {})",
            records - 1
        )
    );
    assert!(!out.contains("http://"), "{out}");
}
