//! Where each input's output goes, for the commands that write one file
//! per input (`convert`, `shade`, `height`), the rule that no output
//! replaces an input or an earlier output of the same run, and the
//! library's [`Output`] of a job: a file, or standard output.

use std::collections::HashSet;
use std::io::StdoutLock;
use std::path::{Path, PathBuf};

use normalfit::convert::{ConvertError, Output, Place};

use super::input::{Input, refuse_overwrite};
use super::report::Failure;

/// How messages name standard output.
pub const STDOUT: &str = "<standard output>";

/// Where outputs go, from `-o`.
pub enum Destination {
    /// A name made from the input's stem beside each input (standard output
    /// for standard input).
    BesideInputs,
    /// This exact file (one input only).
    File(PathBuf),
    /// A name made from the input's stem in this folder.
    Folder(PathBuf),
    /// Standard output (one input only).
    Stdout,
}

impl Destination {
    /// Reads `-o`, `many` saying whether the run has more than one input
    /// (or a folder of them): `-` is standard output (one input only);
    /// with many inputs, naming a folder, or ending in a slash, it is a
    /// folder, made if missing; else a file.
    pub fn for_batch(output: Option<&Path>, many: bool) -> Result<Destination, Failure> {
        let destination = match output {
            None => Destination::BesideInputs,
            Some(o) if o.as_os_str() == "-" => {
                if many {
                    return Err(Failure::usage("'-o -' takes one input: many images cannot share standard output"));
                }
                Destination::Stdout
            }
            // A trailing slash says "folder" even before the folder exists.
            Some(o) if many || o.is_dir() || o.to_string_lossy().ends_with(std::path::is_separator) => {
                Destination::Folder(o.to_path_buf())
            }
            Some(o) => Destination::File(o.to_path_buf()),
        };
        if let Destination::Folder(dir) = &destination {
            if dir.exists() && !dir.is_dir() {
                return Err(Failure::file(dir, "is not a folder: with many inputs, -o names the output folder"));
            }
            std::fs::create_dir_all(dir)
                .map_err(|e| Failure::file(dir, format!("cannot create the output folder: {e}")))?;
        }
        Ok(destination)
    }

    /// The output of `input`, found in `subfolder` of a folder named as
    /// input (empty for a file named directly), `file_name` being its name
    /// when the destination makes one (beside the input, or in an output
    /// folder, under the same subfolder); `None` is standard output.
    pub fn path_in(&self, input: &Input, subfolder: &Path, file_name: &str) -> Option<PathBuf> {
        match self {
            Destination::Stdout => None,
            Destination::BesideInputs => match input {
                Input::Stdin => None,
                Input::File(p) => Some(p.parent().unwrap_or(Path::new("")).join(file_name)),
            },
            Destination::File(p) => Some(p.clone()),
            Destination::Folder(dir) => Some(dir.join(subfolder).join(file_name)),
        }
    }
}

/// Refuses `output` (of `input`) if it is an input, or if an earlier input
/// of this run already wrote it (`written` keeps their absolute paths).
pub fn claim(
    output: &Path,
    input: &Input,
    ids: &normalfit::io::Inputs,
    written: &mut HashSet<PathBuf>,
) -> Result<(), Failure> {
    refuse_overwrite(ids, output)?;
    let key = std::path::absolute(output).unwrap_or_else(|_| output.to_path_buf());
    if !written.insert(key) {
        return Err(Failure::file(
            output,
            format!(
                "is the output of an earlier input of this run, so {} is skipped; give the inputs distinct names or separate -o folders",
                input.name().display()
            ),
        ));
    }
    Ok(())
}

/// The file `path`, an output of an input found in `subfolder` of a folder
/// named as input (empty for a file named directly): the folder is made
/// when there is a subfolder (under `-o DIR`, it may not exist yet).
pub fn file<'a>(path: &'a Path, subfolder: &Path) -> Output<'a> {
    Output::File { path, create_folder: !subfolder.as_os_str().is_empty() }
}

/// The output at `target`: that [`file`], or standard output (`None`),
/// locked into `stdout` so that only the job that writes there holds it.
pub fn file_or_stdout<'a>(
    target: Option<&'a Path>,
    subfolder: &Path,
    stdout: &'a mut Option<StdoutLock<'static>>,
) -> Output<'a> {
    match target {
        Some(path) => file(path, subfolder),
        None => Output::Writer(stdout.insert(std::io::stdout().lock())),
    }
}

/// How messages name the output at `target`: the file, or standard output.
pub fn name(target: Option<&Path>) -> &Path {
    target.unwrap_or(Path::new(STDOUT))
}

/// Whether `e` is a write into standard output (`to_stdout`) whose reader
/// has gone (`| head -c4`): no failure, the run stops
/// ([`Outcome::PipeClosed`](super::batch::Outcome::PipeClosed)).
pub fn stdout_closed(e: &ConvertError, to_stdout: bool) -> bool {
    to_stdout
        && e.place == Place::Output
        && matches!(&e.error, normalfit::Error::Io(io) if io.kind() == std::io::ErrorKind::BrokenPipe)
}
