//! The progress bar of a long batch: one line on standard error, drawn by
//! `indicatif` only when standard error is a terminal (a log or a pipe
//! gets none of it), and only for long work: more than one file, or an
//! image of at least [`BIG_IMAGE`] texels. Redrawn at most ten times a
//! second and erased at the end; messages print above it
//! ([`super::report`] suspends it around each line).
//!
//! What is drawn is ours: the files finished plus the fraction of rows of
//! those being converted, so that one big file moves the bar too.

use std::collections::BTreeMap;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use super::report;

/// An image this large (2048²) takes long enough on its own to deserve a bar.
pub const BIG_IMAGE: usize = 1 << 22;

/// Redraws per second, at most.
const REDRAWS_PER_SECOND: u8 = 10;

/// Steps of the bar per file: the rows of files under way move it too.
const STEPS: u64 = 1000;

/// Longest file name shown, in characters (longer ones keep their end).
const NAME_CHARS: usize = 28;

/// Progress over the files of one run, shared by the jobs doing them.
pub struct Progress {
    /// Hidden unless standard error is a terminal and the user did not ask
    /// for quiet.
    bar: ProgressBar,
    started: Instant,
    state: Mutex<State>,
}

struct State {
    total: usize,
    finished: usize,
    /// Files under way, by their place in the run.
    active: BTreeMap<usize, Active>,
    /// Whether the bar was ever shown (a short run shows none).
    shown: bool,
}

struct Active {
    name: String,
    rows: usize,
    height: usize,
    texels: usize,
}

impl Progress {
    /// Progress over `total` files; drawn only if `wanted` and standard
    /// error is a terminal.
    pub fn new(total: usize, wanted: bool) -> Progress {
        let target = if wanted {
            // Hidden by indicatif itself when standard error is no terminal.
            ProgressDrawTarget::stderr_with_hz(REDRAWS_PER_SECOND)
        } else {
            ProgressDrawTarget::hidden()
        };
        let length = (total as u64).saturating_mul(STEPS);
        let style = ProgressStyle::with_template("[{bar:24}] {msg}")
            .map(|s| s.progress_chars("#-"))
            .unwrap_or_else(|_| ProgressStyle::default_bar());
        let bar = ProgressBar::with_draw_target(Some(length), target).with_style(style);
        if !bar.is_hidden() {
            report::set_bar(Some(bar.clone()));
        }
        Progress {
            bar,
            started: Instant::now(),
            state: Mutex::new(State { total, finished: 0, active: BTreeMap::new(), shown: false }),
        }
    }

    /// Time since the run started.
    pub fn elapsed(&self) -> Duration {
        self.started.elapsed()
    }

    /// File `job` starts.
    pub fn begin(&self, job: usize, name: &str) {
        self.update(|s| {
            s.active.insert(job, Active { name: name.to_string(), rows: 0, height: 0, texels: 0 });
        });
    }

    /// File `job` turns out to be `width` × `height` and streams row by row.
    pub fn size(&self, job: usize, width: usize, height: usize) {
        self.update(|s| {
            if let Some(a) = s.active.get_mut(&job) {
                a.height = height;
                a.texels = width.saturating_mul(height);
            }
        });
    }

    /// One more row of file `job` went through the fit.
    pub fn row(&self, job: usize) {
        self.update(|s| {
            if let Some(a) = s.active.get_mut(&job) {
                a.rows += 1;
            }
        });
    }

    /// File `job` is done, whatever the outcome.
    pub fn finish(&self, job: usize) {
        self.update(|s| {
            s.active.remove(&job);
            s.finished += 1;
        });
    }

    /// Erases the bar, before the summary.
    pub fn close(&self) {
        if self.bar.is_hidden() {
            return;
        }
        report::set_bar(None);
        let shown = self.state.lock().unwrap_or_else(|e| e.into_inner()).shown;
        if shown {
            self.bar.finish_and_clear();
        } else {
            // Never drawn: nothing to erase, not even a line's worth.
            self.bar.set_draw_target(ProgressDrawTarget::hidden());
        }
    }

    fn update(&self, change: impl FnOnce(&mut State)) {
        if self.bar.is_hidden() {
            return;
        }
        let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
        change(&mut state);
        let long = state.total > 1 || state.active.values().any(|a| a.texels >= BIG_IMAGE);
        if long {
            state.shown = true;
            // indicatif redraws at most REDRAWS_PER_SECOND times a second.
            self.bar.set_position(state.steps());
            self.bar.set_message(state.message(self.started.elapsed()));
        }
    }
}

impl State {
    /// Files finished, and the fraction of rows of those under way, in
    /// [`STEPS`] per file.
    fn steps(&self) -> u64 {
        let partial: u64 = self
            .active
            .values()
            .map(|a| (STEPS as usize * a.rows.min(a.height)).checked_div(a.height).unwrap_or(0) as u64)
            .sum();
        (self.finished as u64 * STEPS + partial).min(self.total as u64 * STEPS)
    }

    /// What follows the bar: `3/12 files  rock.png 45%  0:04`.
    fn message(&self, elapsed: Duration) -> String {
        let secs = elapsed.as_secs();
        let mut line = format!("{}/{} files", self.finished, self.total);
        if let Some(a) = self.active.values().next() {
            let chars: Vec<char> = a.name.chars().collect();
            let name: String = chars[chars.len().saturating_sub(NAME_CHARS)..].iter().collect();
            line.push_str(&format!("  {name}"));
            if let Some(percent) = (100 * a.rows.min(a.height)).checked_div(a.height) {
                line.push_str(&format!(" {percent}%"));
            }
        }
        line.push_str(&format!("  {}:{:02}", secs / 60, secs % 60));
        line
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_line_counts_finished_files_and_the_rows_of_the_current_one() {
        let mut state = State { total: 4, finished: 1, active: BTreeMap::new(), shown: false };
        state.active.insert(1, Active { name: "rock.png".into(), rows: 50, height: 100, texels: 100 });
        assert_eq!(state.message(Duration::from_secs(65)), "1/4 files  rock.png 50%  1:05");
        // 1.5 of 4 files.
        assert_eq!(state.steps(), 1500);
    }

    #[test]
    fn long_names_keep_their_end() {
        let mut state = State { total: 2, finished: 0, active: BTreeMap::new(), shown: false };
        let name = format!("{}/ground.png", "deep".repeat(20));
        state.active.insert(0, Active { name, rows: 0, height: 0, texels: 0 });
        let line = state.message(Duration::ZERO);
        // The last 28 characters: 17 of the folder, then "/ground.png".
        assert_eq!(line, "0/2 files  pdeepdeepdeepdeep/ground.png  0:00");
        assert_eq!(state.steps(), 0);
    }
}
