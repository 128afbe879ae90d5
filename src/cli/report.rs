//! How the program speaks: every error is one line on standard error,
//! `normalfit: <file>: <problem>`, and ends in exit code 2.
//!
//! Every line goes through [`print_line`], which takes the one lock on
//! standard error: lines from files converted at once never mix, and a
//! progress line ([`show_status`]) is cleared before a message and drawn
//! again after it.

use std::fmt::Display;
use std::io::Write;
use std::path::Path;
use std::sync::Mutex;

/// The progress line now on the terminal ("" when none).
static STATUS: Mutex<String> = Mutex::new(String::new());

/// Erases the terminal's current line: back to its start, clear to its end.
const ERASE_LINE: &str = "\r\x1b[2K";

/// Prints one line on standard error, above the progress line if one is shown.
pub fn print_line(line: &str) {
    let status = STATUS.lock().unwrap_or_else(|e| e.into_inner());
    let mut err = std::io::stderr().lock();
    // Standard error may be closed; there is nowhere else to say so.
    if status.is_empty() {
        let _ = writeln!(err, "{line}");
    } else {
        let _ = write!(err, "{ERASE_LINE}{line}\n{status}");
    }
    let _ = err.flush();
}

/// Shows `line` as the progress line (a terminal only), replacing the last;
/// an empty `line` erases it.
pub fn show_status(line: &str) {
    let mut status = STATUS.lock().unwrap_or_else(|e| e.into_inner());
    if status.is_empty() && line.is_empty() {
        return;
    }
    let mut err = std::io::stderr().lock();
    let _ = write!(err, "{ERASE_LINE}{line}");
    let _ = err.flush();
    line.clone_into(&mut status);
}

/// An error to print: what it concerns (a file) and what is wrong.
#[derive(Debug)]
pub struct Failure {
    subject: Option<String>,
    message: String,
}

impl Failure {
    /// A problem with a file.
    pub fn file(path: impl AsRef<Path>, problem: impl Display) -> Failure {
        Failure { subject: Some(path.as_ref().display().to_string()), message: one_line(&problem.to_string()) }
    }

    /// A problem with the arguments themselves.
    pub fn usage(problem: impl Display) -> Failure {
        Failure { subject: None, message: one_line(&problem.to_string()) }
    }

    /// Prints the one line.
    pub fn report(&self) {
        match &self.subject {
            Some(s) => print_line(&format!("normalfit: {s}: {}", self.message)),
            None => print_line(&format!("normalfit: {}", self.message)),
        }
    }
}

/// A warning: the work goes on.
pub fn warn(subject: impl Display, message: impl Display) {
    print_line(&format!("normalfit: warning: {subject}: {message}"));
}

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}
