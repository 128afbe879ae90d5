//! The command-line program: argument parsing and printing only. All the
//! work is the library's.

pub mod args;
pub mod batch;
pub mod blend;
pub mod check;
pub mod completions;
pub mod convert;
pub mod fitting;
pub mod heaps;
pub mod height;
pub mod input;
pub mod man;
pub mod output;
pub mod progress;
pub mod report;
pub mod shade;
pub mod tiling;

use std::process::ExitCode;

use clap::Parser;

use args::{Cli, Command};
use report::Failure;

/// Exit codes, as grep: 0 success, 1 a seam found (`tiling`) or a finding
/// (`check`), 2 error.
pub mod exit {
    pub const OK: u8 = 0;
    pub const SEAM: u8 = 1;
    pub const ERROR: u8 = 2;

    /// A batch's code: 2 when any file failed, else 1 when any file had a
    /// seam or a finding, else 0.
    pub fn of_batch(errors: usize, findings: usize) -> u8 {
        if errors > 0 {
            ERROR
        } else if findings > 0 {
            SEAM
        } else {
            OK
        }
    }
}

/// Parses the arguments, runs the command, and maps the outcome to an exit code.
pub fn main() -> ExitCode {
    heaps::share_under_a_limit();
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) if !e.use_stderr() => {
            // --help and --version: print as clap formats them.
            let _ = e.print();
            return ExitCode::from(exit::OK);
        }
        Err(e) => {
            Failure::usage(clap_one_line(&e)).report();
            return ExitCode::from(exit::ERROR);
        }
    };
    let all_written = |failures: usize| if failures == 0 { exit::OK } else { exit::ERROR };
    let outcome = match cli.command {
        Command::Convert(args) => convert::run(args).map(all_written),
        Command::Tiling(args) => tiling::run(args),
        Command::Shade(args) => shade::run(args).map(all_written),
        Command::Height(args) => height::run(&args).map(all_written),
        Command::Blend(args) => blend::run(&args).map(|()| exit::OK),
        Command::Check(args) => check::run(&args),
        Command::Completions(args) => completions::run(&args).map(|()| exit::OK),
        Command::Man(args) => man::run(&args).map(|()| exit::OK),
    };
    match outcome {
        Ok(code) => ExitCode::from(code),
        Err(f) => {
            f.report();
            ExitCode::from(exit::ERROR)
        }
    }
}

/// clap's message without its blank lines, usage block and colours.
fn clap_one_line(e: &clap::Error) -> String {
    let text = e.to_string();
    let first = text.lines().find(|l| !l.trim().is_empty()).unwrap_or("invalid arguments");
    let first = first.trim_start_matches("error: ");
    format!("{first} (see 'normalfit --help')")
}
