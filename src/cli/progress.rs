//! A progress bar on stderr for the long commands (`demo`, `report`). It appears only once a
//! run has taken more than a second, and never when stderr is not a terminal.

use crate::report::Progress;
use std::io::{IsTerminal, Write};
use std::time::{Duration, Instant};

/// Draws `[#####.....] 5/14 step` on one line of stderr.
pub(crate) struct Bar {
    start: Instant,
    enabled: bool,
    drawn: bool,
    last: (usize, usize, String),
}

/// Width of the bar in characters.
const WIDTH: usize = 30;

impl Bar {
    /// A bar that draws only when stderr is a terminal.
    pub(crate) fn new() -> Self {
        Bar {
            start: Instant::now(),
            enabled: std::io::stderr().is_terminal(),
            drawn: false,
            last: (0, 0, String::new()),
        }
    }

    /// Records a progress report and redraws when the run is older than one second.
    pub(crate) fn update(&mut self, p: Progress<'_>) {
        self.last = (p.done, p.total, p.step.to_string());
        if !self.enabled || self.start.elapsed() < Duration::from_secs(1) {
            return;
        }
        let (done, total, step) = &self.last;
        let filled = (WIDTH * done).checked_div(*total).unwrap_or(0).min(WIDTH);
        let mut err = std::io::stderr().lock();
        let _ = write!(
            err,
            "\r\x1b[2K[{}{}] {done}/{total} {step} ({:.0} s)",
            "#".repeat(filled),
            ".".repeat(WIDTH - filled),
            self.start.elapsed().as_secs_f64()
        );
        let _ = err.flush();
        self.drawn = true;
    }

    /// Clears the bar's line, if one was drawn.
    pub(crate) fn finish(&mut self) {
        if self.drawn {
            let mut err = std::io::stderr().lock();
            let _ = write!(err, "\r\x1b[2K");
            let _ = err.flush();
            self.drawn = false;
        }
    }
}
