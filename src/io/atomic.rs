//! Files that appear whole or not at all (SPEC §4), even when the process
//! is killed while writing them.
//!
//! The target path is never opened: the bytes go to a new file in the same
//! folder (a rename is atomic only within one file system), which is
//! flushed and synced, and only then takes the target's name in one step.
//! Until that step, the old content of the target (or its absence) is what
//! anyone sees.
//!
//! Where the new file lives until then is the part that decides what a
//! kill leaves behind:
//!
//! * **Unnamed** (Linux, on file systems with `O_TMPFILE`: ext4, XFS,
//!   Btrfs, tmpfs, …): the file is created without a name. A process that
//!   dies at any point, even by SIGKILL, which no handler can catch, leaves
//!   nothing: the kernel frees a file that no name and no descriptor holds.
//!   Once it is complete and synced it gets its name with `linkat` through
//!   `/proc/self/fd`: straight as the target when there is none, else as a
//!   temporary name that is then renamed onto the target (there is no
//!   "link and replace" call). Only a kill in the instant between those two
//!   calls leaves a file behind, a complete one under the temporary name.
//! * **Named** (other systems and file systems, or without `/proc`): the
//!   file is created as `.<file name>.<pid>-<counter>.normalfit-tmp`
//!   beside the target and renamed onto it. It is removed on any error and
//!   if the writer panics; a process killed while writing leaves it behind
//!   (the name says what it is).
//!
//! Why not a crate. Measured by SIGKILLing a writer 0.4 s into a 64 MiB
//! write, on this machine's Linux, then completing a write over a 0600
//! file (a scratch program outside the repository):
//! `tempfile`'s `NamedTempFile::persist` left `.tmpXXXXXX` beside the old
//! file, which breaks the promise tests/integration/faults.rs
//! (`a_conversion_killed_mid_write_leaves_the_old_output_and_nothing_else`)
//! proves, and its files are 0600, which tests/integration/io_formats.rs
//! (`write_atomically_gives_ordinary_permissions`) and tests/integration/cli.rs refuse.
//! `atomic-write-file` 0.3 with its `unnamed-tmpfile` feature (O_TMPFILE,
//! as here) left nothing, and new files get 0666 minus the umask: it keeps
//! every promise those tests check. It differs only where no test looks:
//! a replaced file keeps its old mode and owner (0600 stayed 0600; here a
//! replaced output gets an ordinary file's mode, like a new one), and it
//! brings `nix` and `rand`. It was not adopted in this change because its
//! writer is not the `BufWriter<File>` that [`write_file_atomically`]
//! hands out (and the seekable PNG path uses), so the switch changes this
//! public signature; it is the candidate if that signature may change.

use std::ffi::OsStr;
use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use super::identity::Inputs;
use super::target::{OutputTarget, open_stream, output_target};
use crate::error::{Error, Result};

/// Creates `path` with the bytes `write` produces, so that it appears
/// whole or not at all (SPEC §4).
///
/// `path` itself is never opened: the bytes go to a new file in the same
/// folder, which is flushed and synced to disk, then takes `path`'s name in
/// one step (a link or a rename), and the folder is synced. So:
///
/// * whatever fails (a full disk, a read-only or missing folder, an error
///   of `write`, a panic in it), `path` keeps its old content, or stays
///   absent, and no temporary file is left;
/// * on Linux, on file systems that support `O_TMPFILE` (ext4, XFS,
///   Btrfs, tmpfs, …), the new file has no name until it is complete, so a
///   process killed while writing, even by SIGKILL, leaves nothing behind
///   either; elsewhere, the file is named `.<file name>.<pid>-<counter>.normalfit-tmp`
///   while it is written, and a killed process can leave it behind;
/// * the new file gets the permissions of any new file (0666 minus the
///   umask), not the private 0600 of a temp-file crate;
/// * a symbolic link is followed ([`output_target`]): the link stays, and
///   the file it names is replaced as above (or created, for a link that
///   names no file yet);
/// * a device, FIFO or socket (`/dev/null`, `/dev/stdout`, a named pipe)
///   is written into as it is, with no new file and no rename: it is a
///   stream, and the promise of a whole output or none does not apply;
///   `write` gets the opened device, which may not seek.
///
/// Errors: [`Error::Io`], with the folder named when a file cannot be
/// created in it; any error of `write`, as it is.
pub fn write_atomically(path: &Path, write: impl FnOnce(&mut dyn Write) -> Result<()>) -> Result<()> {
    write_file_atomically(path, |out| write(out))
}

