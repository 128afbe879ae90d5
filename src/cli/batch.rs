//! The batch driver of every command that takes many files (`convert`,
//! `shade`, `tiling`): which files the folders named as inputs hold, the
//! files done several at once ([`Batch::run`]), the rule that outputs are
//! claimed in the order of the command line, `--overwrite`, the progress
//! bar, one failure not stopping the others, and the summary line. A
//! command supplies only what it does to one file (a closure given a
//! [`Job`] and its [`Turn`]) and what it prints; messages and outcomes do
//! not depend on which file finishes first.

use std::collections::HashSet;
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex};

use normalfit::io::{InputFormat, Inputs, Replace};

use super::args::{BatchArgs, OverwriteArg};
use super::input::Input;
use super::output;
use super::progress::Progress;
use super::report::{Failure, print_line, warn};

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
    let normal_map = |stem: &str| !suffix.is_empty() && stem.ends_with(suffix);
    // A mip chain's levels and roughness, named from a normal map's stem.
    let chain = normalfit::convert::chain_stem(&stem).is_some_and(normal_map);
    let ours = normal_map(&stem) || chain || stem.ends_with(RESIDUAL_SUFFIX);
    !ours
}

/// What became of one file that raised no error.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Outcome {
    /// Done: converted, shaded, checked.
    Done,
    /// Every output exists already and `--overwrite` keeps it.
    Skipped,
    /// The reader of standard output went away (`| head -c4`): the output
    /// it did not want is no error, as for ripgrep and fd, and the files
    /// after this one are not done.
    PipeClosed,
}

/// How a command names its work in the messages of a batch.
pub struct Words {
    /// What the summary calls a file done: "converted", "shaded", "checked".
    pub done: &'static str,
    /// What a folder without images holds none of: "to convert".
    pub purpose: &'static str,
}

/// The files of one run, gathered from the command line, before any is done.
pub struct Batch<'a> {
    listing: Listing,
    settings: &'a BatchArgs,
    words: Words,
    inputs: Arc<Inputs>,
}

impl<'a> Batch<'a> {
    /// Gathers the inputs (folders searched as [`gather`] says, skipping
    /// files whose stem ends in `suffix`, this command's outputs).
    pub fn gather(inputs: &[PathBuf], settings: &'a BatchArgs, suffix: &str, words: Words) -> Batch<'a> {
        let listing = gather(inputs, settings.recursive, suffix);
        let files = listing.jobs.iter().filter_map(|j| match &j.input {
            Input::File(p) => Some(p.as_path()),
            Input::Stdin => None,
        });
        let inputs = Arc::new(Inputs::of(files));
        Batch { listing, settings, words, inputs }
    }

    /// Whether the run has more than one file (or a folder of them): the
    /// outputs then go into folders, and a summary line ends the run.
    /// The files named or found as inputs, which no output may replace
    /// (the library checks every file a job writes against them).
    pub fn inputs(&self) -> Arc<Inputs> {
        self.inputs.clone()
    }

    pub fn many(&self) -> bool {
        self.listing.jobs.len() + self.listing.failures.len() > 1 || self.listing.any_folder
    }

    /// Does `one` to every file, `--jobs` at a time; reports each failure
    /// as one line as soon as it happens, and the summary line at the end
    /// (many files, not `--quiet`). Returns the number of failures (folders
    /// that could not be listed included), all already reported.
    pub fn run(self, one: impl Fn(&Job, &Turn) -> Result<Outcome, Failure> + Sync) -> usize {
        let Batch { listing, settings, words, inputs: self_inputs } = self;
        let many = listing.jobs.len() + listing.failures.len() > 1 || listing.any_folder;
        listing.failures.iter().for_each(Failure::report);
        if !settings.quiet {
            let hint = if settings.recursive { "" } else { " (--recursive searches its subfolders)" };
            for dir in &listing.empty_folders {
                warn(dir.display(), format!("holds no image files {}{hint}", words.purpose));
            }
        }
        let jobs = &listing.jobs;
        let shared = Shared {
            ids: self_inputs,
            claimed: Mutex::new(HashSet::new()),
            claims: ClaimOrder::new(jobs.len()),
            prints: ClaimOrder::new(jobs.len()),
            pipe_closed: AtomicBool::new(false),
            progress: Progress::new(jobs.len(), !settings.quiet),
            overwrite: settings.overwrite,
        };
        let workers = settings.jobs.map_or_else(default_jobs, usize::from);
        let outcomes = run_jobs(jobs.len(), workers, |k| {
            let job = &jobs[k];
            let outcome = if shared.pipe_closed.load(Ordering::Relaxed) {
                Ok(Outcome::PipeClosed)
            } else {
                shared.progress.begin(k, &job.input.name().display().to_string());
                let outcome = one(job, &Turn { k, shared: &shared });
                shared.progress.finish(k);
                outcome
            };
            // A job that ended before its turn lets the next one go on.
            shared.claims.pass(k);
            shared.prints.pass(k);
            match &outcome {
                Err(f) => f.report(),
                Ok(Outcome::PipeClosed) => shared.pipe_closed.store(true, Ordering::Relaxed),
                Ok(_) => {}
            }
            outcome
        });
        shared.progress.close();
        let count = |wanted: Outcome| outcomes.iter().filter(|o| o.as_ref().is_ok_and(|&o| o == wanted)).count();
        let failures = listing.failures.len() + outcomes.iter().filter(|o| o.is_err()).count();
        if many && !settings.quiet {
            print_line(&format!(
                "normalfit: {} {}, {} skipped, {} failed in {:.2} s",
                count(Outcome::Done),
                words.done,
                count(Outcome::Skipped),
                failures,
                shared.progress.elapsed().as_secs_f64()
            ));
        }
        failures
    }
}

/// Files done at once unless `--jobs` says: twice the cores, at most 8.
/// Each file's fit already uses every core, but its decoding, deflate and
/// sync to disk run on one thread or wait: on 2 cores, 200 files of 256²
/// took 1.4 s one at a time, 0.73 s two at a time, 0.55 s four at a time
/// and no less with eight; four 2048² files took the same time either way.
/// The cap bounds memory when files are large. Under a memory limit, one
/// file at a time: each file's work is checked against the memory left
/// when it starts, which files done beside it would then take.
fn default_jobs() -> usize {
    if normalfit::io::memory_limit().is_some() {
        return 1;
    }
    std::thread::available_parallelism().map_or(2, |n| (2 * n.get()).min(8))
}

/// What the files of one run share while they are done at once.
struct Shared {
    /// The inputs' identities, so that no output replaces one.
    ids: Arc<Inputs>,
    /// The outputs claimed so far.
    claimed: Mutex<HashSet<PathBuf>>,
    claims: ClaimOrder,
    /// The order of what jobs print on standard output ([`Turn::in_order`]).
    prints: ClaimOrder,
    pipe_closed: AtomicBool,
    progress: Progress,
    overwrite: OverwriteArg,
}

/// One file's place in the run, given to the command's work on it.
pub struct Turn<'a> {
    k: usize,
    shared: &'a Shared,
}

