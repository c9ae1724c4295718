//! Progress on standard error: a bar redrawn in place on a terminal, a line every tenth of the
//! way otherwise (a log file then reads well).
//!
//! ```text
//! [#####.....] 37/80 runs, 0.4 s
//! ```

use std::io::{self, IsTerminal, Write};
use std::time::{Duration, Instant};

/// Cells of the bar.
const WIDTH: usize = 10;
/// Shortest interval between two redraws on a terminal.
const REDRAW: Duration = Duration::from_millis(50);

/// What is counted.
#[derive(Debug, Clone)]
enum Measure {
    /// Whole items (`37/80 runs`).
    Count { total: usize, unit: String },
    /// A fraction done (`41 %`).
    Fraction,
}

/// A progress report on standard error.
#[derive(Debug)]
pub struct Progress {
    /// What is counted and how it is shown.
    measure: Measure,
    /// Start of the work.
    start: Instant,
    /// Nothing is shown before this much time has passed (short work stays quiet).
    delay: Duration,
    /// Whether standard error is a terminal (redraw in place) or not (print lines).
    terminal: bool,
    /// Last fraction reported, in [0, 1].
    done: f64,
    /// Tenths already printed as lines (off a terminal).
    tenths: usize,
    /// When the bar was last drawn (on a terminal), if it is on screen.
    drawn: Option<Instant>,
}

impl Progress {
    /// Progress over `total` items named `unit` (`runs`), shown from the start.
    pub fn count(total: usize, unit: &str) -> Progress {
        Progress::new(
            Measure::Count {
                total,
                unit: unit.to_string(),
            },
            Duration::ZERO,
        )
    }

    /// Progress as a fraction, shown only once the work has lasted `delay`.
    pub fn fraction(delay: Duration) -> Progress {
        Progress::new(Measure::Fraction, delay)
    }

    fn new(measure: Measure, delay: Duration) -> Progress {
        Progress {
            measure,
            start: Instant::now(),
            delay,
            terminal: io::stderr().is_terminal(),
            done: 0.0,
            tenths: 0,
            drawn: None,
        }
    }

    /// Seconds since the start.
    pub fn elapsed(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    /// Reports `items` of the total done (a count).
    pub fn set_count(&mut self, items: usize) {
        let total = match self.measure {
            Measure::Count { total, .. } => total,
            Measure::Fraction => 1,
        };
        let fraction = if total == 0 {
            1.0
        } else {
            items as f64 / total as f64
        };
        self.set(fraction);
    }

    /// Reports the fraction done, in [0, 1].
    pub fn set(&mut self, fraction: f64) {
        self.done = fraction.clamp(0.0, 1.0);
        let elapsed = self.start.elapsed();
        if elapsed < self.delay {
            return;
        }
        if self.terminal {
            // Redraw in place, at most every REDRAW, and always at the end.
            let due = self.drawn.map_or(true, |t| t.elapsed() >= REDRAW);
            if due || self.done >= 1.0 {
                self.draw();
            }
        } else {
            // A line at each tenth passed (one for several tenths passed at once).
            let tenths = (self.done * 10.0 + 1e-9).floor() as usize;
            if tenths > self.tenths {
                self.tenths = tenths;
                eprintln!("{}", self.line());
            }
        }
    }

    /// Prints `text` on its own line without garbling the bar.
    pub fn message(&mut self, text: &str) {
        if self.drawn.is_some() {
            self.clear();
            eprintln!("{text}");
            self.draw();
        } else {
            eprintln!("{text}");
        }
    }

    /// Ends the report: the bar, if drawn, is left on screen with a line break after it.
    pub fn finish(&mut self) {
        if self.drawn.take().is_some() {
            self.draw_text();
            eprintln!();
        }
    }

    /// The report's text: `[#####.....] 37/80 runs, 0.4 s`.
    fn line(&self) -> String {
        let filled = ((self.done * WIDTH as f64).floor() as usize).min(WIDTH);
        let bar = format!("{}{}", "#".repeat(filled), ".".repeat(WIDTH - filled));
        let amount = match &self.measure {
            Measure::Count { total, unit } => {
                let items = (self.done * *total as f64).round() as usize;
                format!("{items}/{total} {unit}")
            }
            Measure::Fraction => format!("{:.0} %", self.done * 100.0),
        };
        format!("[{bar}] {amount}, {:.1} s", self.elapsed())
    }

    fn draw(&mut self) {
        self.draw_text();
        self.drawn = Some(Instant::now());
    }

    fn draw_text(&self) {
        let mut err = io::stderr().lock();
        // Errors on standard error have nowhere to be reported.
        let _ = write!(err, "\r{}\x1b[K", self.line());
        let _ = err.flush();
    }

    fn clear(&self) {
        let mut err = io::stderr().lock();
        let _ = write!(err, "\r\x1b[K");
        let _ = err.flush();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_shows_bar_count_and_time() {
        let mut p = Progress::count(80, "runs");
        p.terminal = true;
        p.done = 37.0 / 80.0;
        let line = p.line();
        assert!(line.starts_with("[####......] 37/80 runs, "), "{line}");
        assert!(line.ends_with(" s"), "{line}");
        p.done = 1.0;
        assert!(p.line().starts_with("[##########] 80/80 runs"));
    }

    #[test]
    fn fraction_shows_percent() {
        let mut p = Progress::fraction(Duration::ZERO);
        p.done = 0.414;
        assert!(p.line().starts_with("[####......] 41 %, "), "{}", p.line());
    }
}
