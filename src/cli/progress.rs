//! The progress bar of a render on a terminal: a session [`Observer`].

use crate::run::session::{Observer, Progress};
use indicatif::{HumanDuration, ProgressDrawTarget, ProgressStyle};
use std::time::Duration;

/// A bar of samples per pixel on stderr, with rays/s and the time left; or
/// nothing at all when hidden. Warnings are printed above it.
pub struct ProgressBar {
    bar: indicatif::ProgressBar,
}

impl ProgressBar {
    /// A bar that draws when `show` is set.
    pub fn new(show: bool) -> Self {
        let bar = if show {
            indicatif::ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr())
        } else {
            indicatif::ProgressBar::hidden()
        };
        Self { bar }
    }
}

impl Observer for ProgressBar {
    fn start(&mut self, total: u64, done: u64) {
        if self.bar.is_hidden() {
            return;
        }
        let style = ProgressStyle::with_template(
            "{elapsed_precise} [{wide_bar}] {human_pos}/{human_len} spp  {msg}",
        )
        .expect("the progress template is valid")
        .progress_chars("=> ");
        self.bar.set_style(style);
        self.bar.set_length(total);
        self.bar.set_position(done);
        self.bar.set_message("measuring speed");
        self.bar.enable_steady_tick(Duration::from_millis(250));
    }

    fn pass(&mut self, p: &Progress) {
        if self.bar.is_hidden() {
            return;
        }
        self.bar.set_position(p.done);
        // With a time limit, the bar ends at the samples that will fit.
        self.bar.set_length(p.expected);
        let note = if p.time_limited { " (time limit)" } else { "" };
        self.bar.set_message(format!(
            "{:.2} Mrays/s  ETA {}{note}",
            p.rays_per_second / 1e6,
            HumanDuration(Duration::from_secs_f64(p.eta_seconds))
        ));
    }

    fn warning(&mut self, message: &str) {
        self.bar.suspend(|| eprintln!("warning: {message}"));
    }

    fn finish(&mut self) {
        self.bar.finish_and_clear();
    }
}
