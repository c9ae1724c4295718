//! `vibrissa experiment`: the seed's template experiments `e1` and `e2`, every estimator scored.
//!
//! Simulates the experiment's grid, the templates and the free-budget training runs, fits each
//! method on the runs its budget allows, estimates every evaluated run, and prints the errors
//! and the coverage of the 90% intervals beside the paper's figures. Writes `results.json` and
//! the figures (PNG) into the output folder.

use crate::output::{sig, Align, FormatArgs, Render, Table};
use anyhow::{Context, Result};
use plotters::prelude::*;
use serde::Serialize;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};
use std::time::Instant;
use vibrissa_infer::{evaluate, Budget, Evaluation, Experiment, Variant};

/// Arguments of `vibrissa experiment`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The experiment: e1 (distance only) or e2 (distance and speed).
    #[arg(value_name = "EXPERIMENT")]
    experiment: String,
    /// clean, or noisy (sensor noise of 5% of each channel's range, plus process noise).
    #[arg(long, default_value = "clean")]
    variant: String,
    /// Output folder (default: experiment-<EXPERIMENT>-<VARIANT>).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Seed of all randomness.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    #[command(flatten)]
    format: FormatArgs,
}

/// The printed result: the evaluation plus where its files went.
#[derive(Debug, Serialize)]
struct Report {
    #[serde(flatten)]
    evaluation: Evaluation,
    /// Files written.
    files: Vec<PathBuf>,
}

/// Runs the experiment, writes its files and prints the table.
pub fn run(args: &Args) -> Result<()> {
    let experiment = Experiment::parse(&args.experiment)?;
    let variant = Variant::parse(&args.variant)?;
    let out = args.out.clone().unwrap_or_else(|| {
        PathBuf::from(format!(
            "experiment-{}-{}",
            experiment.name(),
            variant.name()
        ))
    });
    std::fs::create_dir_all(&out)
        .with_context(|| format!("cannot create the output folder `{}`", out.display()))?;

    // Progress: one line per stage on standard error.
    let start = Instant::now();
    let last = Mutex::new(String::new());
    let progress = |stage: &str, done: usize, total: usize| {
        let mut l = last.lock().expect("progress lock");
        if *l != stage || done == total {
            let line = format!("{stage} {done}/{total}");
            if *l != line {
                eprintln!("[{:6.2} s] {line}", start.elapsed().as_secs_f64());
                *l = if done == total {
                    line
                } else {
                    stage.to_string()
                };
            }
        }
    };
    let evaluation = evaluate(experiment, variant, args.seed, &progress)?;

    // Files: results.json and the figures.
    let mut files = Vec::new();
    let json = out.join("results.json");
    crate::files::write_atomic(&json, serde_json::to_string_pretty(&evaluation)?.as_bytes())?;
    files.push(json);
    files.extend(figures(&evaluation, &out)?);
    eprintln!("[{:6.2} s] done", start.elapsed().as_secs_f64());
    args.format.format().print(&Report { evaluation, files })?;
    Ok(())
}

