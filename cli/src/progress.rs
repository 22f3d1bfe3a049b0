//! Progress display on stderr: on a terminal a spinner per long stage ([`Stages`]) or a bar
//! over known steps ([`Steps`]); when stderr is redirected (a log, CI), a line per stage or
//! step instead, so that a long command is never silent.

use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};

/// A spinner whose message follows the stages of a long computation.
pub struct Stages {
    bar: ProgressBar,
    what: String,
    /// When redirected: the last line printed (its words before any number) and when.
    said: std::sync::Mutex<(String, Option<std::time::Instant>)>,
}

/// How often at most a redirected stage that only counts on prints its line.
const LINE_EVERY: Duration = Duration::from_secs(5);

impl Stages {
    /// Starts a spinner prefixed with `what` (hidden when stderr is not a terminal).
    pub fn start(what: &str) -> Self {
        let bar = ProgressBar::new_spinner();
        bar.set_style(
            ProgressStyle::with_template("{spinner} {prefix}: {msg} [{elapsed}]").unwrap_or_else(|_| ProgressStyle::default_spinner()),
        );
        bar.set_prefix(what.to_string());
        bar.enable_steady_tick(Duration::from_millis(120));
        Self {
            bar,
            what: what.to_string(),
            said: std::sync::Mutex::new((String::new(), None)),
        }
    }

    /// Shows the current stage. When stderr is no terminal, a line of its own: at once for a
    /// new stage, every [`LINE_EVERY`] at most while only its numbers change.
    pub fn stage(&self, label: &str) {
        if self.bar.is_hidden() {
            let words: String = label.chars().take_while(|c| !c.is_ascii_digit()).collect();
            let mut said = self.said.lock().unwrap_or_else(|p| p.into_inner());
            let due = said.0 != words || said.1.is_none_or(|t| t.elapsed() >= LINE_EVERY);
            if due {
                eprintln!("vademecum: {}: {label}", self.what);
                *said = (words, Some(std::time::Instant::now()));
            }
        }
        self.bar.set_message(label.to_string());
    }

    /// Prints a warning line above the spinner (`vademecum: warning: …` on stderr).
    pub fn warn(&self, message: &str) {
        above(&self.bar, &format!("vademecum: warning: {message}"));
    }

    /// Removes the spinner.
    pub fn finish(self) {
        self.bar.finish_and_clear();
    }
}

/// A bar over a known number of steps: drawn on a terminal; when stderr is redirected, a
/// line per step (`vademecum: <what>: <step> (i/n)`).
pub struct Steps {
    bar: ProgressBar,
    what: String,
    started: u64,
}

impl Steps {
    /// Starts a bar of `n` steps prefixed with `what`.
    pub fn start(what: &str, n: usize) -> Self {
        let bar = ProgressBar::new(n as u64);
        bar.set_style(
            ProgressStyle::with_template("{prefix}: {bar:30} {pos}/{len} {msg} [{elapsed}]")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar.set_prefix(what.to_string());
        Self {
            bar,
            what: what.to_string(),
            started: 0,
        }
    }

    /// Announces the next step, `label`; the one before is counted done.
    pub fn step(&mut self, label: &str) {
        if self.started > 0 {
            self.bar.inc(1);
        }
        self.started += 1;
        if self.bar.is_hidden() {
            let n = self.bar.length().unwrap_or(0);
            eprintln!("vademecum: {}: {label} ({}/{n})", self.what, self.started);
        }
        self.bar.set_message(label.to_string());
    }

    /// Prints a line above the bar (on stderr as it is when redirected).
    pub fn println(&self, line: &str) {
        above(&self.bar, line);
    }

    /// Removes the bar.
    pub fn finish(self) {
        self.bar.finish_and_clear();
    }
}

/// Prints `line` above `bar` on a terminal, or on stderr as it is when the bar is hidden.
fn above(bar: &ProgressBar, line: &str) {
    if bar.is_hidden() {
        eprintln!("{line}");
    } else {
        bar.println(line);
    }
}