impl Turn<'_> {
    /// Claims the outputs of `input`: refuses one that is an input of the
    /// run, or that an earlier input (in the order of the command line,
    /// whichever finishes first) writes too.
    pub fn claim(&self, input: &Input, outputs: &[&Path]) -> Result<(), Failure> {
        let shared = self.shared;
        shared.claims.wait_turn(self.k);
        let mut claimed = shared.claimed.lock().unwrap_or_else(|e| e.into_inner());
        for path in outputs {
            output::claim(path, input, &shared.ids, &mut claimed)?;
        }
        drop(claimed);
        shared.claims.pass(self.k);
        Ok(())
    }

    /// Whether `--overwrite` lets the output at `path` (None: standard
    /// output, always written) be written for `input`.
    pub fn wanted(&self, path: Option<&Path>, input: &Input) -> bool {
        path.is_none_or(|path| self.replace(input).allows(path))
    }

    /// The files `--overwrite` lets the outputs of `input` replace: the
    /// library applies it to every file a conversion writes (sidecars
    /// included) before writing any.
    pub fn replace(&self, input: &Input) -> Replace {
        match (self.shared.overwrite, input) {
            (OverwriteArg::Always, _) => Replace::Always,
            (OverwriteArg::Never, _) => Replace::Never,
            (OverwriteArg::Older, Input::File(source)) => match std::fs::metadata(source).and_then(|m| m.modified()) {
                Ok(changed) => Replace::OlderThan(changed),
                // An input without a time: an output is as old as it.
                Err(_) => Replace::Never,
            },
            (OverwriteArg::Older, _) => Replace::Always,
        }
    }

    /// Runs `print` once every earlier file of the run is done, so that
    /// what files print on standard output comes in the order of the
    /// command line whatever order they finish in.
    pub fn in_order<T>(&self, print: impl FnOnce() -> T) -> T {
        self.shared.prints.wait_turn(self.k);
        print()
    }

    /// The file's size, for the progress bar.
    pub fn size(&self, width: usize, height: usize) {
        self.shared.progress.size(self.k, width, height);
    }

    /// One more row of the file went through the fit.
    pub fn row(&self) {
        self.shared.progress.row(self.k);
    }
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
            ("rock_normal_mip3.png", false),
            ("rock_normal_roughness.png", false),
            ("rock_normal_roughness_mip12.exr", false),
            ("rock_mip3.png", true),
            ("rock_normal_mipmap.png", true),
            ("rock_normal_mip0.png", true),
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