/// Like [`write_atomically`], with the new file itself (buffered), for
/// encoders that seek. The same guarantees hold.
pub fn write_file_atomically(path: &Path, write: impl FnOnce(&mut BufWriter<File>) -> Result<()>) -> Result<()> {
    write_in(path, Where::Unnamed, write)
}

/// Where the new file is kept until it is complete.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Where {
    /// Without a name where the system allows, else named.
    Unnamed,
    /// Named, always (what other systems get; for tests).
    #[cfg_attr(not(test), allow(dead_code))]
    Named,
}

/// [`write_file_atomically`], keeping the new file as `place` says.
fn write_in(path: &Path, place: Where, write: impl FnOnce(&mut BufWriter<File>) -> Result<()>) -> Result<()> {
    let mut set = FileSet::new(Replace::Always);
    set.write_in(path, place, write)?;
    set.commit()
}

/// Which existing files a command may replace (the CLI's `--overwrite`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub enum Replace {
    /// Any file.
    #[default]
    Always,
    /// None: a file that exists is kept.
    Never,
    /// Those last changed before this time (the input's): outputs older
    /// than their input.
    OlderThan(std::time::SystemTime),
}

impl Replace {
    /// Whether a file at `path` may be written: always where there is none.
    #[must_use]
    pub fn allows(self, path: &Path) -> bool {
        let changed = || fs::metadata(path).and_then(|m| m.modified());
        match self {
            Replace::Always => true,
            Replace::Never => fs::metadata(path).is_err(),
            Replace::OlderThan(input) => changed().map_or(true, |written| written < input),
        }
    }
}

/// Files that appear together or not at all: a normal map and its
/// residual, an image and its georeferencing sidecars.
///
/// Each file is written as [`write_file_atomically`] writes one (to a new
/// file beside its target, complete and synced before it has a name), but
/// none takes its name until [`FileSet::commit`] names them all. Before
/// that, the old files that will be replaced are kept under temporary
/// names (hard links, else copies), so that if naming one fails, those
/// already named are put back as they were (the old file, or none): every
/// file is new, or every file is as before. Dropped without a commit, the
/// set leaves every target as it was and no temporary file.
///
/// A file is checked against the set's [`Replace`] policy, and against
/// the [`Inputs`] it must keep, before a byte of it is written
/// ([`FileSet::check`]; a command that writes several files checks them
/// all before it starts). A device, FIFO or socket is written into at
/// once (a stream: the promise does not apply to it).
#[derive(Default)]
pub struct FileSet {
    replace: Replace,
    inputs: Arc<Inputs>,
    staged: Vec<Staged>,
}

/// A complete new file of a set, not yet named.
struct Staged {
    target: PathBuf,
    /// Open until named (closed first where it has a temporary name:
    /// some systems, Windows, refuse to rename an open file).
    file: Option<File>,
    /// Its temporary name, or `None` for an unnamed file.
    named: Option<TempName>,
}

impl FileSet {
    /// A set that may replace the files `replace` allows.
    #[must_use]
    pub fn new(replace: Replace) -> FileSet {
        FileSet { replace, inputs: Arc::default(), staged: Vec::new() }
    }

    /// The same set, refusing to write any of `inputs`.
    #[must_use]
    pub fn keeping(mut self, inputs: Arc<Inputs>) -> FileSet {
        self.inputs = inputs;
        self
    }

