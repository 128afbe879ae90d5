//! Where an output path leads: symbolic links followed to the file they
//! name, and outputs that are not files (a device such as `/dev/null` or
//! `/dev/stdout`'s terminal, a FIFO, a socket) told from those that are.
//!
//! A file (or a name where none is yet) is replaced atomically
//! ([`super::write_file_atomically`]): a new file takes its name once
//! complete. Done to a link, that would put a file where the link was and
//! leave the file it named untouched; done to a device, it would replace
//! the device itself (as root, `-o /dev/null` would leave a regular file
//! at /dev/null). So a link is followed, and the link stays; what is not a
//! file is written into as a stream, which no rename can make atomic.

use std::fs::{self, File, OpenOptions};
use std::io;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Where an output path leads, links followed.
#[derive(Debug, PartialEq, Eq)]
pub enum OutputTarget {
    /// A regular file, or no file yet (then it is created), at this path:
    /// replaced atomically. Also a folder, which creating the file refuses.
    File(PathBuf),
    /// A character or block device, a FIFO or a socket at this path:
    /// written into directly (no temporary file, no rename), so the
    /// promise that an output appears whole or not at all does not hold.
    Stream(PathBuf),
}

/// Links followed before giving up, as Linux's `ELOOP` does (40).
const MAX_LINKS: usize = 40;

/// Where `path` leads. An existing file is asked of the system through
/// any links (so `/dev/stdout`, a link through `/proc/self/fd` to a pipe
/// or a terminal, is a stream): a device, FIFO or socket is a
/// [`OutputTarget::Stream`] at `path`, a file a [`OutputTarget::File`] at
/// its own name, links resolved. Where no file is there yet, each link of
/// a chain is replaced by the name it holds (a relative name taken from
/// the link's folder), down to the name to create.
///
/// Errors: [`Error::Io`] for a loop of links or a link that cannot be
/// read, naming `path`.
pub fn output_target(path: &Path) -> Result<OutputTarget> {
    if let Ok(meta) = fs::metadata(path) {
        if is_stream(&meta) {
            return Ok(OutputTarget::Stream(path.to_path_buf()));
        }
        let is_link = fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink());
        return match is_link {
            true => fs::canonicalize(path).map(OutputTarget::File).map_err(|e| link_error(path, e)),
            false => Ok(OutputTarget::File(path.to_path_buf())),
        };
    }
    let mut target = path.to_path_buf();
    for _ in 0..=MAX_LINKS {
        match fs::symlink_metadata(&target) {
            Ok(meta) if meta.file_type().is_symlink() => {
                let named = fs::read_link(&target).map_err(|e| link_error(path, e))?;
                target = match target.parent() {
                    Some(folder) => folder.join(named),
                    None => named,
                };
            }
            // No file (or a folder on the way that cannot be read: creating
            // the file there says so, with the folder named).
            _ => return Ok(OutputTarget::File(target)),
        }
    }
    Err(link_error(path, io::Error::other(format!("more than {MAX_LINKS} symbolic links in a row (a loop?)"))))
}

/// Whether the file is a device, a FIFO or a socket.
fn is_stream(meta: &fs::Metadata) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let kind = meta.file_type();
        kind.is_char_device() || kind.is_block_device() || kind.is_fifo() || kind.is_socket()
    }
    #[cfg(not(unix))]
    {
        let _ = meta;
        false
    }
}

/// Opens a [`OutputTarget::Stream`] for writing: a device or FIFO opened
/// as it is (not truncated: that means nothing to them), a Unix socket
/// connected to.
///
/// Errors: [`Error::Io`], naming the path.
pub fn open_stream(path: &Path) -> Result<File> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if fs::metadata(path).is_ok_and(|m| m.file_type().is_socket()) {
            let stream = std::os::unix::net::UnixStream::connect(path).map_err(|e| opening(path, e))?;
            return Ok(File::from(std::os::fd::OwnedFd::from(stream)));
        }
    }
    OpenOptions::new().write(true).open(path).map_err(|e| opening(path, e))
}

fn opening(path: &Path, e: io::Error) -> Error {
    Error::Io(io::Error::new(e.kind(), format!("cannot open {} for writing: {e}", path.display())))
}

fn link_error(path: &Path, e: io::Error) -> Error {
    Error::Io(io::Error::new(e.kind(), format!("cannot follow the link {}: {e}", path.display())))
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    #[test]
    fn files_and_missing_names_are_files_and_devices_are_streams() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("a.png");
        fs::write(&file, b"old").unwrap();
        assert_eq!(output_target(&file).unwrap(), OutputTarget::File(file.clone()));
        let missing = dir.path().join("new.png");
        assert_eq!(output_target(&missing).unwrap(), OutputTarget::File(missing.clone()));
        let null = Path::new("/dev/null");
        assert_eq!(output_target(null).unwrap(), OutputTarget::Stream(null.to_path_buf()));
    }

    #[test]
    fn links_are_followed_relative_to_their_folder_and_may_dangle() {
        let dir = tempfile::tempdir().unwrap();
        fs::create_dir(dir.path().join("real")).unwrap();
        let file = dir.path().join("real/a.png");
        fs::write(&file, b"old").unwrap();
        // link → (relative) real/a.png, and a link to that link.
        let link = dir.path().join("link.png");
        std::os::unix::fs::symlink("real/a.png", &link).unwrap();
        let chain = dir.path().join("chain.png");
        std::os::unix::fs::symlink(&link, &chain).unwrap();
        let real = fs::canonicalize(&file).unwrap();
        assert_eq!(output_target(&link).unwrap(), OutputTarget::File(real.clone()));
        assert_eq!(output_target(&chain).unwrap(), OutputTarget::File(real));
        let dangling = dir.path().join("dangling.png");
        std::os::unix::fs::symlink("real/b.png", &dangling).unwrap();
        assert_eq!(output_target(&dangling).unwrap(), OutputTarget::File(dir.path().join("real/b.png")));
        let to_null = dir.path().join("null.png");
        std::os::unix::fs::symlink("/dev/null", &to_null).unwrap();
        // Written through the link, which the system follows when opening it.
        assert_eq!(output_target(&to_null).unwrap(), OutputTarget::Stream(to_null.clone()));
    }

    #[test]
    fn a_loop_of_links_is_an_error_naming_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.png"), dir.path().join("b.png"));
        std::os::unix::fs::symlink(&b, &a).unwrap();
        std::os::unix::fs::symlink(&a, &b).unwrap();
        let message = output_target(&a).unwrap_err().to_string();
        assert!(message.contains("a.png") && message.contains("loop"), "{message}");
    }

    #[test]
    #[cfg(target_os = "linux")]
    fn a_fifo_is_a_stream_that_is_written_into() {
        use std::os::unix::fs::FileTypeExt;
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        rustix::fs::mknodat(
            rustix::fs::CWD,
            &fifo,
            rustix::fs::FileType::Fifo,
            rustix::fs::Mode::RUSR | rustix::fs::Mode::WUSR,
            0,
        )
        .unwrap();
        assert_eq!(output_target(&fifo).unwrap(), OutputTarget::Stream(fifo.clone()));
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || fs::read(fifo).unwrap())
        };
        let mut file = open_stream(&fifo).unwrap();
        io::Write::write_all(&mut file, b"bytes").unwrap();
        drop(file);
        assert_eq!(reader.join().unwrap(), b"bytes");
        assert!(fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo(), "the FIFO stays");
    }
}
