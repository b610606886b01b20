//! A deadline timer for real time, finer than tokio's.
//!
//! tokio's timer wheel rounds deadlines up to whole milliseconds, so a 1 ms polling monitor on
//! tokio's clock runs about 1.5 ms late. With [`crate::Runtime::precise_timer`], a dedicated thread
//! waits for the engine's next deadline on a condition variable until shortly before it, then spins
//! the last stretch, and wakes the driver. It reads the real clock, so it is for real-time runs only;
//! virtual-time runs (tokio's paused clock) keep tokio's timer.

use crate::host::Shared;
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// The stretch before a deadline spent spinning rather than sleeping: about the scheduler's wake-up
/// jitter on these machines, so the wake-up lands on time at the cost of a short busy wait.
const SPIN: Duration = Duration::from_micros(200);

#[derive(Default)]
struct TimerState {
    deadline: Option<Instant>,
    stop: bool,
}

pub(crate) struct PreciseTimer {
    state: Arc<(Mutex<TimerState>, Condvar)>,
    thread: Option<JoinHandle<()>>,
}

impl PreciseTimer {
    pub(crate) fn start(shared: Arc<Shared>) -> std::io::Result<PreciseTimer> {
        let state: Arc<(Mutex<TimerState>, Condvar)> = Arc::default();
        let st = state.clone();
        let thread = std::thread::Builder::new()
            .name("tcm-timer".into())
            .spawn(move || run(&st, &shared))?;
        Ok(PreciseTimer {
            state,
            thread: Some(thread),
        })
    }

    /// Sets (or clears) the deadline to wake the driver at.
    pub(crate) fn set(&self, deadline: Option<Instant>) {
        let (lock, cv) = &*self.state;
        if let Ok(mut s) = lock.lock() {
            if s.deadline != deadline {
                s.deadline = deadline;
                cv.notify_all();
            }
        }
    }
}

impl Drop for PreciseTimer {
    fn drop(&mut self) {
        let (lock, cv) = &*self.state;
        if let Ok(mut s) = lock.lock() {
            s.stop = true;
            cv.notify_all();
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The timer thread: an intentionally endless loop until `stop`, each turn waiting for the deadline.
fn run(state: &(Mutex<TimerState>, Condvar), shared: &Shared) {
    let (lock, cv) = state;
    let Ok(mut s) = lock.lock() else { return };
    loop {
        if s.stop {
            return;
        }
        let Some(deadline) = s.deadline else {
            s = match cv.wait(s) {
                Ok(s) => s,
                Err(_) => return,
            };
            continue;
        };
        let now = Instant::now();
        if now >= deadline {
            s.deadline = None;
            drop(s);
            shared.wake.notify_one();
            s = match lock.lock() {
                Ok(s) => s,
                Err(_) => return,
            };
        } else if deadline - now > SPIN {
            s = match cv.wait_timeout(s, deadline - now - SPIN) {
                Ok((s, _)) => s,
                Err(_) => return,
            };
        } else {
            drop(s);
            while Instant::now() < deadline {
                std::hint::spin_loop();
            }
            s = match lock.lock() {
                Ok(s) => s,
                Err(_) => return,
            };
        }
    }
}
