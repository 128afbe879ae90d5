//! Batches: which files the folders named as inputs hold, and converting
//! several files at once with messages and outcomes that do not depend on
//! which finishes first.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex};

use normalfit::io::InputFormat;

use super::input::Input;
use super::report::Failure;

/// The stem ending of residual maps (`--residual` with many inputs).
pub const RESIDUAL_SUFFIX: &str = "_residual";

/// One input of the run and where, under an output folder, its outputs go.
pub struct Job {
    pub input: Input,
    /// The input's folder relative to the folder named on the command line
    /// (empty for files named directly): under `-o DIR`, outputs keep it.
    pub subfolder: PathBuf,
}

/// The inputs of a run, in order.
pub struct Listing {
    pub jobs: Vec<Job>,
    /// Folders that could not be listed.
    pub failures: Vec<Failure>,
    /// Folders named on the command line in which no image was found.
    pub empty_folders: Vec<PathBuf>,
    /// Whether a folder was named: the outputs then go into a folder too.
    pub any_folder: bool,
}

/// Expands the command line's inputs: files (and `-`) as they are; a
/// folder, into the image files it holds (with `recursive`, in its
/// subfolders too), sorted by name. Searching skips hidden files and
/// folders (names starting with `.`), files whose stem ends in `suffix`
/// or in `_residual` (outputs of an earlier run), and symbolic links to
/// folders, so a link loop cannot trap it.
pub fn gather(args: &[PathBuf], recursive: bool, suffix: &str) -> Listing {
    let mut listing = Listing { jobs: Vec::new(), failures: Vec::new(), empty_folders: Vec::new(), any_folder: false };
    for arg in args {
        let input = Input::from_arg(arg);
        if matches!(input, Input::File(_)) && arg.is_dir() {
            listing.any_folder = true;
            let before = listing.jobs.len();
            walk(arg, arg, recursive, suffix, &mut listing);
            if listing.jobs.len() == before {
                listing.empty_folders.push(arg.clone());
            }
        } else {
            listing.jobs.push(Job { input, subfolder: PathBuf::new() });
        }
    }
    listing
}

fn walk(root: &Path, dir: &Path, recursive: bool, suffix: &str, listing: &mut Listing) {
    let entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) => {
            listing.failures.push(Failure::file(dir, format!("cannot list the folder: {e}")));
            return;
        }
    };
    let mut entries: Vec<_> = entries
        .filter_map(|entry| {
            entry.map_err(|e| listing.failures.push(Failure::file(dir, format!("cannot list the folder: {e}")))).ok()
        })
        .collect();
    entries.sort_by_key(|e| e.file_name());
    for entry in entries {
        let name = entry.file_name();
        if name.as_encoded_bytes().starts_with(b".") {
            continue;
        }
        let path = entry.path();
        // The entry itself: a symbolic link is not followed here.
        let Ok(kind) = entry.file_type() else { continue };
        if kind.is_dir() {
            if recursive {
                walk(root, &path, recursive, suffix, listing);
            }
        } else if kind.is_symlink() && path.is_dir() {
            // Not followed: a link to a folder above would loop.
        } else if is_input_name(&path, suffix) {
            let subfolder = dir.strip_prefix(root).map(Path::to_path_buf).unwrap_or_default();
            listing.jobs.push(Job { input: Input::File(path), subfolder });
        }
    }
}

/// Whether a file found in a folder is an input: an extension of a format
/// the reader takes (the library's registry of formats), and not one of
/// our outputs. Only a folder's search goes by name; a file named on the
/// command line is read whatever its name, by content.
fn is_input_name(path: &Path, suffix: &str) -> bool {
    let ext = path.extension().and_then(OsStr::to_str);
    if ext.and_then(InputFormat::from_extension).is_none() {
        return false;
    }
    let stem = path.file_stem().map(|s| s.to_string_lossy()).unwrap_or_default();
    let ours = (!suffix.is_empty() && stem.ends_with(suffix)) || stem.ends_with(RESIDUAL_SUFFIX);
    !ours
}