impl Render for Report {
    fn render(&self, out: &mut dyn Write) -> io::Result<()> {
        let ev = &self.evaluation;
        let two = ev.unknowns.len() == 2;
        writeln!(
            out,
            "experiment {} ({}), seed {}: {} runs, {} evaluated; template σ² = {} rad²",
            ev.experiment.name(),
            ev.variant.name(),
            ev.seed,
            ev.grid.len(),
            ev.grid.len() - ev.is_template.iter().filter(|t| **t).count(),
            sig(ev.sigma2, 3)
        )?;
        let mut cols = vec![
            ("method", Align::Left),
            ("budget", Align::Left),
            ("training runs", Align::Right),
            ("MAE d (mm)", Align::Right),
        ];
        if two {
            cols.push(("MAE v (mm/ms)", Align::Right));
        }
        cols.push(("90% cover d", Align::Right));
        if two {
            cols.push(("90% cover v", Align::Right));
        }
        cols.extend([
            ("simulate (s)", Align::Right),
            ("fit (s)", Align::Right),
            ("estimate (ms)", Align::Right),
        ]);
        let mut t = Table::new(&cols);
        let mut paper = vec![
            "paper (seed)".to_string(),
            "paper".into(),
            "".into(),
            format!("{:.2}", ev.paper_mae[0] * 1e3),
        ];
        if two {
            paper.push(format!("{:.3}", ev.paper_mae[1]));
        }
        t.row(paper);
        for m in &ev.methods {
            let mut r = vec![
                m.name.clone(),
                m.budget.name().into(),
                m.training_runs.to_string(),
                format!("{:.3}", m.mae[0] * 1e3),
            ];
            if two {
                r.push(format!("{:.4}", m.mae[1]));
            }
            r.push(format!("{:.0}%", m.coverage[0] * 100.0));
            if two {
                r.push(format!("{:.0}%", m.coverage[1] * 100.0));
            }
            r.push(format!("{:.2}", m.simulate_seconds));
            r.push(format!("{:.3}", m.fit_seconds));
            r.push(format!("{:.3}", m.predict_seconds * 1e3));
            t.row(r);
        }
        t.write(out, "  ")?;
        writeln!(
            out,
            "noise: sensor σ = [{}] (theta01, theta12 rad; m0 N·m; fx, fy N), process {} N·s^½·m^-½",
            ev.noise.sensor.iter().map(|s| sig(*s, 3)).collect::<Vec<_>>().join(", "),
            sig(ev.noise.process, 2)
        )?;
        writeln!(out, "wall time {:.2} s; files:", ev.seconds)?;
        for f in &self.files {
            writeln!(out, "  {}", f.display())?;
        }
        Ok(())
    }
}

/// DejaVu Sans, embedded (licence: assets/DejaVuSans-LICENSE.txt).
const FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
/// Family name under which [`FONT`] is registered here.
const FAMILY: &str = "sans-serif";
/// Curve colours.
const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

/// One set of points of a figure, joined by lines or drawn as dots.
struct Set {
    label: String,
    points: Vec<(f64, f64)>,
    line: bool,
}

