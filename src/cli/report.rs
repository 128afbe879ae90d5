//! How the program speaks: every error is one line on standard error,
//! `normalfit: <file>: <problem>`, and ends in exit code 2.
//!
//! Every line goes through [`print_line`], which takes the one lock on
//! standard error: lines from files done at once never mix, and a
//! progress bar ([`super::progress`]) is hidden while a message prints and
//! drawn again after it.

use std::fmt::Display;
use std::io::Write;
use std::path::Path;
use std::sync::Mutex;

use indicatif::ProgressBar;

/// The progress bar now shown on the terminal, if any.
static BAR: Mutex<Option<ProgressBar>> = Mutex::new(None);

/// Prints one line on standard error, above the progress bar if one is shown.
pub fn print_line(line: &str) {
    let bar = BAR.lock().unwrap_or_else(|e| e.into_inner());
    let print = || {
        let mut err = std::io::stderr().lock();
        // Standard error may be closed; there is nowhere else to say so.
        let _ = writeln!(err, "{line}");
        let _ = err.flush();
    };
    match &*bar {
        Some(bar) => bar.suspend(print),
        None => print(),
    }
}

/// The bar that [`print_line`] hides while it prints (None: no bar).
pub fn set_bar(bar: Option<ProgressBar>) {
    *BAR.lock().unwrap_or_else(|e| e.into_inner()) = bar;
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
