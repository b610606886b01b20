//! Running a compiled and an interpreted task side by side, and comparing their traces.

use tcm_trace::TraceEvent;
use tdl::{Recorder, Runtime, Task};

/// A program compiled by `tdl!` with its text kept, to load it again at run time.
#[macro_export]
macro_rules! both {
    ($name:ident { $($src:tt)* }) => {
        #[allow(dead_code, unused_variables, unused_mut, clippy::all)]
        mod $name {
            tdl::tdl! { $($src)* }
            pub(crate) const SRC: &str = stringify!($($src)*);
        }
    };
}

/// The trace of `task` run on `rt`, as JSON lines, after the trace checker passed it.
pub(crate) async fn trace_of(rt: Runtime, task: Task) -> Vec<String> {
    let rec = Recorder::new();
    let report = rt
        .with_sink(rec.clone())
        .run(task)
        .await
        .expect("the run ends");
    let trace: Vec<TraceEvent> = rec.events();
    tdl::testing::assert_checked(&trace);
    tdl::testing::assert_no_panics(&report, &trace);
    tdl::testing::lines(&trace)
}

/// The program of `src`, loaded with `registry`.
pub(crate) fn load(src: &str, registry: &tdl_interp::Registry) -> tdl_interp::Program {
    match tdl_interp::Program::from_sources(&[("test.tdl".into(), src.into())], registry) {
        Ok(p) => p,
        Err(e) => panic!("{e}"),
    }
}

/// Asserts two traces are the same, showing the first difference.
#[track_caller]
pub(crate) fn assert_same(compiled: &[String], interpreted: &[String]) {
    for (i, (c, n)) in compiled.iter().zip(interpreted).enumerate() {
        assert_eq!(c, n, "record {i} differs (compiled, then interpreted)");
    }
    assert_eq!(
        compiled.len(),
        interpreted.len(),
        "the traces have different lengths"
    );
}