    /// Whether a file may be written at `path`: not one of the inputs the
    /// set keeps, and a file the policy lets it replace (or none). A
    /// device, FIFO or socket passes: it is written into, not replaced.
    ///
    /// Errors: [`Error::InvalidOption`] for an input, naming `path`;
    /// [`Error::Io`] of kind `AlreadyExists` when the policy keeps an
    /// existing file there; [`Error::Io`] for a link not followed.
    pub fn check(&self, path: &Path) -> Result<()> {
        match output_target(path)? {
            OutputTarget::File(target) => self.check_target(&target),
            OutputTarget::Stream(_) => Ok(()),
        }
    }

    /// [`FileSet::check`] of a file target.
    fn check_target(&self, target: &Path) -> Result<()> {
        if let Err(Error::InvalidOption(problem)) = self.inputs.refuse(target) {
            return Err(Error::InvalidOption(format!("{} {problem}", target.display())));
        }
        if !self.replace.allows(target) {
            let kept = format!("{} exists and is kept (--overwrite): nothing written", target.display());
            return Err(Error::Io(io::Error::new(io::ErrorKind::AlreadyExists, kept)));
        }
        Ok(())
    }

    /// Writes the file at `path` with the bytes `write` produces, to be
    /// named at [`FileSet::commit`].
    ///
    /// Errors: [`Error::Io`] of kind `AlreadyExists` when the policy keeps
    /// an existing file there (nothing written); those of
    /// [`write_file_atomically`].
    pub fn write(&mut self, path: &Path, write: impl FnOnce(&mut BufWriter<File>) -> Result<()>) -> Result<()> {
        self.write_in(path, Where::Unnamed, write)
    }

    /// [`FileSet::write`], keeping the new file as `place` says.
    fn write_in(
        &mut self,
        path: &Path,
        place: Where,
        write: impl FnOnce(&mut BufWriter<File>) -> Result<()>,
    ) -> Result<()> {
        let target = match output_target(path)? {
            OutputTarget::File(target) => target,
            OutputTarget::Stream(target) => return write_stream(&target, write),
        };
        self.check_target(&target)?;
        let name = target
            .file_name()
            .ok_or_else(|| Error::Io(io::Error::new(io::ErrorKind::InvalidInput, "output path has no file name")))?;
        let (file, named) = create(folder_of(&target), name, place)?;
        let write_back = WriteBack::start(&file);
        let mut out = BufWriter::new(file);
        write(&mut out)?;
        let file = out.into_inner().map_err(|e| Error::Io(e.into_error()))?;
        drop(write_back);
        file.sync_all()?;
        self.staged.push(Staged { target, file: Some(file), named });
        Ok(())
    }

    /// Names every file written, together (see [`FileSet`]).
    ///
    /// Errors: [`Error::Io`] when a file cannot be named, or an old file
    /// not kept aside; the targets are then as they were.
    pub fn commit(self) -> Result<()> {
        let several = self.staged.len() > 1;
        // The old files aside first: a failure here has named nothing.
        let mut kept = Vec::with_capacity(self.staged.len());
        for staged in &self.staged {
            kept.push(if several { keep_aside(&staged.target)? } else { None });
        }
        let mut named: Vec<(&Path, Option<TempName>)> = Vec::new();
        let mut failure = None;
        let mut staged = self.staged;
        for (staged, old) in staged.iter_mut().zip(kept) {
            match staged.name() {
                Ok(()) => named.push((staged.target.as_path(), old)),
                Err(e) => {
                    failure = Some(e);
                    break;
                }
            }
        }
        if let Some(e) = failure {
            // Put back what was named: the old file, or none.
            for (target, old) in named {
                match old {
                    Some(old) => {
                        let _ = old.rename_onto(target);
                    }
                    None => {
                        let _ = fs::remove_file(target);
                    }
                }
            }
            return Err(e);
        }
        // The old files' temporary names go as `named` drops.
        drop(named);
        let mut folders: Vec<&Path> = staged.iter().map(|s| folder_of(&s.target)).collect();
        folders.dedup();
        folders.into_iter().for_each(sync_folder);
        Ok(())
    }
}

