//! `normalfit man`: manual pages (roff) made from the clap definition, so
//! they list exactly the options the program takes, with their defaults.

use std::io::{self, Write};
use std::path::Path;

use clap::CommandFactory;
use clap_mangen::Man;

use super::args::{Cli, ManArgs};
use super::output::STDOUT;
use super::report::Failure;

/// Prints the whole manual as one page, or writes one page per command into
/// `--out` (`normalfit.1`, `normalfit-convert.1`, …), as packagers install
/// them.
pub fn run(args: &ManArgs) -> Result<(), Failure> {
    let mut cli = Cli::command().disable_help_subcommand(true);
    // Built, the subcommands know their full names ("normalfit-convert").
    cli.build();
    match &args.out {
        None => {
            let page = whole_manual(&cli).map_err(|e| Failure::usage(format!("cannot render the manual: {e}")))?;
            let mut stdout = std::io::stdout().lock();
            stdout.write_all(&page).and_then(|()| stdout.flush()).map_err(|e| Failure::file(STDOUT, e))
        }
        Some(dir) => {
            std::fs::create_dir_all(dir)
                .map_err(|e| Failure::file(dir, format!("cannot create the folder for the pages: {e}")))?;
            write_pages(cli, dir)
        }
    }
}

/// `normalfit.1` with, after its list of commands, a section for each
/// command: its synopsis, description and options, so that one page read
/// with `man -l -` says everything.
fn whole_manual(cli: &clap::Command) -> io::Result<Vec<u8>> {
    let top = Man::new(cli.clone());
    let mut page = Vec::new();
    top.render_title(&mut page)?;
    top.render_name_section(&mut page)?;
    top.render_synopsis_section(&mut page)?;
    top.render_description_section(&mut page)?;
    top.render_options_section(&mut page)?;
    top.render_subcommands_section(&mut page)?;
    for sub in cli.get_subcommands().filter(|s| !s.is_hide_set()) {
        writeln!(page, ".SH \"{} {}\"", cli.get_name().to_uppercase(), sub.get_name().to_uppercase())?;
        let man = Man::new(sub.clone());
        let mut sections = Vec::new();
        man.render_synopsis_section(&mut sections)?;
        man.render_description_section(&mut sections)?;
        man.render_options_section(&mut sections)?;
        // The command's sections become subsections of its own. Lines of
        // text never start with a bare `.` (roff escapes them), so this
        // touches only the macros.
        for line in String::from_utf8_lossy(&sections).lines() {
            let line = line.strip_prefix(".SH ").map_or_else(|| line.to_string(), |heading| format!(".SS {heading}"));
            writeln!(page, "{line}")?;
        }
    }
    top.render_version_section(&mut page)?;
    Ok(once_preamble(&String::from_utf8_lossy(&page)).into_bytes())
}

/// Every render starts with the same two lines defining the `Aq` string;
/// the page needs them once, at its top.
fn once_preamble(roff: &str) -> String {
    let mut seen = Vec::new();
    let mut out = String::with_capacity(roff.len());
    for line in roff.lines() {
        let preamble = line.starts_with(".ie \\n(.g .ds Aq") || line.starts_with(".el .ds Aq");
        if preamble && seen.contains(&line) {
            continue;
        }
        if preamble {
            seen.push(line);
        }
        out.push_str(line);
        out.push('\n');
    }
    out
}

/// Writes the page of `cmd` and of each of its subcommands into `dir`,
/// each file appearing whole or not at all.
fn write_pages(cmd: clap::Command, dir: &Path) -> Result<(), Failure> {
    for sub in cmd.get_subcommands().filter(|s| !s.is_hide_set()) {
        write_pages(sub.clone(), dir)?;
    }
    let man = Man::new(cmd);
    let path = dir.join(man.get_filename());
    let mut page = Vec::new();
    man.render(&mut page).map_err(|e| Failure::file(&path, e))?;
    normalfit::io::write_atomically(&path, |out| Ok(out.write_all(&page)?)).map_err(|e| Failure::file(&path, e))
}
