//! Whether two paths name the same file: the rule that keeps an output
//! from replacing an input, whether it is named directly, through a
//! symbolic link or as a hard link.

use std::collections::HashSet;
use std::path::Path;

use crate::error::{Error, Result};

/// What identifies a file: its device and inode on Unix, its canonical
/// path elsewhere.
#[cfg(unix)]
type Id = (u64, u64);
#[cfg(not(unix))]
type Id = std::path::PathBuf;

/// A file's identity: equal for every path that leads to the same file
/// (symbolic links followed, hard links included). For many inputs,
/// keep their identities and compare each output's with them, one
/// `stat` an output instead of one an input.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct FileId(Id);

impl FileId {
    /// The identity of the file at `path`; `None` when there is no file
    /// there to know (it does not exist, or cannot be examined).
    #[must_use]
    pub fn of(path: &Path) -> Option<FileId> {
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            let m = std::fs::metadata(path).ok()?;
            Some(FileId((m.dev(), m.ino())))
        }
        #[cfg(not(unix))]
        {
            std::fs::metadata(path).ok()?;
            std::fs::canonicalize(path).ok().map(FileId)
        }
    }
}

/// Whether `a` and `b` are the same existing file, through links too: an
/// output that is its input. Paths where no file is are never the same.
///
/// ```
/// let dir = std::env::temp_dir();
/// let file = dir.join(format!("normalfit-same-file-doc-{}", std::process::id()));
/// std::fs::write(&file, b"x")?;
/// assert!(normalfit::io::same_file(&file, &dir.join(".").join(file.file_name().unwrap())));
/// assert!(!normalfit::io::same_file(&file, &dir));
/// std::fs::remove_file(&file)?;
/// # Ok::<(), std::io::Error>(())
/// ```
#[must_use]
pub fn same_file(a: &Path, b: &Path) -> bool {
    match (FileId::of(a), FileId::of(b)) {
        (Some(a), Some(b)) => a == b,
        _ => false,
    }
}

/// The files no output may replace: a run's inputs, by identity
/// ([`FileId`]: links and hard links are the file they lead to). The
/// command line gathers its inputs here once; a conversion's
/// [`FileSet`](super::FileSet) refuses each file it would write that is
/// one of them, level by level of a mip chain.
#[derive(Clone, Debug, Default)]
pub struct Inputs(HashSet<FileId>);

impl Inputs {
    /// The identities of the files at `paths` (those that exist).
    #[must_use]
    pub fn of<P: AsRef<Path>>(paths: impl IntoIterator<Item = P>) -> Inputs {
        Inputs(paths.into_iter().filter_map(|p| FileId::of(p.as_ref())).collect())
    }

    /// Whether the file at `path` (followed through links) is one of them.
    #[must_use]
    pub fn contains(&self, path: &Path) -> bool {
        !self.0.is_empty() && FileId::of(path).is_some_and(|id| self.0.contains(&id))
    }

    /// Refuses an output at `path` that is one of them.
    ///
    /// Errors: [`Error::InvalidOption`], saying so.
    pub fn refuse(&self, path: &Path) -> Result<()> {
        if self.contains(path) {
            return Err(Error::InvalidOption(
                "is one of the inputs (or a link to one): normalfit never writes over an input".into(),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn links_are_the_same_file_and_copies_are_not() {
        let dir = tempfile::tempdir().unwrap();
        let (a, copy) = (dir.path().join("a.png"), dir.path().join("copy.png"));
        std::fs::write(&a, b"height").unwrap();
        std::fs::write(&copy, b"height").unwrap();
        assert!(same_file(&a, &a));
        assert!(same_file(&a, &dir.path().join(".").join("a.png")));
        assert!(!same_file(&a, &copy));
        assert_ne!(FileId::of(&a), FileId::of(&copy));
        let missing = dir.path().join("missing.png");
        assert!(!same_file(&missing, &missing), "no file: nothing to write over");
        assert_eq!(FileId::of(&missing), None);
        #[cfg(unix)]
        {
            let (hard, soft) = (dir.path().join("hard.png"), dir.path().join("soft.png"));
            std::fs::hard_link(&a, &hard).unwrap();
            std::os::unix::fs::symlink(&a, &soft).unwrap();
            assert!(same_file(&a, &hard) && same_file(&soft, &a));
            assert_eq!(FileId::of(&hard), FileId::of(&a));
        }
    }
}
