//! Inputs as the command line names them: files or standard input, and the
//! identities (device, inode) that protect them from being written over.

use std::path::{Path, PathBuf};

use normalfit::convert;
use normalfit::io::{self, Raster, ReadOptions};

use super::args::library_message;
use super::report::Failure;

/// One input: a file, or `-` for standard input.
pub enum Input {
    File(PathBuf),
    Stdin,
}

impl Input {
    pub fn from_arg(arg: &Path) -> Input {
        if arg.as_os_str() == "-" { Input::Stdin } else { Input::File(arg.to_path_buf()) }
    }

    /// How messages name it.
    pub fn name(&self) -> &Path {
        match self {
            Input::File(p) => p,
            Input::Stdin => Path::new("<standard input>"),
        }
    }

    /// The file name without its extension, for `<stem>_normal.<ext>`.
    pub fn stem(&self) -> String {
        match self {
            Input::File(p) => p.file_stem().map_or_else(|| "image".into(), |s| s.to_string_lossy().into_owned()),
            Input::Stdin => "stdin".into(),
        }
    }
}

/// Reads and decodes one input; errors name it.
pub fn read_input(input: &Input, opts: &ReadOptions) -> Result<Raster, Failure> {
    let fail = |e: normalfit::Error| Failure::file(input.name(), e);
    match input {
        Input::File(p) => io::read_path(not_a_folder(p)?, opts).map_err(fail),
        Input::Stdin => io::decode(&read_stdin()?, opts).map_err(fail),
    }
}

/// One input as the library's engine takes it: the file's path, or the
/// bytes of standard input, read whole into `bytes`. A folder is refused.
pub fn source<'a>(input: &'a Input, bytes: &'a mut Vec<u8>) -> Result<convert::Input<'a>, Failure> {
    Ok(match input {
        Input::File(p) => convert::Input::Path(not_a_folder(p)?),
        Input::Stdin => {
            *bytes = read_stdin()?;
            convert::Input::Bytes(bytes)
        }
    })
}

/// `path`, unless it is a folder.
fn not_a_folder(path: &Path) -> Result<&Path, Failure> {
    if path.is_dir() {
        return Err(Failure::file(path, "is a folder, not an image"));
    }
    Ok(path)
}

/// Reads standard input to its end; errors name it.
pub fn read_stdin() -> Result<Vec<u8>, Failure> {
    normalfit::engine::read_all(std::io::stdin().lock()).map_err(|e| Failure::file(Input::Stdin.name(), e))
}

/// Standard input can be read only once.
pub fn stdin_at_most_once(inputs: &[PathBuf]) -> Result<(), Failure> {
    if inputs.iter().filter(|p| p.as_os_str() == "-").count() > 1 {
        return Err(Failure::usage("standard input ('-') can be read only once"));
    }
    Ok(())
}

/// Refuses `output` if it is (or links to) one of the run's `inputs` (the
/// library's rule, [`io::Inputs`], which every conversion applies to each
/// file it writes too), or a folder.
pub fn refuse_overwrite(inputs: &io::Inputs, output: &Path) -> Result<(), Failure> {
    inputs.refuse(output).map_err(|e| Failure::file(output, library_message(&e)))?;
    if output.is_dir() {
        return Err(Failure::file(output, "is a folder: cannot write the output there"));
    }
    Ok(())
}
