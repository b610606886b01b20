//! The heap every measurement runs on: kept between measurements, as a long-running executive's
//! is (see docs/performance.md, "The heap the benchmarks run on").
//!
//! glibc's allocator gives the top of its heap back to the system whenever more than a threshold
//! of it is free, and serves large blocks with their own `mmap`, unmapped when freed. A benchmark
//! that builds a fresh runtime for each of its repeats then pays the kernel's first touch of every
//! page again in each repeat, but only for trees too large to stay in the heap glibc keeps: a
//! 10,000-node run reuses its memory from one repeat to the next, a 1,000,000-node run never does.
//! That first touch (page faults, the kernel zeroing pages) is a cost of the process growing, not
//! of the task tree, and it made the figures depend on the size of the tree and on where the heap
//! happened to end. Keeping the heap measures every size and every workload in the same, steady
//! state. `--cold-heap` leaves glibc's defaults, to see the difference; `bench/compare` gives the
//! other systems' processes the same setting through `GLIBC_TUNABLES`
//! (`glibc.malloc.trim_threshold=4294967295:glibc.malloc.mmap_threshold=33554432`).

/// The largest block glibc serves from its heap rather than with a mapping of its own: 32 MiB,
/// the most `mallopt` accepts on a 64-bit system.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const MMAP_THRESHOLD: libc::c_int = 32 << 20;

/// Keeps the heap: never gives its top back, and serves blocks up to 32 MiB from it. Returns
/// whether the allocator took the setting (false off glibc).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
pub(crate) fn keep() -> bool {
    // SAFETY: `mallopt` only sets the allocator's parameters; it is called before any thread of
    // this process allocates concurrently, and glibc takes its own lock for it.
    unsafe {
        libc::mallopt(libc::M_TRIM_THRESHOLD, -1) == 1
            && libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD) == 1
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
pub(crate) fn keep() -> bool {
    false
}
