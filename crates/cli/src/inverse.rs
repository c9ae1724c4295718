//! `vibrissa inverse`: the field's beam-theory estimators of contact distance, measured on
//! simulated whisks against stationary pegs.
//!
//! With `--out DIR`, also writes `results.json` (the sweep's settings, every row and the
//! worst-error table) and the figure `inverse-error.png` (+ `.svg`): worst |relative error|
//! against tip deflection, one line per estimator, the 2% line marked.

use crate::output::{sig, Align, FormatArgs, Render, Table};
use crate::plot::{self, Mark, XyFigure, XyPanel, XySet};
use anyhow::{Context, Result};
use serde::Serialize;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use vibrissa_core::inverse::{
    evaluate_peg_sweep, worst_over_distances, Estimator, InverseResult, PegSweep,
};

/// Arguments of `vibrissa inverse`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output folder for results.json and the figure inverse-error.png (+ .svg); created if
    /// missing.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    #[command(flatten)]
    format: FormatArgs,
}

/// The sweep's settings (SI units).
#[derive(Debug, Serialize)]
struct Settings {
    /// Whisker.
    whisker: &'static str,
    /// Whisking rate, rad/s.
    rate: f64,
    /// Segment count N.
    segments: usize,
    /// Time step, s.
    dt: f64,
    /// Longest simulated time per peg, s.
    max_time: f64,
    /// Levels up to this fraction of L are sampled no earlier than `settle` after first contact.
    settle_below: f64,
    /// Settling time for the small levels, s.
    settle: f64,
}

/// Every row, and the worst error per estimator and deflection level.
#[derive(Debug, Serialize)]
struct InverseReport {
    /// How the pegs were whisked.
    settings: Settings,
    /// Peg distances, m.
    distances: Vec<f64>,
    /// Tip-deflection levels, fractions of L.
    levels: Vec<f64>,
    /// `(estimator, level, worst |relative error| over distances, rows)`.
    worst: Vec<Worst>,
    /// Every estimate.
    rows: Vec<InverseResult>,
    /// Files written (with `--out`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    files: Vec<PathBuf>,
}

#[derive(Debug, Serialize)]
struct Worst {
    /// The estimator's name in the table.
    estimator: &'static str,
    /// Its identifier (as in `rows`).
    id: Estimator,
    level: f64,
    worst_relative_error: f64,
    rows: usize,
}

/// Runs the sweep, writes the files asked for and prints the table.
pub fn run(args: &Args) -> Result<()> {
    if let Some(out) = &args.out {
        std::fs::create_dir_all(out)
            .with_context(|| format!("cannot create the output folder `{}`", out.display()))?;
    }
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
            id: e,
            level,
            worst_relative_error: worst,
            rows: n,
        })
        .collect();
    let mut report = InverseReport {
        settings: Settings {
            whisker: "w30",
            rate: sweep.rate,
            segments: sweep.segments,
            dt: sweep.dt,
            max_time: sweep.max_time,
            settle_below: sweep.settle_below,
            settle: sweep.settle,
        },
        distances: sweep.distances,
        levels: sweep.levels,
        worst,
        rows,
        files: Vec::new(),
    };
    if let Some(out) = &args.out {
        report.files = write_files(&report, out)?;
    }
    args.format.format().print(&report)?;
    Ok(())
}

/// The 2% error that the table is read against.
const TARGET: f64 = 0.02;

/// Writes `results.json` and the figure into `dir`, each appearing whole; returns their paths.
fn write_files(report: &InverseReport, dir: &Path) -> Result<Vec<PathBuf>> {
    let png = dir.join("inverse-error.png");
    let figure = plot::render_xy(&png, &error_figure(report))?;
    let json = dir.join("results.json");
    crate::files::write_atomic(&json, serde_json::to_string_pretty(report)?.as_bytes())?;
    let mut files = vec![json];
    for (path, file) in figure {
        file.commit()?;
        files.push(path);
    }
    Ok(files)
}

/// Worst |relative error| (%) against tip deflection (% of L), one line per estimator; the
/// frequency estimator, which reads no deflection, as a dashed level line across the axis.
fn error_figure(report: &InverseReport) -> XyFigure {
    let levels: Vec<f64> = report
        .levels
        .iter()
        .map(|l| l * 100.0)
        .filter(|l| l.is_finite())
        .collect();
    let (lo, hi) = levels
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &l| {
            (a.min(l), b.max(l))
        });
    let mut sets = Vec::new();
    for (i, e) in Estimator::ALL.into_iter().enumerate() {
        let worst: Vec<&Worst> = report.worst.iter().filter(|w| w.id == e).collect();
        if worst.is_empty() {
            continue;
        }
        let deflected: Vec<(f64, f64)> = worst
            .iter()
            .filter(|w| w.level > 0.0)
            .map(|w| (w.level * 100.0, w.worst_relative_error * 100.0))
            .collect();
        let set = if deflected.is_empty() {
            // No deflection level: one worst error over every peg, drawn across the axis.
            let y = worst
                .iter()
                .map(|w| w.worst_relative_error * 100.0)
                .fold(0.0, f64::max);
            XySet {
                label: format!("{} (ringing, any deflection)", e.name()),
                points: vec![(lo, y), (hi, y)],
                mark: Mark::Dashed,
                colour: Some(i),
            }
        } else {
            XySet {
                label: e.name().to_string(),
                points: deflected,
                mark: Mark::LineDots,
                colour: Some(i),
            }
        };
        sets.push(set);
    }
    sets.push(XySet {
        label: format!("{:.0} %", TARGET * 100.0),
        points: vec![(lo, TARGET * 100.0), (hi, TARGET * 100.0)],
        mark: Mark::Dashed,
        colour: None,
    });
    XyFigure {
        title: format!(
            "contact distance from base measurements: worst error over {} pegs",
            report.distances.len()
        ),
        x_desc: "tip deflection (% of L)".into(),
        y_desc: "worst |relative error| (%)".into(),
        log_y: true,
        columns: 1,
        legend_lower_right: true,
        panels: vec![XyPanel {
            caption: String::new(),
            sets,
        }],
    }
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
        table.write(out, "  ")?;
        if !self.files.is_empty() {
            writeln!(out, "files:")?;
            for f in &self.files {
                writeln!(out, "  {}", f.display())?;
            }
        }
        Ok(())
    }
}