impl Staged {
    /// Gives the new file its target's name.
    fn name(&mut self) -> Result<()> {
        match (&self.named, &self.file) {
            (Some(temp), _) => {
                self.file = None;
                fs::rename(&temp.path, &self.target).map_err(placing)?;
                // The temporary name is gone with the rename.
                if let Some(temp) = &mut self.named {
                    temp.armed = false;
                }
                Ok(())
            }
            (None, Some(file)) => {
                let name = self.target.file_name().unwrap_or_default();
                name_unnamed(file, folder_of(&self.target), name, &self.target)
            }
            (None, None) => Ok(()),
        }
    }
}

/// Keeps the file at `target` (if any) under a temporary name beside it:
/// a second link, else a copy. `None` where there is no file.
fn keep_aside(target: &Path) -> Result<Option<TempName>> {
    if !fs::symlink_metadata(target).is_ok_and(|m| m.is_file()) {
        return Ok(None);
    }
    let name = target.file_name().unwrap_or_default();
    let path = temp_path(folder_of(target), name);
    let kept = fs::hard_link(target, &path).or_else(|_| fs::copy(target, &path).map(|_| ()));
    kept.map_err(|e| {
        Error::Io(io::Error::new(e.kind(), format!("cannot keep the old {} aside: {e}", target.display())))
    })?;
    Ok(Some(TempName { path, armed: true }))
}

/// Writes into a device, FIFO or socket as it is: nothing to sync or
/// rename.
fn write_stream(path: &Path, write: impl FnOnce(&mut BufWriter<File>) -> Result<()>) -> Result<()> {
    let mut out = BufWriter::new(open_stream(path)?);
    write(&mut out)?;
    out.flush()?;
    Ok(())
}

