//! `normalfit completions` and `normalfit man`: made from the same clap
//! definition the program parses with, so they know every command and
//! option. The list of commands is read from `normalfit --help`, so a new
//! command is checked here without editing this file.

use crate::common;

use std::path::Path;
use std::process::{Command, Output};

use common::cli::run;

fn stdout(out: &Output) -> String {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout.clone()).expect("UTF-8 output")
}

/// The commands `normalfit --help` lists, but `help`.
fn commands() -> Vec<String> {
    let help = stdout(&run(&["--help"]));
    let listed: Vec<String> = help
        .lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        // Command lines are indented by two; their wrapped help, deeper.
        .filter(|l| l.starts_with("  ") && !l.starts_with("   "))
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| *c != "help")
        .map(str::to_owned)
        .collect();
    for known in ["convert", "tiling", "shade", "height", "completions", "man"] {
        assert!(listed.iter().any(|c| c == known), "{known} missing from {listed:?}");
    }
    listed
}

#[test]
fn bash_completion_knows_every_command_and_their_options() {
    let script = stdout(&run(&["completions", "bash"]));
    for command in commands() {
        assert!(script.contains(&command), "{command}");
    }
    for option in ["--light", "--tile", "--relief", "--border", "--convention", "--json", "--preview-lit", "--bits"] {
        assert!(script.contains(option), "{option}");
    }
}

/// What bash offers after `words` (the last one being completed), with the
/// script sourced as a user's shell would.
fn bash_offers(script: &Path, words: &[&str]) -> Vec<String> {
    let words_array = words.iter().map(|w| format!("'{w}'")).collect::<Vec<_>>().join(" ");
    let (current, previous) = (words[words.len() - 1], words[words.len() - 2]);
    let program = format!(
        "source '{}'; COMP_WORDS=({words_array}); COMP_CWORD={}; _normalfit normalfit '{current}' '{previous}'; \
         printf '%s\\n' \"${{COMPREPLY[@]}}\"",
        script.display(),
        words.len() - 1
    );
    let out = Command::new("bash").args(["--norc", "-c", &program]).output().expect("bash runs");
    stdout(&out).lines().map(str::to_owned).collect()
}

#[test]
fn bash_completes_commands_options_and_values() {
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("normalfit.bash");
    std::fs::write(&script, stdout(&run(&["completions", "bash"]))).unwrap();
    assert_eq!(bash_offers(&script, &["normalfit", "sh"]), ["shade"]);
    assert_eq!(bash_offers(&script, &["normalfit", "shade", "--li"]), ["--light"]);
    let mut conventions = bash_offers(&script, &["normalfit", "convert", "--convention", ""]);
    conventions.sort();
    assert_eq!(conventions, ["directx", "opengl"]);
}

#[test]
fn every_shell_gets_a_script_and_an_unknown_shell_is_an_error() {
    for shell in ["bash", "zsh", "fish", "elvish", "powershell"] {
        let script = stdout(&run(&["completions", shell]));
        // fish names long options without their dashes (`-l light`).
        assert!(script.contains("normalfit") && script.contains("shade") && script.contains("light"), "{shell}");
    }
    let out = run(&["completions", "tcsh"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("tcsh"), "{err}");
}

/// The text as a reader sees it: roff escapes `-` as `\-` and switches
/// fonts with `\fB` (bold), `\fI` (italic) and `\fR` (roman).
fn unescaped(roff: &str) -> String {
    ["\\fB", "\\fI", "\\fR"].iter().fold(roff.replace("\\-", "-"), |text, font| text.replace(font, ""))
}

#[test]
fn the_manual_has_a_title_and_every_command_with_its_options() {
    let page = stdout(&run(&["man"]));
    assert!(page.lines().any(|l| l.starts_with(".TH normalfit 1")), "{page}");
    let text = unescaped(&page);
    for command in commands() {
        assert!(text.contains(&format!("normalfit-{command}(1)")), "{command} is listed");
        let section = format!(".SH \"NORMALFIT {}\"", command.to_uppercase());
        assert!(text.contains(&section), "{command} has its section");
    }
    // The light's default depends on the input (a GeoTIFF gets the sun):
    // its help says so rather than clap's fixed default.
    assert!(text.contains("--light <AZIMUTH,ELEVATION>") && text.contains("Default: 135,35"), "defaults are shown");
    assert!(text.contains("--azimuth <DEGREES>") && text.contains("--altitude <DEGREES>"));
    assert!(text.contains("--patch <N> [default: 3]"));
    // One title, one preamble: a single page.
    assert_eq!(page.matches(".TH ").count(), 1);
    assert_eq!(page.matches(".ds Aq").count(), 2, "the preamble's two lines, once");
}

#[test]
fn man_out_writes_one_page_per_command() {
    let dir = tempfile::tempdir().unwrap();
    let pages = dir.path().join("man1");
    let out = run(&["man", "--out", pages.to_str().unwrap()]);
    assert!(out.status.success() && out.stdout.is_empty(), "{}", String::from_utf8_lossy(&out.stderr));
    let mut names: Vec<String> =
        std::fs::read_dir(&pages).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    let mut want: Vec<String> = commands().iter().map(|c| format!("normalfit-{c}.1")).collect();
    want.push("normalfit.1".into());
    want.sort();
    assert_eq!(names, want, "no temporary files left either");
    let shade = std::fs::read_to_string(pages.join("normalfit-shade.1")).unwrap();
    assert!(shade.contains(".TH normalfit-shade 1"), "{shade}");
    assert!(unescaped(&shade).contains("--tile"));

    let file = dir.path().join("a-file");
    std::fs::write(&file, "x").unwrap();
    let out = run(&["man", "--out", file.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("a-file"));
}
