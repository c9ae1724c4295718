//! `vibrissa inverse`: the field's beam-theory estimators of contact distance, measured on
//! simulated whisks against stationary pegs.

use crate::output::{sig, Align, FormatArgs, Render, Table};
use anyhow::{Context, Result};
use serde::Serialize;
use std::io::{self, Write};
use vibrissa_core::inverse::{evaluate_peg_sweep, worst_over_distances, InverseResult, PegSweep};

/// Arguments of `vibrissa inverse`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    format: FormatArgs,
}

/// Every row, and the worst error per estimator and deflection level.
#[derive(Debug, Serialize)]
struct InverseReport {
    /// Peg distances, m.
    distances: Vec<f64>,
    /// Tip-deflection levels, fractions of L.
    levels: Vec<f64>,
    /// `(estimator, level, worst |relative error| over distances, rows)`.
    worst: Vec<Worst>,
    /// Every estimate.
    rows: Vec<InverseResult>,
}

#[derive(Debug, Serialize)]
struct Worst {
    estimator: &'static str,
    level: f64,
    worst_relative_error: f64,
    rows: usize,
}

/// Runs the sweep and prints the table.
pub fn run(args: &Args) -> Result<()> {
    let sweep = PegSweep::default();
    eprintln!(
        "whisking into {} pegs and reading {} deflection levels…",
        sweep.distances.len(),
        sweep.levels.len()
    );
    let rows = evaluate_peg_sweep(&sweep).context("the peg sweep could not be completed")?;
    let worst = worst_over_distances(&rows)
        .into_iter()
        .map(|(e, level, worst, n)| Worst {
            estimator: e.name(),
            level,
            worst_relative_error: worst,
            rows: n,
        })
        .collect();
    let report = InverseReport {
        distances: sweep.distances,
        levels: sweep.levels,
        worst,
        rows,
    };
    args.format.format().print(&report)?;
    Ok(())
}

impl Render for InverseReport {
    fn render(&self, out: &mut dyn Write) -> io::Result<()> {
        writeln!(
            out,
            "contact distance from base measurements, w30 whisked at 0.05 rad/s into pegs at d = {:.0}…{:.0} mm",
            self.distances[0] * 1e3,
            self.distances[self.distances.len() - 1] * 1e3
        )?;
        writeln!(
            out,
            "worst |relative error| over the pegs, by tip deflection (fraction of L):"
        )?;
        let mut table = Table::new(&[
            ("estimator", Align::Left),
            ("deflection", Align::Right),
            ("worst error", Align::Right),
            ("pegs", Align::Right),
        ]);
        for w in &self.worst {
            let level = if w.level > 0.0 {
                format!("{} %", sig(w.level * 100.0, 2))
            } else {
                "ringing".to_string()
            };
            table.row(vec![
                w.estimator.to_string(),
                level,
                format!("{} %", sig(w.worst_relative_error * 100.0, 3)),
                w.rows.to_string(),
            ]);
        }
        table.write(out, "  ")
    }
}
