//! Whether a decode fits in the memory the process may still take.
//!
//! Under a memory limit (`ulimit -v`, `prlimit --as`, `ulimit -d`) an
//! allocation that does not fit fails, and a failed allocation inside a
//! dependency (the `exr` crate allocates its sample buffers itself) ends the
//! process with an abort that no `Result` can catch. So a whole-image
//! decode first estimates, from the header, the bytes it will hold, and is
//! refused with [`Error::Limits`] when they exceed the room left under the
//! limits ([`check_memory`], which the command line also calls before a
//! whole-image encode). The buffers normalfit allocates itself are reserved
//! fallibly (`try_reserve`) besides, so an estimate that falls short still
//! ends in an error, not an abort.
//!
//! The room is the soft limit on address space (RLIMIT_AS) less what the
//! process has mapped (`VmSize` in `/proc/self/status`), and likewise for
//! the data limit (RLIMIT_DATA, `VmData`). Without a limit, or where these
//! cannot be read (not Linux), there is nothing to check.

use exr::meta::attribute::SampleType;

use crate::error::{Error, Result};

/// Headroom above an estimate for the decoder's own buffers, threads and
/// stacks, which the estimate does not count.
const SLACK: u64 = 64 << 20;

/// Refuses work that needs about `needed` more bytes of memory than the
/// process's memory limits leave, keeping 64 MiB besides for the buffers
/// of the libraries doing the work, whose failure to allocate would abort
/// the process. `what` names the work in the message ("decoding"). `Ok`
/// when no limit is set, or where the use cannot be read (not Linux).
///
/// The limits are the soft limits on address space (RLIMIT_AS: `ulimit
/// -v`, `prlimit --as`) and data (RLIMIT_DATA: `ulimit -d`); the use is
/// what the process has mapped (`VmSize`, `VmData` in `/proc/self/status`).
///
/// Errors: [`Error::Limits`], saying how much is needed and how much is
/// left.
pub fn check_memory(what: &str, needed: u64) -> Result<()> {
    let Some((room, limit)) = room() else { return Ok(()) };
    let wanted = needed.saturating_add(SLACK);
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

/// The bytes the process may still map and the limit that bounds them,
/// the tighter of address space and data; `None` when neither is limited
/// or the use cannot be read.
fn room() -> Option<(u64, u64)> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    room_in(&status, limits::address_space(), limits::data())
}

/// [`room`] from the text of `/proc/self/status` and the two limits.
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

/// The bytes the `exr` crate holds for a whole-image read of the part
/// `header` describes (every channel at full resolution, as stored), plus
/// one converted `f32` plane for half or u32 channels.
pub(crate) fn exr_decode_bytes(header: &exr::meta::header::Header) -> u64 {
    let texels = (header.layer_size.0 as u64).saturating_mul(header.layer_size.1 as u64);
    let stored: u64 = header
        .channels
        .list
        .iter()
        .map(|c| texels.saturating_mul(c.sample_type.bytes_per_sample() as u64))
        .fold(0, u64::saturating_add);
    let all_f32 = header.channels.list.iter().all(|c| c.sample_type == SampleType::F32);
    let converted = if all_f32 { 0 } else { texels.saturating_mul(4) };
    stored.saturating_add(converted)
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
