//! How the program speaks: every error is one line on standard error,
//! `normalfit: <file>: <problem>`, and ends in exit code 2.

use std::fmt::Display;
use std::path::Path;

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
            Some(s) => eprintln!("normalfit: {s}: {}", self.message),
            None => eprintln!("normalfit: {}", self.message),
        }
    }
}

/// A warning: the work goes on.
pub fn warn(subject: impl Display, message: impl Display) {
    eprintln!("normalfit: warning: {subject}: {message}");
}

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}
