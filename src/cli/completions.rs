//! `normalfit completions <SHELL>`: a completion script made from the same
//! clap definition the program parses with, so it cannot fall behind.

use std::io::Write;

use clap::CommandFactory;

use super::args::{Cli, CompletionsArgs};
use super::output::STDOUT;
use super::report::Failure;

/// Prints the script for the shell asked for.
pub fn run(args: &CompletionsArgs) -> Result<(), Failure> {
    // Into memory first: the generator panics on a failed write, and a
    // closed pipe must be an error line, not a panic.
    let mut script = Vec::new();
    clap_complete::generate(args.shell, &mut Cli::command(), "normalfit", &mut script);
    let mut stdout = std::io::stdout().lock();
    stdout.write_all(&script).and_then(|()| stdout.flush()).map_err(|e| Failure::file(STDOUT, e))
}
