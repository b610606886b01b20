//! Compiled and interpreted, the same program gives the same trace.

use tdl::Runtime;
use tdl_interp::{Registry, Value};

use crate::both;
use crate::util::{assert_same, load, trace_of};

both!(sequence {
    pub goal patrol(rooms: u32) {
        for room in 0..rooms {
            spawn visit(room) with sequential execution previous;
        }
        spawn report() with sequential execution previous, terminate in 30s;
    }

    command visit(room: u32) {
        if room == 1 {
            fail DoorLocked { room };
        }
    }

    command report() {}

    exception DoorLocked { room: u32 }
});

#[tokio::test(start_paused = true)]
async fn a_sequence_with_a_failure_runs_alike() {
    let compiled = trace_of(Runtime::new(), sequence::patrol(3)).await;
    let program = load(sequence::SRC, &Registry::new());
    let task = program.task("patrol", vec![Value::Int(3)]).expect("a task");
    let interpreted = trace_of(Runtime::new(), task).await;
    assert_same(&compiled, &interpreted);
}
