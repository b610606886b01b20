//! W3 through the async runtime (layer `shell`), and W1, W2 and W3 written with synchronous
//! actions (`Task::goal_now`, `Task::command_now`; layer `shell-now`).

use super::{best, shell};
use tcm::{Facet, NodeRef, Task};

/// W1 (`chained`) or W2 through the async runtime, written with synchronous actions
/// (`Task::goal_now`, `Task::command_now`): no future per action. The async rows keep their goal
/// as it was written (an async block with the loop in it), so that their figures compare across
/// versions.
pub(crate) fn shell_flat_now(n: usize, chained: bool) -> (f64, usize) {
    let mut hw = 0;
    let ns = best(|| {
        let (ns, h) = shell(n, || {
            Task::goal_now("top", move |ctx| {
                for _ in 0..n {
                    let s = ctx.spawn(Task::command_now("noop", |_| Ok(())));
                    let s = if chained {
                        s.serial(NodeRef::Previous)
                    } else {
                        s
                    };
                    s.start()?;
                }
                Ok(())
            })
        });
        hw = h;
        ns
    });
    (ns, hw)
}

/// W3 written with synchronous actions.
fn recursive_now(depth: usize) -> Task {
    Task::goal_now("g", move |ctx| {
        if depth > 1 {
            let c = ctx.spawn(Task::command_now("c", |_| Ok(()))).start()?;
            ctx.spawn(recursive_now(depth - 1))
                .sequential(Facet::Execution, c)
                .start()?;
        }
        Ok(())
    })
}

fn recursive(depth: usize) -> Task {
    Task::goal("g", move |ctx| async move {
        if depth > 1 {
            let c = ctx
                .spawn(Task::command("c", |_| async { Ok(()) }))
                .start()?;
            ctx.spawn(recursive(depth - 1))
                .sequential(Facet::Execution, c)
                .start()?;
        }
        Ok(())
    })
}

/// W3 through the async runtime, its actions async or synchronous (`now`).
pub(crate) fn shell_recursive(depth: usize, now: bool) -> (f64, usize) {
    let root: fn(usize) -> Task = if now { recursive_now } else { recursive };
    let mut hw = 0;
    let ns = best(|| {
        let (ns, h) = shell(2 * depth, || root(depth));
        hw = h;
        ns
    });
    (ns, hw)
}
