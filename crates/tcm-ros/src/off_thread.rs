//! Blocking calls of ros2-client's zenoh backend (its action client's goal, result and cancel
//! requests wait on a channel) run on a thread of their own, awaited through a oneshot channel.
//!
//! Not tokio's blocking pool: a result request may block for up to a minute (the backend's own
//! timeout), and a runtime that shuts down waits for its blocking tasks, so a run that ended would
//! wait for it. A detached thread holds nobody; its answer is dropped if nobody awaits it.

use crate::failure::RosError;
use tcm::Failure;

/// Runs `f` on a new thread named `name`; the future ends with what `f` returns, or with a
/// [`RosError`] if the thread could not start or `f` panicked.
pub(crate) async fn run<T, F>(name: &str, f: F) -> Result<T, Failure>
where
    T: Send + 'static,
    F: FnOnce() -> T + Send + 'static,
{
    let (tx, rx) = tokio::sync::oneshot::channel();
    std::thread::Builder::new()
        .name(name.to_string())
        .spawn(move || {
            let _ = tx.send(f());
        })
        .map_err(|e| RosError::failure(format!("cannot start a thread for {name}: {e}")))?;
    rx.await
        .map_err(|_| RosError::failure(format!("the thread of {name} panicked")))
}
