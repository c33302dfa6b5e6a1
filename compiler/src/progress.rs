//! Progress of long steps, on standard error: one implementation every long command
//! shares (training, validation, reproduction, evaluation).
//!
//! On a terminal a step is a bar redrawn in place. Anywhere else (a log file, a pipe,
//! CI) it is plain lines, e.g. `test graphs 120/540 (14 s)`: one when another tenth of
//! the step is done and at least [`LINE_INTERVAL`] has passed since the last line, one
//! after [`QUIET_INTERVAL`] without any, and a last one when a step that printed
//! anything (or took longer than [`LINE_INTERVAL`]) ends. [`Progress::stage`] prints a
//! line announcing a stage in both cases. [`Progress::Hidden`] prints nothing.
//!
//! [`LINE_INTERVAL`]: crate::progress::LINE_INTERVAL
//! [`QUIET_INTERVAL`]: crate::progress::QUIET_INTERVAL
//! [`Progress::stage`]: crate::progress::Progress::stage
//! [`Progress::Hidden`]: crate::progress::Progress::Hidden

use std::io::IsTerminal;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

/// Least time between two progress lines of one step.
pub const LINE_INTERVAL: Duration = Duration::from_secs(3);

/// Longest silence of a step that is still running.
pub const QUIET_INTERVAL: Duration = Duration::from_secs(60);

/// Whether and how to report progress.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Progress {
    /// On standard error: a bar on a terminal, plain lines otherwise (see the module
    /// docs).
    Auto,
    /// Nothing.
    Hidden,
}

impl Progress {
    /// The progress of a step of `len` units called `what` (e.g. `test graphs`).
    pub fn bar(self, len: u64, what: &str) -> Bar {
        if self == Progress::Hidden {
            return Bar::Hidden;
        }
        if std::io::stderr().is_terminal() && std::env::var_os("CI").is_none() {
            let bar = ProgressBar::new(len);
            if let Ok(style) = ProgressStyle::with_template("{prefix} [{bar:30}] {pos}/{len} {msg}")
            {
                bar.set_style(style);
            }
            bar.set_prefix(what.to_string());
            return Bar::Terminal(bar);
        }
        let now = Instant::now();
        Bar::Lines(Box::new(Lines {
            what: what.to_string(),
            len,
            pos: AtomicU64::new(0),
            start: now,
            last: Mutex::new(Printed {
                at: now,
                tenth: 0,
                any: false,
            }),
        }))
    }

    /// Announces a stage (one line on standard error), unless hidden.
    pub fn stage(self, message: &str) {
        if self == Progress::Auto {
            eprintln!("{message}");
        }
    }
}

/// The progress of one step: [`Bar::inc`] as units are done (from any thread),
/// [`Bar::finish_and_clear`] at the end.
pub enum Bar {
    /// Nothing is shown.
    Hidden,
    /// A bar on the terminal.
    Terminal(ProgressBar),
    /// Plain lines.
    Lines(Box<Lines>),
}

/// State of a step reported as plain lines.
pub struct Lines {
    what: String,
    len: u64,
    pos: AtomicU64,
    start: Instant,
    last: Mutex<Printed>,
}

/// The last line printed.
struct Printed {
    at: Instant,
    /// Tenths of the step done at that line.
    tenth: u64,
    /// Whether any line was printed.
    any: bool,
}

impl Lines {
    fn line(&self, pos: u64) -> String {
        format!(
            "{} {pos}/{} ({:.0} s)",
            self.what,
            self.len,
            self.start.elapsed().as_secs_f64()
        )
    }

    /// Counts `n` more units and returns the line to print now, if one is due.
    fn advance(&self, n: u64) -> Option<String> {
        let pos = self.pos.fetch_add(n, Ordering::Relaxed) + n;
        let tenth = (pos * 10).checked_div(self.len).unwrap_or(10);
        let mut last = self.last.lock().ok()?;
        let since = last.at.elapsed();
        let due = (tenth > last.tenth && since >= LINE_INTERVAL) || since >= QUIET_INTERVAL;
        if !due || pos >= self.len {
            return None;
        }
        *last = Printed {
            at: Instant::now(),
            tenth,
            any: true,
        };
        Some(self.line(pos))
    }

    /// The last line of the step, if it printed any or took long.
    fn last_line(&self) -> Option<String> {
        let any = self.last.lock().map(|l| l.any).unwrap_or(false);
        (any || self.start.elapsed() >= LINE_INTERVAL)
            .then(|| self.line(self.pos.load(Ordering::Relaxed)))
    }

    fn inc(&self, n: u64) {
        if let Some(line) = self.advance(n) {
            eprintln!("{line}");
        }
    }

    fn finish(&self) {
        if let Some(line) = self.last_line() {
            eprintln!("{line}");
        }
    }
}

impl Bar {
    /// `n` more units done.
    pub fn inc(&self, n: u64) {
        match self {
            Bar::Hidden => {}
            Bar::Terminal(b) => b.inc(n),
            Bar::Lines(l) => l.inc(n),
        }
    }

    /// A note shown beside a terminal bar (not printed as a line).
    pub fn set_message(&self, message: String) {
        if let Bar::Terminal(b) = self {
            b.set_message(message);
        }
    }

    /// The step is over: a terminal bar is removed; as lines, a last line is printed
    /// if the step printed any or took long.
    pub fn finish_and_clear(&self) {
        match self {
            Bar::Hidden => {}
            Bar::Terminal(b) => b.finish_and_clear(),
            Bar::Lines(l) => l.finish(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A step of `len` units that started `ago` and last printed `ago`.
    fn lines(len: u64, ago: Duration) -> Lines {
        let then = Instant::now() - ago;
        Lines {
            what: "test graphs".into(),
            len,
            pos: AtomicU64::new(0),
            start: then,
            last: Mutex::new(Printed {
                at: then,
                tenth: 0,
                any: false,
            }),
        }
    }

    #[test]
    fn without_a_terminal_progress_is_plain_lines() {
        // Under `cargo test` standard error is captured, never a terminal.
        assert!(matches!(Progress::Auto.bar(10, "x"), Bar::Lines(_)));
        assert!(matches!(Progress::Hidden.bar(10, "x"), Bar::Hidden));
    }

    #[test]
    fn a_line_per_tenth_at_most_every_interval_and_after_a_silence() {
        let l = lines(100, LINE_INTERVAL + Duration::from_millis(50));
        let first = l.advance(10).expect("a tenth done after the interval");
        assert!(first.starts_with("test graphs 10/100 ("), "{first}");
        // Right after a line: nothing, even for another tenth.
        assert_eq!(l.advance(10), None);
        // A long silence prints even without a new tenth.
        l.last.lock().unwrap().at = Instant::now() - QUIET_INTERVAL;
        assert!(l.advance(1).unwrap().starts_with("test graphs 21/100"));
        // The end is the last line's job.
        l.last.lock().unwrap().at = Instant::now() - QUIET_INTERVAL;
        assert_eq!(l.advance(79), None);
        assert!(l.last_line().unwrap().starts_with("test graphs 100/100"));
    }

    #[test]
    fn a_short_quiet_step_prints_nothing() {
        let l = lines(4, Duration::ZERO);
        assert_eq!(l.advance(4), None);
        assert_eq!(l.last_line(), None);
    }
}
