//! Progress on standard error: a bar redrawn in place on a terminal (indicatif), a line every
//! tenth of the way otherwise (a log file then reads well).
//!
//! ```text
//! [#####.....] 37/80 runs, 0.4 s
//! ```

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::{self, IsTerminal};
use std::time::{Duration, Instant};

/// Cells of the bar.
const WIDTH: usize = 10;
/// Steps of a bar that shows a fraction.
const FRACTION_STEPS: u64 = 1000;

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
    /// The bar on a terminal, once shown.
    bar: Option<ProgressBar>,
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
            bar: None,
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
            let position = self.position();
            self.bar
                .get_or_insert_with(|| terminal_bar(&self.measure, self.start))
                .set_position(position);
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
        match &self.bar {
            Some(bar) => bar.suspend(|| eprintln!("{text}")),
            None => eprintln!("{text}"),
        }
    }

    /// Ends the report: the bar, if shown, is left on screen with a line break after it.
    pub fn finish(&mut self) {
        if let Some(bar) = self.bar.take() {
            bar.set_position(self.position());
            bar.abandon();
            eprintln!();
        }
    }

    /// The bar's position: items done, or thousandths of the work.
    fn position(&self) -> u64 {
        match &self.measure {
            Measure::Count { total, .. } => (self.done * *total as f64).round() as u64,
            Measure::Fraction => (self.done * FRACTION_STEPS as f64).round() as u64,
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
}

/// A bar on standard error that shows `measure` as [`Progress::line`] words it.
fn terminal_bar(measure: &Measure, start: Instant) -> ProgressBar {
    let (length, amount) = match measure {
        Measure::Count { total, unit } => (*total as u64, format!("{{pos}}/{{len}} {unit}")),
        Measure::Fraction => (FRACTION_STEPS, "{percent} %".to_string()),
    };
    let template = format!("[{{bar:{WIDTH}}}] {amount}, {{elapsed_seconds}}");
    let style = ProgressStyle::with_template(&template)
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("#.")
        .with_key(
            "elapsed_seconds",
            move |_: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
                let _ = write!(w, "{:.1} s", start.elapsed().as_secs_f64());
            },
        );
    let bar = ProgressBar::with_draw_target(Some(length), ProgressDrawTarget::stderr());
    bar.set_style(style);
    bar
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
