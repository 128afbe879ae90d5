//! The one memory rule: work is refused up front, in one line, when what
//! it will allocate does not fit in the memory the process may still take.
//!
//! Under a memory limit (`ulimit -v`, `prlimit --as`, `ulimit -d`) an
//! allocation that does not fit fails, and a failed allocation ends the
//! process with an abort that no `Result` can catch: inside a dependency
//! (the `exr` crate allocates its sample buffers itself), and in our own
//! code wherever a vector grows. So every path estimates, before it
//! allocates, the bytes it will hold, and is refused with
//! [`Error::Limits`] ("too large: … needs about N MiB of memory, but the
//! process may take only M MiB more (its memory limit is L MiB)") when they
//! do not fit ([`check_memory`]):
//!
//! * a whole-image decode, from the header (`io`);
//! * the fit, whose sums grow with N: a strip of at least 8·N columns
//!   holds up to 2N rows of them, on every thread at once
//!   (`fit::Plan::work_bytes`), checked by every fit
//!   ([`FitRequest::normals_into`](crate::FitRequest::normals_into), so the
//!   Python package's calls too) and, with their own buffers, up front by
//!   the whole-image conversion (its normals, residual, holes and encoders),
//!   the lit view and the streamed conversion (its bands);
//! * the inverse (`height`): its planes per texel, its patch operators
//!   (which grow with N) and its re-fits;
//! * the tiling check, and an EXR or TIFF assembled in memory for a writer.
//!
//! The buffers normalfit allocates itself are reserved fallibly
//! (`try_reserve`) besides, so an estimate that falls short still ends in
//! an error, not an abort.
//!
//! The room is the soft limit on address space (RLIMIT_AS) less what the
//! process has mapped (`VmSize` in `/proc/self/status`), and likewise for
//! the data limit (RLIMIT_DATA, `VmData`). The need is the estimate, plus
//! 64 MiB for the buffers of the libraries doing the work, plus what the
//! allocator reserves beyond the bytes allocated: glibc gives each thread
//! that allocates a heap of its own (an arena) that takes address space
//! 64 MiB at a time, so each thread the work starts counts 64 MiB and its
//! stack (2 MiB) ([`new_threads`]); and the estimates of work that holds
//! many smaller buffers per thread (the fit's sums) count up to 64 MiB
//! more a thread for the heap they grow, which may be left unused
//! ([`in_heaps`]). Without a limit, or where these cannot be read (not
//! Linux), there is nothing to check.

use std::sync::Mutex;

use crate::error::{Error, Result};

/// Headroom above an estimate for the buffers of the libraries doing the
/// work, which the estimate does not count.
const SLACK: u64 = 64 << 20;

/// The address space glibc reserves for a heap of a thread's arena, at
/// least its own (`HEAP_MAX_SIZE` on 64-bit systems): a new arena takes
/// one, and an arena that outgrows it takes another.
const HEAP: u64 = 64 << 20;

/// A thread's stack (Rust's and rayon's default).
const STACK: u64 = 2 << 20;

/// Refuses work that needs about `needed` more bytes of memory than the
/// process's memory limits leave, keeping 64 MiB besides for the buffers
/// of the libraries doing the work, and 66 MiB for each thread of the
/// thread pool it runs on (rayon's current pool) the first time the pool
/// is seen, for their allocator's heaps and stacks: a failure to allocate
/// would abort the process. `what` names the work in the message
/// ("decoding"). `Ok` when no limit is set, or where the use cannot be
/// read (not Linux).
///
/// The limits are the soft limits on address space (RLIMIT_AS: `ulimit
/// -v`, `prlimit --as`) and data (RLIMIT_DATA: `ulimit -d`); the use is
/// what the process has mapped (`VmSize`, `VmData` in `/proc/self/status`).
///
/// Errors: [`Error::Limits`], saying how much is needed and how much is
/// left.
pub fn check_memory(what: &str, needed: u64) -> Result<()> {
    check_work(what, needed, 0)
}

/// [`check_memory`] for work that also starts `spawned` threads of its own
/// beside the pool's (a streamed conversion's decoding and fitting
/// stages).
pub(crate) fn check_work(what: &str, needed: u64, spawned: usize) -> Result<()> {
    // The limits first: without one, /proc is not read.
    let (address_space, data) = (limits::address_space(), limits::data());
    if address_space.is_none() && data.is_none() {
        return Ok(());
    }
    let Ok(status) = std::fs::read_to_string("/proc/self/status") else { return Ok(()) };
    let Some((room, limit)) = room_in(&status, address_space, data) else { return Ok(()) };
    let threads = new_threads(crate::par::current_num_threads(), spawned);
    let overhead = threads.saturating_mul(HEAP + STACK);
    let wanted = needed.saturating_add(SLACK).saturating_add(overhead);
    if wanted <= room {
        return Ok(());
    }
    Err(Error::Limits(format!(
        "{what} needs about {} MiB of memory, but the process may take only {} MiB more (its memory limit is {} MiB)",
        mib(wanted),
        mib(room),
        mib(limit)
    )))
}