/// Writes a file's data to disk in the background while it is being
/// written, so the final sync waits only for the last few megabytes:
/// syncing a 23 MB file took 20 ms at the end of a 0.26 s conversion (3 ms
/// with this). It syncs only once [`BYTES`](Self::BYTES) more have been
/// written, so a small file (most of a batch) gets no sync but the final
/// one, and a large one a sync per few megabytes, not a stream of them.
/// Stops (and waits for a sync under way) when dropped; its errors are
/// ignored, since the final sync reports them.
struct WriteBack {
    stop: Option<std::sync::mpsc::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl WriteBack {
    /// How often the file's size is looked at. 20 ms let the syncs fall
    /// a poll's bytes behind: 201 MB float maps were done 5 to 10 ms
    /// later than with 5 ms (three runs each, on ext4).
    const INTERVAL: std::time::Duration = std::time::Duration::from_millis(5);

    /// Bytes written since the last sync that call for the next.
    const BYTES: u64 = 4 << 20;

    /// Starts watching `file`; does nothing if its descriptor cannot be
    /// shared or no thread started.
    fn start(file: &File) -> WriteBack {
        let (stop, stopped) = std::sync::mpsc::channel::<()>();
        let thread = file.try_clone().ok().and_then(|file| {
            std::thread::Builder::new()
                .name("normalfit-write-back".into())
                .spawn(move || {
                    let mut synced = 0;
                    // Woken by the sender's drop, or each interval to look.
                    while let Err(std::sync::mpsc::RecvTimeoutError::Timeout) = stopped.recv_timeout(Self::INTERVAL) {
                        let Ok(size) = file.metadata().map(|m| m.len()) else { return };
                        if size >= synced + Self::BYTES && file.sync_data().is_ok() {
                            synced = size;
                        }
                    }
                })
                .ok()
        });
        WriteBack { stop: Some(stop), thread }
    }
}

impl Drop for WriteBack {
    fn drop(&mut self) {
        drop(self.stop.take());
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// The folder a path's file is in ("." for a bare file name).
fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// A new, empty file in `folder`: unnamed where the system can, else named
/// (and then returned with the guard that removes it).
fn create(folder: &Path, name: &OsStr, place: Where) -> Result<(File, Option<TempName>)> {
    if place == Where::Unnamed
        && let Some(file) = unnamed::create(folder).map_err(|e| creating_in(folder, e))?
    {
        return Ok((file, None));
    }
    let mut last = None;
    for _ in 0..100 {
        let path = temp_path(folder, name);
        match OpenOptions::new().write(true).create_new(true).open(&path) {
            Ok(file) => return Ok((file, Some(TempName { path, armed: true }))),
            // `create_new` never opens an existing file: a name already
            // taken (another process, a leftover) moves on to the next.
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => last = Some(e),
            Err(e) => return Err(creating_in(folder, e)),
        }
    }
    Err(creating_in(folder, last.unwrap_or_else(|| io::Error::from(io::ErrorKind::AlreadyExists))))
}

/// Gives the complete unnamed `file` the name `target`: linked straight
/// there when the name is free, else linked under a temporary name and
/// renamed onto it.
fn name_unnamed(file: &File, folder: &Path, name: &OsStr, target: &Path) -> Result<()> {
    match unnamed::link(file, target) {
        Ok(()) => return Ok(()),
        Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {}
        Err(e) => return Err(placing(e)),
    }
    for _ in 0..100 {
        let path = temp_path(folder, name);
        match unnamed::link(file, &path) {
            Ok(()) => return TempName { path, armed: true }.rename_onto(target),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {}
            Err(e) => return Err(placing(e)),
        }
    }
    Err(placing(io::Error::from(io::ErrorKind::AlreadyExists)))
}

/// Tells temporary names of one process apart.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// `.<name>.<pid>-<counter>.normalfit-tmp` in `folder`: hidden, and saying
/// whose it is.
fn temp_path(folder: &Path, name: &OsStr) -> PathBuf {
    let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
    let mut temp_name = std::ffi::OsString::from(".");
    temp_name.push(name);
    temp_name.push(format!(".{}-{n}.normalfit-tmp", std::process::id()));
    folder.join(temp_name)
}

/// A temporary name that is removed when dropped, unless renamed.
struct TempName {
    path: PathBuf,
    armed: bool,
}

impl TempName {
    /// Renames the file onto `target`; on failure the temporary name goes.
    fn rename_onto(mut self, target: &Path) -> Result<()> {
        fs::rename(&self.path, target).map_err(placing)?;
        self.armed = false;
        Ok(())
    }
}

impl Drop for TempName {
    fn drop(&mut self) {
        if self.armed {
            // Best effort: the original error is the one worth reporting.
            let _ = fs::remove_file(&self.path);
        }
    }
}

/// An error creating a file in `folder`, with the folder named: a missing
/// folder says so, others keep the system's words.
fn creating_in(folder: &Path, e: io::Error) -> Error {
    let message = match e.kind() {
        io::ErrorKind::NotFound => format!("the folder {} does not exist", folder.display()),
        _ => format!("cannot create a file in the folder {}: {e}", folder.display()),
    };
    Error::Io(io::Error::new(e.kind(), message))
}

/// An error putting the complete file in place under its name.
fn placing(e: io::Error) -> Error {
    Error::Io(io::Error::new(e.kind(), format!("cannot put the new file in place: {e}")))
}

/// Syncs `folder`, so the new name itself survives a crash. Best effort:
/// some file systems refuse to open or sync a folder, and the file is
/// already complete either way.
fn sync_folder(folder: &Path) {
    #[cfg(unix)]
    if let Ok(dir) = File::open(folder) {
        let _ = dir.sync_all();
    }
    #[cfg(not(unix))]
    let _ = folder;
}

/// Files without a name, on Linux (`O_TMPFILE`).
#[cfg(any(target_os = "linux", target_os = "android"))]
mod unnamed {
    use std::fs::File;
    use std::io;
    use std::os::fd::AsRawFd;
    use std::path::Path;

    use rustix::fs::{AtFlags, CWD, Mode, OFlags, linkat, openat};
    use rustix::io::Errno;

    /// An unnamed file in `folder`, or `None` where the file system or the
    /// kernel has no `O_TMPFILE` or `/proc` is not there to name it later.
    pub(super) fn create(folder: &Path) -> io::Result<Option<File>> {
        if !Path::new("/proc/self/fd").is_dir() {
            return Ok(None);
        }
        // 0666: the umask applies, as to any new file.
        let flags = OFlags::WRONLY | OFlags::TMPFILE | OFlags::CLOEXEC;
        match openat(CWD, folder, flags, Mode::from_raw_mode(0o666)) {
            Ok(fd) => Ok(Some(File::from(fd))),
            // No O_TMPFILE on this file system (EOPNOTSUPP), or a kernel
            // before 3.11, which sees only O_DIRECTORY in the flags (EISDIR).
            Err(Errno::OPNOTSUPP | Errno::ISDIR | Errno::INVAL) => Ok(None),
            Err(e) => Err(e.into()),
        }
    }

    /// Gives `file` the name `to` (`AlreadyExists` if it is taken). Linking
    /// the `/proc/self/fd` entry with `AT_SYMLINK_FOLLOW` is the way open(2)
    /// documents for unprivileged processes; std's `hard_link` does not
    /// follow it.
    pub(super) fn link(file: &File, to: &Path) -> io::Result<()> {
        let fd = format!("/proc/self/fd/{}", file.as_raw_fd());
        linkat(CWD, fd.as_str(), CWD, to, AtFlags::SYMLINK_FOLLOW).map_err(io::Error::from)
    }
}

/// Elsewhere every new file is named.
#[cfg(not(any(target_os = "linux", target_os = "android")))]
mod unnamed {
    use std::fs::File;
    use std::io;
    use std::path::Path;

    pub(super) fn create(_folder: &Path) -> io::Result<Option<File>> {
        Ok(None)
    }

    pub(super) fn link(_file: &File, _to: &Path) -> io::Result<()> {
        Err(io::Error::from(io::ErrorKind::Unsupported))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn listing(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> =
            fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        names.sort();
        names
    }

    /// Writes `bytes` to `target` as `place` says, and returns what the
    /// folder held while the bytes were being written.
    fn write_seeing(target: &Path, place: Where, bytes: &[u8]) -> Result<Vec<String>> {
        let mut during = Vec::new();
        write_in(target, place, |out| {
            out.write_all(bytes)?;
            out.flush()?;
            during = listing(target.parent().unwrap());
            Ok(())
        })?;
        Ok(during)
    }

    /// Whether this system can keep a new file in `dir` unnamed.
    fn unnamed_here(dir: &Path) -> bool {
        matches!(unnamed::create(dir), Ok(Some(_)))
    }

    /// Linux's temporary folder (tmpfs or ext4) takes `O_TMPFILE`; other
    /// systems name every new file (tested below).
    #[test]
    #[cfg_attr(
        not(any(target_os = "linux", target_os = "android")),
        ignore = "unnamed files are Linux's O_TMPFILE; the named path is tested below"
    )]
    fn a_new_file_has_no_name_until_complete_where_the_system_allows() {
        let dir = tempfile::tempdir().unwrap();
        assert!(unnamed_here(dir.path()), "no O_TMPFILE in {}", dir.path().display());
        let target = dir.path().join("n.png");
        let during = write_seeing(&target, Where::Unnamed, b"first").unwrap();
        assert!(during.is_empty(), "nothing in the folder while writing: {during:?}");
        assert_eq!(fs::read(&target).unwrap(), b"first");
        // Over an existing file: linked under a temporary name, renamed.
        let during = write_seeing(&target, Where::Unnamed, b"second").unwrap();
        assert_eq!(during, ["n.png"], "only the old file while writing");
        assert_eq!(fs::read(&target).unwrap(), b"second");
        assert_eq!(listing(dir.path()), ["n.png"]);
    }

    #[test]
    fn a_named_temporary_file_is_renamed_in_place() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("n.png");
        fs::write(&target, b"old").unwrap();
        let during = write_seeing(&target, Where::Named, b"new").unwrap();
        assert_eq!(during.len(), 2, "{during:?}");
        let temp = during.iter().find(|n| *n != "n.png").unwrap();
        assert!(temp.starts_with(".n.png.") && temp.ends_with(".normalfit-tmp"), "{temp}");
        assert_eq!(fs::read(&target).unwrap(), b"new");
        assert_eq!(listing(dir.path()), ["n.png"]);
    }

