//! A progress bar on standard error for long report runs: units of work
//! done out of those known so far. Shown only when standard error is a
//! terminal, `--quiet` was not given, and the run has taken more than about
//! 2 s; it never touches standard output or a report's figures.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::time::{Duration, Instant};

/// Runs shorter than this show no bar.
const QUIET_FOR: Duration = Duration::from_secs(2);

/// A handle to the bar (cheap to clone; every clone moves the same bar).
#[derive(Clone, Debug)]
pub struct Progress {
    bar: Option<(ProgressBar, Instant)>,
}

impl Progress {
    /// No bar at all.
    #[must_use]
    pub fn hidden() -> Progress {
        Progress { bar: None }
    }

    /// A bar labelled `label`, unless `quiet` or standard error is not a terminal.
    #[must_use]
    pub fn for_terminal(label: &str, quiet: bool) -> Progress {
        if quiet || !std::io::stderr().is_terminal() {
            return Progress::hidden();
        }
        let bar = ProgressBar::with_draw_target(Some(0), ProgressDrawTarget::hidden());
        if let Ok(style) = ProgressStyle::with_template(
            "{prefix} [{elapsed_precise}] {wide_bar} {pos}/{len} units (eta {eta})",
        ) {
            bar.set_style(style);
        }
        bar.set_prefix(label.to_string());
        Progress {
            bar: Some((bar, Instant::now())),
        }
    }

    /// `n` more units of work are known.
    pub fn add_units(&self, n: u64) {
        if let Some((bar, _)) = &self.bar {
            bar.inc_length(n);
        }
    }

    /// `n` units are done.
    pub fn done(&self, n: u64) {
        if let Some((bar, start)) = &self.bar {
            bar.inc(n);
            if bar.is_hidden() && start.elapsed() > QUIET_FOR {
                bar.set_draw_target(ProgressDrawTarget::stderr());
            }
        }
    }

    /// Clear the bar (before the report is printed).
    pub fn finish(&self) {
        if let Some((bar, _)) = &self.bar {
            bar.finish_and_clear();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quiet_shows_no_bar_and_a_hidden_bar_ignores_updates() {
        let p = Progress::for_terminal("drs-table1", true);
        assert!(p.bar.is_none());
        p.add_units(10);
        p.done(3);
        p.finish();
        assert!(Progress::hidden().bar.is_none());
    }
}
