//! The priority a blocking body runs at (`Runtime::blocking_nice`): its thread's nice value is
//! raised while the body runs, and put back after, where the OS allows it (Linux only: elsewhere
//! nothing changes, since `setpriority` on a process there is not per thread).

/// Raises the calling thread's nice value to `nice` until dropped, if it is lower.
pub(crate) struct Niced {
    #[cfg(target_os = "linux")]
    before: Option<i32>,
}

impl Niced {
    /// `nice` 0 changes nothing.
    #[cfg(target_os = "linux")]
    pub(crate) fn enter(nice: i32) -> Niced {
        use rustix::process::{getpriority_process, setpriority_process};
        // On Linux the nice value is per thread, and `None` names the calling thread.
        let before = (nice > 0)
            .then(|| getpriority_process(None).ok())
            .flatten()
            .filter(|before| *before < nice)
            .filter(|_| setpriority_process(None, nice).is_ok());
        Niced { before }
    }

    #[cfg(not(target_os = "linux"))]
    pub(crate) fn enter(_nice: i32) -> Niced {
        Niced {}
    }
}

impl Drop for Niced {
    fn drop(&mut self) {
        #[cfg(target_os = "linux")]
        if let Some(before) = self.before {
            // Fails without the right to raise a priority: the thread stays lower.
            let _ = rustix::process::setpriority_process(None, before);
        }
    }
}