    #[test]
    fn a_failed_or_panicking_write_leaves_the_old_file_and_nothing_else() {
        for place in [Where::Unnamed, Where::Named] {
            let dir = tempfile::tempdir().unwrap();
            let target = dir.path().join("n.png");
            fs::write(&target, b"old").unwrap();
            let failed = write_in(&target, place, |out| {
                out.write_all(&[7; 100_000])?;
                Err(Error::Encode("stop".into()))
            });
            assert!(matches!(failed, Err(Error::Encode(_))), "{place:?}: {failed:?}");
            let panicked = std::panic::catch_unwind(|| {
                write_in(&target, place, |out| {
                    out.write_all(&[7; 100_000])?;
                    panic!("the encoder broke");
                })
            });
            assert!(panicked.is_err());
            assert_eq!(fs::read(&target).unwrap(), b"old", "{place:?}");
            assert_eq!(listing(dir.path()), ["n.png"], "{place:?}");
        }
    }

    #[test]
    fn a_folder_in_the_way_or_missing_is_an_error_that_leaves_nothing() {
        for place in [Where::Unnamed, Where::Named] {
            let dir = tempfile::tempdir().unwrap();
            let folder = dir.path().join("n.png");
            fs::create_dir(&folder).unwrap();
            let e = write_seeing(&folder, place, b"new").unwrap_err().to_string();
            assert!(e.contains("cannot put the new file in place"), "{place:?}: {e}");
            assert_eq!(listing(dir.path()), ["n.png"], "{place:?}");
            assert!(folder.is_dir());
            let missing = dir.path().join("nope").join("n.png");
            let e = write_seeing(&missing, place, b"new").unwrap_err().to_string();
            assert!(e.contains("the folder") && e.contains("nope") && e.contains("does not exist"), "{place:?}: {e}");
        }
    }