/// Draws the experiment's figures into `dir`; returns their paths.
fn figures(ev: &Evaluation, dir: &Path) -> Result<Vec<PathBuf>> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    if !*REGISTERED
        .get_or_init(|| plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).is_ok())
    {
        anyhow::bail!("the embedded font could not be read");
    }
    let mut files = Vec::new();
    let two = ev.unknowns.len() == 2;
    let templates: Vec<usize> = (0..ev.grid.len()).filter(|&k| ev.is_template[k]).collect();

    // Fig. 6: theta12 of the templates.
    let sets: Vec<Set> = templates
        .iter()
        .map(|&k| Set {
            label: if two {
                format!(
                    "d = {:.0} mm, v = {:.1} m/s",
                    ev.grid[k][0] * 1e3,
                    ev.grid[k][1]
                )
            } else {
                format!("d = {:.0} mm", ev.grid[k][0] * 1e3)
            },
            points: ev.theta12[k]
                .iter()
                .enumerate()
                .map(|(i, y)| (i as f64, *y))
                .collect(),
            line: true,
        })
        .collect();
    files.push(xy(
        dir,
        "templates",
        "theta12 of the templates (cf. the paper's Fig. 6)",
        "t (ms)",
        "theta12 (rad)",
        &sets,
    )?);

    // Fig. 7: responsibilities against distance (at the first speed of the grid for e2).
    let v0 = ev.grid[0][1];
    let sets: Vec<Set> = ev
        .template_params
        .iter()
        .enumerate()
        .map(|(i, p)| Set {
            label: if two {
                format!("template d = {:.0} mm, v = {:.1} m/s", p[0] * 1e3, p[1])
            } else {
                format!("template d = {:.0} mm", p[0] * 1e3)
            },
            points: (0..ev.grid.len())
                .filter(|&k| (ev.grid[k][1] - v0).abs() < 1e-9)
                .map(|k| (ev.grid[k][0] * 1e3, ev.responsibilities[k][i]))
                .collect(),
            line: true,
        })
        .collect();
    let title = if two {
        format!("template responsibilities at v = {v0} m/s (cf. Fig. 7)")
    } else {
        "template responsibilities (cf. Fig. 7)".into()
    };
    files.push(xy(
        dir,
        "responsibilities",
        &title,
        "d (mm)",
        "responsibility",
        &sets,
    )?);

    // Figs. 8–10: estimated against true values, the paper's method and the best ones.
    let mut chosen = vec!["template".to_string()];
    for b in [Budget::Paper, Budget::Free] {
        if let Some(m) = ev.best(b) {
            if !chosen.contains(&m.name) {
                chosen.push(m.name.clone());
            }
        }
    }
    let units = [("d", "mm", 1e3), ("v", "m/s", 1.0)];
    for (u, (name, unit, f)) in units.iter().enumerate().take(ev.unknowns.len()) {
        let mut sets: Vec<Set> = chosen
            .iter()
            .filter_map(|n| ev.methods.iter().find(|m| &m.name == n))
            .map(|m| Set {
                label: m.name.clone(),
                points: m
                    .predictions
                    .iter()
                    .map(|p| (p.truth[u] * f, p.estimate[u].mean * f))
                    .collect(),
                line: false,
            })
            .collect();
        let r = ev.experiment.ranges()[u];
        sets.push(Set {
            label: "truth".into(),
            points: vec![(r[0] * f, r[0] * f), (r[1] * f, r[1] * f)],
            line: true,
        });
        let fig = if u == 0 { "Figs. 8, 9" } else { "Fig. 10" };
        files.push(xy(
            dir,
            &format!("estimated-{name}"),
            &format!("estimated against true {name} (cf. the paper's {fig})"),
            &format!("true {name} ({unit})"),
            &format!("estimated {name} ({unit})"),
            &sets,
        )?);
    }
    Ok(files)
}

/// One x-y figure as `dir/name.png`.
fn xy(dir: &Path, name: &str, title: &str, xl: &str, yl: &str, sets: &[Set]) -> Result<PathBuf> {
    let path = dir.join(format!("{name}.png"));
    let err = |e: &dyn std::fmt::Display| anyhow::anyhow!("drawing {}: {e}", path.display());
    let all = sets.iter().flat_map(|s| s.points.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for &(x, y) in all.filter(|(x, y)| x.is_finite() && y.is_finite()) {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    if x0.partial_cmp(&x1) != Some(std::cmp::Ordering::Less) {
        (x0, x1) = (x0 - 1.0, x0 + 1.0);
    }
    let pad = ((y1 - y0) * 0.05).max(1e-12);
    let (y0, y1) = (y0 - pad, y1 + pad);
    {
        let root = BitMapBackend::new(&path, (900, 600)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, (FAMILY, 22))
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .x_desc(xl)
            .y_desc(yl)
            .label_style((FAMILY, 14))
            .draw()
            .map_err(|e| err(&e))?;
        for (i, s) in sets.iter().enumerate() {
            let c = PALETTE[i % PALETTE.len()];
            if s.line {
                chart
                    .draw_series(LineSeries::new(s.points.clone(), c.stroke_width(2)))
                    .map_err(|e| err(&e))?
                    .label(s.label.clone())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2))
                    });
            } else {
                chart
                    .draw_series(s.points.iter().map(|&p| Circle::new(p, 3, c.filled())))
                    .map_err(|e| err(&e))?
                    .label(s.label.clone())
                    .legend(move |(x, y)| Circle::new((x + 10, y), 3, c.filled()));
            }
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font((FAMILY, 13))
            .draw()
            .map_err(|e| err(&e))?;
        root.present().map_err(|e| err(&e))?;
    }
    Ok(path)
}
