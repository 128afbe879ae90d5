//! The allocator's heaps under a memory limit: the one setting the program
//! makes for the whole process, before any thread starts.
//!
//! glibc gives each thread that allocates a heap of its own (an arena),
//! and each such heap reserves 64 MiB of address space, up to eight heaps
//! a core. A batch starts many threads (its workers, each file's decoding
//! and fitting stages, exr's block decoders): 3 files of 8 × 8 texels took
//! over 1000 MiB of address space, and under `ulimit -v 1G` the memory rule
//! then refused the good files. Capped at one heap a core, the threads
//! share them instead, and the address space no longer grows with the
//! threads. Without a limit the reservations cost nothing, so nothing is
//! changed.

/// Caps glibc's arenas at the number of cores when the process runs under a
/// memory limit. Called first thing, while the program has one thread.
pub fn share_under_a_limit() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    if normalfit::io::memory_limit().is_some() {
        let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
        let arenas = libc::c_int::try_from(cores).unwrap_or(libc::c_int::MAX);
        // SAFETY: mallopt only sets a tuning parameter of the allocator; it
        // is called before any thread of ours starts. It returns 0 on
        // failure, which leaves glibc's default in place: harmless.
        unsafe {
            libc::mallopt(libc::M_ARENA_MAX, arenas);
        }
    }
}