    /// A file written slowly, megabytes at a time over several of the
    /// write-back's intervals (so it syncs while the writer goes on, also
    /// after a seek back), arrives whole, and the write-back stops with it.
    #[test]
    fn a_large_file_written_slowly_arrives_whole() {
        use std::io::{Seek, SeekFrom};
        for place in [Where::Unnamed, Where::Named] {
            let dir = tempfile::tempdir().unwrap();
            let target = dir.path().join("big.bin");
            let chunk = |k: u8| vec![k; 3 << 20];
            write_in(&target, place, |out| {
                out.write_all(&[0; 16])?;
                for k in 1..=4 {
                    out.write_all(&chunk(k))?;
                    out.flush()?;
                    std::thread::sleep(WriteBack::INTERVAL * 2);
                }
                out.seek(SeekFrom::Start(0))?;
                out.write_all(b"header, at last!")?;
                out.seek(SeekFrom::End(0))?;
                Ok(())
            })
            .unwrap();
            let got = fs::read(&target).unwrap();
            let mut expected = b"header, at last!".to_vec();
            for k in 1..=4 {
                expected.extend(chunk(k));
            }
            assert_eq!(got.len(), expected.len(), "{place:?}");
            assert!(got == expected, "{place:?}: the content differs");
            assert_eq!(listing(dir.path()), ["big.bin"], "{place:?}");
        }
    }