/// Runs `work` on jobs 0 … count − 1, `workers` at a time (taken in order),
/// and returns the results in job order.
pub fn run_jobs<T: Send>(count: usize, workers: usize, work: impl Fn(usize) -> T + Sync) -> Vec<T> {
    let workers = workers.clamp(1, count.max(1));
    if workers == 1 {
        return (0..count).map(work).collect();
    }
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<T>>> = Mutex::new((0..count).map(|_| None).collect());
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| {
                loop {
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    if k >= count {
                        break;
                    }
                    let result = work(k);
                    results.lock().unwrap_or_else(|e| e.into_inner())[k] = Some(result);
                }
            });
        }
    });
    let results = results.into_inner().unwrap_or_else(|e| e.into_inner());
    results.into_iter().map(|r| r.expect("every job ran")).collect()
}

/// Makes jobs claim their output names in job order, whatever order they
/// reach that point in: with files converted at once, two inputs that
/// would write the same output then still see the first one win, as in a
/// run of one file at a time. Each job waits for its turn just before it
/// claims, and passes the turn on right after (or when it ends early).
pub struct ClaimOrder {
    /// Which jobs have passed their turn on, and the first that has not.
    state: Mutex<(Vec<bool>, usize)>,
    turn: Condvar,
}

impl ClaimOrder {
    pub fn new(count: usize) -> ClaimOrder {
        ClaimOrder { state: Mutex::new((vec![false; count], 0)), turn: Condvar::new() }
    }

    /// Blocks until every job before `job` has passed its turn on.
    pub fn wait_turn(&self, job: usize) {
        let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
        while state.1 < job {
            state = self.turn.wait(state).unwrap_or_else(|e| e.into_inner());
        }
    }

    /// Job `job` has claimed its outputs, or will not: later jobs may go
    /// on. Harmless to repeat.
    pub fn pass(&self, job: usize) {
        let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
        let (passed, first_waiting) = &mut *state;
        passed[job] = true;
        while *first_waiting < passed.len() && passed[*first_waiting] {
            *first_waiting += 1;
        }
        self.turn.notify_all();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folder_search_takes_images_by_extension_and_skips_outputs_and_hidden_files() {
        let suffix = "_normal";
        for (name, taken) in [
            ("rock.png", true),
            ("ROCK.PNG", true),
            ("dem.TIF", true),
            ("a.jpeg", true),
            ("h.pgm", true),
            ("h.PPM", true),
            ("sky.hdr", true),
            ("anim.gif", true),
            ("q.qoi", true),
            ("old.tga", true),
            ("photo.webp", true),
            ("notes.txt", false),
            ("rock", false),
            ("rock_normal.png", false),
            ("rock_residual.exr", false),
            ("normal.png", true),
        ] {
            assert_eq!(is_input_name(Path::new(name), suffix), taken, "{name}");
        }
        assert!(is_input_name(Path::new("rock_normal.png"), ""), "an empty suffix marks nothing as ours");
        assert!(is_input_name(Path::new("rock_normal.png"), "_n"));
    }

    #[test]
    fn jobs_return_in_order_whatever_order_they_finish() {
        let out = run_jobs(20, 4, |k| {
            std::thread::sleep(std::time::Duration::from_millis(((20 - k) % 7) as u64));
            k * 10
        });
        assert_eq!(out, (0..20).map(|k| k * 10).collect::<Vec<_>>());
        assert_eq!(run_jobs(0, 3, |k| k), Vec::<usize>::new());
    }

    #[test]
    fn claims_follow_job_order() {
        let order = ClaimOrder::new(6);
        let claimed = Mutex::new(Vec::new());
        run_jobs(6, 3, |k| {
            // Later jobs arrive first.
            std::thread::sleep(std::time::Duration::from_millis((6 - k as u64) * 5));
            order.wait_turn(k);
            claimed.lock().unwrap().push(k);
            order.pass(k);
        });
        assert_eq!(claimed.into_inner().unwrap(), [0, 1, 2, 3, 4, 5]);
    }
}