/// The tighter of the process's soft memory limits (address space, data),
/// `None` when neither is set or they cannot be read (not Unix). Work
/// under a limit is checked by [`check_memory`]; a program may also do
/// less at once under one (the command line's batches take one file at a
/// time by default).
pub fn memory_limit() -> Option<u64> {
    [limits::address_space(), limits::data()].into_iter().flatten().min()
}

/// The sizes of the thread pools the rule has seen.
static POOLS_SEEN: Mutex<Vec<usize>> = Mutex::new(Vec::new());

/// The threads the work starts, each of which may take an arena of its
/// own: `spawned`, and the `pool`'s threads the first time a pool of that
/// size is seen (rayon starts its threads with the pool, and each takes
/// its arena as it starts; an arena outlives its thread, and is handed to
/// the next new one). Pools are told apart by their size alone: a second
/// pool of a size seen is taken for the first.
fn new_threads(pool: usize, spawned: usize) -> u64 {
    let first_sight = match POOLS_SEEN.lock() {
        Ok(mut seen) if !seen.contains(&pool) => {
            seen.push(pool);
            true
        }
        Ok(_) => false,
        // Poisoned: every pool counts.
        Err(_) => true,
    };
    (spawned + if first_sight { pool } else { 0 }) as u64
}

/// `bytes` a thread holds in buffers small enough for its arena's heaps
/// (below glibc's threshold for a mapping of their own, at most 32 MiB: a
/// fit's sums, rows of scratch), with what the heaps may leave unused: the
/// last one reserved, up to 64 MiB, and no more than the bytes themselves.
pub(crate) fn in_heaps(bytes: u64) -> u64 {
    bytes.saturating_add(bytes.min(HEAP))
}

/// The bytes the process may still map and the limit that bounds them,
/// from the text of `/proc/self/status` and the soft limits: the tighter
/// of address space and data; `None` when neither is limited or the use
/// cannot be read.
fn room_in(status: &str, address_space: Option<u64>, data: Option<u64>) -> Option<(u64, u64)> {
    [(address_space, "VmSize:"), (data, "VmData:")]
        .into_iter()
        .filter_map(|(limit, field)| {
            let limit = limit?;
            let used = kib_field(status, field)?.saturating_mul(1024);
            Some((limit.saturating_sub(used), limit))
        })
        .min()
}

/// A `Field:   123 kB` line of `/proc/self/status`, in KiB.
fn kib_field(status: &str, field: &str) -> Option<u64> {
    let line = status.lines().find(|l| l.starts_with(field))?;
    line[field.len()..].trim().trim_end_matches("kB").trim().parse().ok()
}

/// Bytes to whole MiB, for messages.
fn mib(bytes: u64) -> u64 {
    bytes >> 20
}

/// The soft limits, `None` when unlimited.
#[cfg(unix)]
mod limits {
    use rustix::process::{Resource, getrlimit};

    pub(super) fn address_space() -> Option<u64> {
        getrlimit(Resource::As).current
    }

    pub(super) fn data() -> Option<u64> {
        getrlimit(Resource::Data).current
    }
}

#[cfg(not(unix))]
mod limits {
    pub(super) fn address_space() -> Option<u64> {
        None
    }

    pub(super) fn data() -> Option<u64> {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_a_status_field() {
        let status = "Name:\tx\nVmPeak:\t  9000 kB\nVmSize:\t    3060 kB\nVmData:\t 360 kB\n";
        assert_eq!(kib_field(status, "VmSize:"), Some(3060));
        assert_eq!(kib_field(status, "VmData:"), Some(360));
        assert_eq!(kib_field(status, "VmSwap:"), None);
    }

    #[test]
    fn the_threads_a_job_starts_count_once() {
        // A pool is counted the first time it is seen; threads the work
        // spawns itself, every time. (Sizes no other test uses.)
        assert_eq!(new_threads(1001, 0), 1001);
        assert_eq!(new_threads(1001, 2), 2);
        assert_eq!(new_threads(1002, 2), 1004);
        // Buffers in the heaps may leave up to 64 MiB of the last unused.
        let mib = 1u64 << 20;
        assert_eq!(in_heaps(10 * mib), 20 * mib);
        assert_eq!(in_heaps(1000 * mib), 1064 * mib);
    }

    #[test]
    fn the_room_is_the_tighter_limit_less_the_use() {
        let status = "VmSize:\t 102400 kB\nVmData:\t 10240 kB\n";
        let gib = 1u64 << 30;
        assert_eq!(room_in(status, None, None), None, "no limit, nothing to check");
        assert_eq!(room_in(status, Some(gib), None), Some((gib - (100 << 20), gib)));
        assert_eq!(room_in(status, None, Some(gib)), Some((gib - (10 << 20), gib)));
        assert_eq!(room_in(status, Some(gib), Some(gib)), Some((gib - (100 << 20), gib)), "address space is tighter");
        assert_eq!(room_in(status, Some(50 << 20), None), Some((0, 50 << 20)), "over the limit: no room");
        assert_eq!(room_in("", Some(gib), None), None, "use unknown");
    }
}
