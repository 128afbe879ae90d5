//! The progress bar of a long `convert`: one line on standard error, drawn
//! only when standard error is a terminal (a log or a pipe gets none of
//! it), and only for long work: more than one file, or an image of at
//! least [`BIG_IMAGE`] texels. Redrawn at most ten times a second and
//! erased at the end; messages print above it ([`super::report`]).

use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use super::report::show_status;

/// An image this large (2048²) takes long enough on its own to deserve a bar.
pub const BIG_IMAGE: usize = 1 << 22;

/// Time between two redraws.
const REDRAW: Duration = Duration::from_millis(100);

/// Cells of the bar itself.
const BAR_CELLS: usize = 24;

/// Longest file name shown, in characters (longer ones keep their end).
const NAME_CHARS: usize = 28;

/// Progress over the files of one run, shared by the jobs converting them.
pub struct Progress {
    /// Whether anything may be drawn: standard error is a terminal and the
    /// user did not ask for quiet.
    enabled: bool,
    started: Instant,
    state: Mutex<State>,
}

struct State {
    total: usize,
    finished: usize,
    /// Files being converted, by their place in the run.
    active: BTreeMap<usize, Active>,
    last_draw: Option<Instant>,
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
        Progress {
            enabled: wanted && std::io::stderr().is_terminal(),
            started: Instant::now(),
            state: Mutex::new(State { total, finished: 0, active: BTreeMap::new(), last_draw: None }),
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
        if self.enabled {
            show_status("");
        }
    }

    fn update(&self, change: impl FnOnce(&mut State)) {
        if !self.enabled {
            return;
        }
        let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
        change(&mut state);
        let long = state.total > 1 || state.active.values().any(|a| a.texels >= BIG_IMAGE);
        let now = Instant::now();
        let due = state.last_draw.is_none_or(|t| now.duration_since(t) >= REDRAW);
        if long && due {
            state.last_draw = Some(now);
            show_status(&state.line(self.started.elapsed()));
        }
    }
}

impl State {
    /// `[######------]  3/12 files  rock.png 45%  0:04`
    fn line(&self, elapsed: Duration) -> String {
        let partial: f64 =
            self.active.values().map(|a| if a.height > 0 { a.rows as f64 / a.height as f64 } else { 0.0 }).sum();
        let done = ((self.finished as f64 + partial) / self.total.max(1) as f64).clamp(0.0, 1.0);
        let filled = (done * BAR_CELLS as f64).round() as usize;
        let bar: String = "#".repeat(filled) + &"-".repeat(BAR_CELLS - filled);
        let secs = elapsed.as_secs();
        let mut line = format!("[{bar}] {}/{} files", self.finished, self.total);
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
        let mut state = State { total: 4, finished: 1, active: BTreeMap::new(), last_draw: None };
        state.active.insert(1, Active { name: "rock.png".into(), rows: 50, height: 100, texels: 100 });
        let line = state.line(Duration::from_secs(65));
        // 1.5 of 4 files: 9 of 24 cells.
        assert_eq!(line, format!("[{}{}] 1/4 files  rock.png 50%  1:05", "#".repeat(9), "-".repeat(15)));
    }

    #[test]
    fn long_names_keep_their_end() {
        let mut state = State { total: 2, finished: 0, active: BTreeMap::new(), last_draw: None };
        let name = format!("{}/ground.png", "deep".repeat(20));
        state.active.insert(0, Active { name, rows: 0, height: 0, texels: 0 });
        let line = state.line(Duration::ZERO);
        // The last 28 characters: 17 of the folder, then "/ground.png".
        assert!(line.ends_with("files  pdeepdeepdeepdeep/ground.png  0:00"), "{line}");
        assert!(line.chars().count() < 80, "{line}");
    }
}
