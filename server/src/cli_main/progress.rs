//! Progress display on stderr: a spinner per long stage, drawn only on a terminal.

use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};

/// A spinner whose message follows the stages of a long computation.
pub struct Stages {
    bar: ProgressBar,
}

impl Stages {
    /// Starts a spinner prefixed with `what` (hidden when stderr is not a terminal).
    pub fn start(what: &str) -> Self {
        let bar = ProgressBar::new_spinner();
        bar.set_style(
            ProgressStyle::with_template("{spinner} {prefix}: {msg} [{elapsed}]").unwrap_or_else(|_| ProgressStyle::default_spinner()),
        );
        bar.set_prefix(what.to_string());
        bar.enable_steady_tick(Duration::from_millis(120));
        Self { bar }
    }

    /// Shows the current stage.
    pub fn stage(&self, label: &str) {
        self.bar.set_message(label.to_string());
    }

    /// Prints a warning line above the spinner (`vademecum: warning: …` on stderr).
    pub fn warn(&self, message: &str) {
        let line = format!("vademecum: warning: {message}");
        if self.bar.is_hidden() {
            eprintln!("{line}");
        } else {
            self.bar.println(line);
        }
    }

    /// Removes the spinner.
    pub fn finish(self) {
        self.bar.finish_and_clear();
    }
}
