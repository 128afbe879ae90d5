//! Running the `normalfit` binary from the integration tests: the helpers
//! the command-line test files share.
// Each test file uses its own subset.
#![allow(dead_code)]

use std::fs;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// The binary under test, as a command to add arguments to.
pub fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_normalfit"))
}

/// Runs the binary with `args` and an empty standard input, capturing its
/// output. A run that takes over a minute (a folder loop, a hang) is
/// killed and fails the test instead of hanging it.
pub fn run(args: &[&str]) -> Output {
    run_command(bin(), args)
}

/// The binary under test with its address space limited to `bytes`
/// (`ulimit -v`, set by sh, which then becomes the binary: the arguments
/// pass through untouched).
pub fn bin_within(bytes: u64) -> Command {
    let mut command = Command::new("sh");
    command.arg("-c").arg(format!("ulimit -v {} && exec \"$0\" \"$@\"", bytes / 1024));
    command.arg(env!("CARGO_BIN_EXE_normalfit"));
    command
}

/// [`run`] with the address space limited to `bytes` ([`bin_within`]).
pub fn run_within(bytes: u64, args: &[&str]) -> Output {
    run_command(bin_within(bytes), args)
}

fn run_command(mut command: Command, args: &[&str]) -> Output {
    let mut child = command
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary starts");
    // Read while it runs, so a large output cannot fill the pipes and stall it.
    let (stdout, stderr) = (child.stdout.take().unwrap(), child.stderr.take().unwrap());
    let read = |mut pipe: Box<dyn std::io::Read + Send>| {
        std::thread::spawn(move || {
            let mut bytes = Vec::new();
            std::io::Read::read_to_end(&mut pipe, &mut bytes).map(|_| bytes)
        })
    };
    let (stdout, stderr) = (read(Box::new(stdout)), read(Box::new(stderr)));
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if started.elapsed() > Duration::from_secs(60) {
            child.kill().unwrap();
            panic!("normalfit {args:?} still runs after a minute");
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    Output { status, stdout: stdout.join().unwrap().unwrap(), stderr: stderr.join().unwrap().unwrap() }
}

/// A path as the `&str` an argument list takes.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Whether a line of standard error is a batch's summary line,
/// `normalfit: C converted, S skipped, F failed in T s` (`shaded`,
/// `checked` for `shade` and `tiling`).
pub fn is_summary(line: &str) -> bool {
    summary_counts(line).is_some()
}

/// The counts (done, skipped, failed) of a summary line, and the word
/// saying what done is.
pub fn summary_counts(line: &str) -> Option<(&str, usize, usize, usize)> {
    let words: Vec<&str> = line.split(' ').collect();
    match words[..] {
        ["normalfit:", a, verb @ ("converted," | "shaded," | "checked,"), b, "skipped,", c, "failed", "in", t, "s"]
            if t.parse::<f64>().is_ok() =>
        {
            Some((verb.trim_end_matches(','), a.parse().ok()?, b.parse().ok()?, c.parse().ok()?))
        }
        _ => None,
    }
}

/// The names in a folder, sorted.
pub fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> =
        fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    names
}