    /// A set's files appear together: none is named before the commit,
    /// all are after it; a file whose naming fails puts back the ones
    /// already named (the old file, or none), whether the new files are
    /// unnamed or named.
    #[test]
    fn a_set_of_files_appears_together_or_not_at_all() {
        for place in [Where::Unnamed, Where::Named] {
            let dir = tempfile::tempdir().unwrap();
            let (image, world, residual) =
                (dir.path().join("n.png"), dir.path().join("n.pgw"), dir.path().join("r.png"));
            fs::write(&image, b"old image").unwrap();
            let mut set = FileSet::new(Replace::Always);
            for (path, bytes) in [(&world, &b"new world"[..]), (&image, b"new image"), (&residual, b"new residual")] {
                set.write_in(path, place, |out| Ok(out.write_all(bytes)?)).unwrap();
            }
            let visible = |names: &[&str]| names.iter().map(|n| (*n).to_string()).collect::<Vec<_>>();
            assert_eq!(listing(dir.path()).iter().filter(|n| !n.starts_with('.')).count(), 1, "{place:?}");
            set.commit().unwrap();
            assert_eq!(listing(dir.path()), visible(&["n.pgw", "n.png", "r.png"]), "{place:?}");
            assert_eq!(fs::read(&image).unwrap(), b"new image");

            // The last file cannot be named (a folder with a file in it
            // took its name after it was written): the others go back.
            let mut set = FileSet::new(Replace::Always);
            for (path, bytes) in
                [(&world, &b"newer world"[..]), (&image, b"newer image"), (&residual, b"newer residual")]
            {
                set.write_in(path, place, |out| Ok(out.write_all(bytes)?)).unwrap();
            }
            fs::remove_file(&residual).unwrap();
            fs::create_dir(&residual).unwrap();
            fs::write(residual.join("keep"), b"").unwrap();
            let e = set.commit().unwrap_err();
            assert!(e.to_string().contains("cannot put the new file in place"), "{e}");
            assert_eq!(fs::read(&world).unwrap(), b"new world", "{place:?}");
            assert_eq!(fs::read(&image).unwrap(), b"new image", "{place:?}");
            assert_eq!(listing(dir.path()), visible(&["n.pgw", "n.png", "r.png"]), "{place:?}: nothing else");

            // Dropped without a commit: nothing changes, nothing is left.
            let mut set = FileSet::new(Replace::Always);
            set.write_in(&image, place, |out| Ok(out.write_all(b"never")?)).unwrap();
            drop(set);
            assert_eq!(fs::read(&image).unwrap(), b"new image", "{place:?}");
            assert_eq!(listing(dir.path()), visible(&["n.pgw", "n.png", "r.png"]), "{place:?}");
        }
    }

    /// The policy is checked before a byte is written: a file it keeps
    /// stops the set, and leaves nothing.
    #[test]
    fn a_set_keeps_the_files_its_policy_keeps() {
        let dir = tempfile::tempdir().unwrap();
        let (old, new) = (dir.path().join("old.pgw"), dir.path().join("new.png"));
        fs::write(&old, b"kept").unwrap();
        let mut set = FileSet::new(Replace::Never);
        set.write(&new, |out| Ok(out.write_all(b"image")?)).unwrap();
        let mut wrote = false;
        let e = set
            .write(&old, |_| {
                wrote = true;
                Ok(())
            })
            .unwrap_err();
        assert!(!wrote, "nothing written for a kept file");
        assert!(e.to_string().contains("old.pgw exists and is kept"), "{e}");
        drop(set);
        assert_eq!(listing(dir.path()), ["old.pgw"]);
        assert_eq!(fs::read(&old).unwrap(), b"kept");

        // Older than a time: a file changed before it may go, one after not.
        let changed = fs::metadata(&old).unwrap().modified().unwrap();
        assert!(!Replace::OlderThan(changed).allows(&old));
        assert!(Replace::OlderThan(changed + std::time::Duration::from_secs(1)).allows(&old));
        assert!(Replace::Never.allows(&new) && Replace::Always.allows(&old));
    }
}
