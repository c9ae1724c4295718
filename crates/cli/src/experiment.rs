//! `vibrissa experiment`: the seed's template experiments `e1` and `e2`, every estimator scored.
//!
//! Simulates the experiment's grid, the templates and the free-budget training runs, fits each
//! method on the runs its budget allows, estimates every evaluated run, and prints the errors
//! and the coverage of the 90% intervals beside the paper's figures. Writes `results.json` and
//! the figures (each as PNG and SVG) into the output folder.

use crate::output::{sig, Align, FormatArgs, Render, Table};
use crate::plot::{self, Mark, XyFigure, XyPanel, XySet};
use anyhow::{Context, Result};
use serde::Serialize;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;
use vibrissa_infer::pf::TransitionModel;
use vibrissa_infer::shapes::ShapeFamily;
use vibrissa_infer::{
    calibration, evaluate_unknown_start, evaluate_with, Budget, Evaluation, Family,
    StartEvaluation, Variant,
};

/// Arguments of `vibrissa experiment`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The built-in experiment: e1 (distance only), e2 (distance and speed), e3 (shape
    /// recognition: the class and pose of an object moved past 1, 3 or 5 whiskers) or e3-active
    /// (the same whiskers whisked against a still object).
    #[arg(value_name = "EXPERIMENT", required_unless_present_any = ["scenario", "shapes"])]
    experiment: Option<String>,
    /// Run a shape experiment on a shape family instead: a TOML file whose [classes] table names
    /// each class's scenario file (box = "box.toml"), every class with the same whiskers.
    #[arg(long, value_name = "FILE.toml", conflicts_with_all = ["experiment", "scenario"])]
    shapes: Option<String>,
    /// Shape experiments: training runs per class (default 800).
    #[arg(long, value_name = "N", value_parser = crate::limits::training)]
    training: Option<usize>,
    /// Shape experiments: evaluated runs per class (default 50).
    #[arg(long, value_name = "N", value_parser = crate::limits::runs)]
    runs: Option<usize>,
    /// Shape experiments with shape-bank: noise-free runs per class in its bank (default 3200,
    /// the training runs' twins included; at least the training runs).
    #[arg(long, value_name = "N", value_parser = crate::limits::bank)]
    bank: Option<usize>,
    /// Shape experiments: the whisker sets to score, as counts of the array's middle whiskers
    /// (`1,3,5`, the default for a fan of five) or names joined by `+` (`c1+c5`).
    #[arg(long, value_name = "SETS")]
    whiskers: Option<String>,
    /// Shape experiments: the estimators to score (repeatable, or joined by commas): shape-krr
    /// (reads the recording whole), shape-esn (online: a class posterior after every sample),
    /// shape-bank (the likelihood under a bank of noise-free runs, also online; simulates its
    /// bank, about 4 minutes on 2 cores) and shape-pf (a particle filter over each class's pose,
    /// the class by marginal likelihood, also online; about half a second per recording and
    /// whisker), shape-mix (shape-bank and shape-pf pooled; costs both). Default: shape-krr and
    /// shape-esn.
    #[arg(long = "method", value_name = "NAME", value_delimiter = ',')]
    methods: Vec<String>,
    /// Shape experiments: train on whiskers and sensors drawn around the scenario's (for
    /// recordings of a whisker known only roughly).
    #[arg(long)]
    randomise: bool,
    /// Shape experiments: also write every evaluated run as a scenario file with `truth.csv`
    /// into DIR, so that another simulator can reproduce each run.
    #[arg(long, value_name = "DIR")]
    export: Option<PathBuf>,
    /// Run the experiment on a scenario family instead: a TOML file with an [unknowns] table
    /// (its [templates] and [grid] set the runs), e.g. "the e2 box on my whisker".
    #[arg(long, value_name = "FILE.toml", conflicts_with = "experiment")]
    scenario: Option<String>,
    /// Overrides of the scenario's keys (key=value).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// The recordings to make: clean, or noisy (sensor noise of 5% of each channel's range, plus
    /// process noise). The estimators are not told: they measure the sensor noise on the
    /// recordings.
    #[arg(long, default_value = "clean")]
    variant: String,
    /// Output folder (default: experiment-<EXPERIMENT>-<VARIANT>).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Seed of all randomness.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Particles of the particle filter `pf` in the table; 0 leaves it out. Default: 1000 for the
    /// noisy variant, 0 for the clean one (the filter takes about 8 s per 71 runs at 1000). For
    /// a shape experiment: particles per class of `shape-pf` and `shape-mix` (default 1000).
    #[arg(long, value_name = "N", value_parser = crate::limits::particles_or_none)]
    particles: Option<usize>,
    /// Score the estimators on recordings that start up to S seconds before the approach (a
    /// whole number of milliseconds, drawn per run): the particle filter with the start `t0` as
    /// a further unknown (default particles: 1000), every other method reading the recordings,
    /// cut to the experiment's length, aligned at the contact's onset.
    #[arg(long, value_name = "S")]
    max_delay: Option<f64>,
    /// Transition model of the particle filter: `coarse` (5 segments at 1/3 ms, real time with
    /// 1000 particles) or `fine` (the recording's own chain at 0.1 ms, about 20 times the cost
    /// per particle, calibrated with 4000 particles).
    #[arg(long, value_name = "NAME", default_value = "coarse")]
    pf_model: String,
    /// Also write report.html into the output folder: the tables, the figures and animations of
    /// a few runs, in one page that needs no network (see `vibrissa report`).
    #[arg(long, conflicts_with = "max_delay")]
    report: bool,
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

/// What results.json holds: the evaluation, and what re-simulating its runs needs beyond it
/// (`vibrissa report` reads it back).
#[derive(Debug, Serialize)]
struct Saved<'a> {
    #[serde(flatten)]
    evaluation: &'a Evaluation,
    /// The scenario file's absolute path, for a family given by --scenario.
    scenario_file: Option<PathBuf>,
    /// The overrides of the scenario's keys, in order.
    sets: &'a [String],
    /// The particle filter's transition model.
    pf_model: &'static str,
}

/// Runs the experiment, writes its files and prints the table.
pub fn run(args: &Args) -> Result<()> {
    let shapes = match (&args.shapes, &args.experiment) {
        (Some(file), _) => Some(ShapeFamily::open(file)?),
        (None, Some(name)) => ShapeFamily::builtin(name).transpose()?,
        _ => None,
    };
    if let Some(family) = shapes {
        if !args.sets.is_empty() {
            anyhow::bail!(
                "--set applies to e1, e2 and --scenario; edit a shape family's class files instead"
            );
        }
        if args.max_delay.is_some() || args.report {
            anyhow::bail!(
                "--max-delay and --report apply to e1, e2 and --scenario, not to shape experiments"
            );
        }
        return crate::experiment_shapes::run(crate::experiment_shapes::ShapeArgs {
            family,
            variant: Variant::parse(&args.variant)?,
            seed: args.seed,
            out: args.out.clone(),
            training: args.training,
            runs: args.runs,
            bank: args.bank,
            particles: args.particles,
            whiskers: args.whiskers.as_deref(),
            methods: &args.methods,
            randomise: args.randomise,
            export: args.export.as_deref(),
            format: args.format.format(),
        });
    }
    if args.training.is_some()
        || !args.methods.is_empty()
        || args.runs.is_some()
        || args.bank.is_some()
        || args.whiskers.is_some()
        || args.randomise
        || args.export.is_some()
    {
        anyhow::bail!("--training, --runs, --bank, --whiskers, --method, --randomise and --export apply to shape experiments (e3, --shapes)");
    }
    let family = match (&args.scenario, &args.experiment) {
        (Some(file), _) => Family::open(file, &args.sets)?,
        (None, Some(name)) => {
            Family::builtin(name)?;
            Family::open(name, &args.sets)?
        }
        (None, None) => {
            anyhow::bail!("name an experiment (e1, e2, e3, e3-active) or give --scenario FILE.toml")
        }
    };
    let scenario_file = match &args.scenario {
        Some(file) => Some(
            std::fs::canonicalize(file)
                .with_context(|| format!("cannot find the scenario file `{file}`"))?,
        ),
        None => None,
    };
    let label = Path::new(family.name())
        .file_stem()
        .map_or("scenario".into(), |s| s.to_string_lossy().to_string());
    let variant = Variant::parse(&args.variant)?;
    let pf_model = TransitionModel::from_name(&args.pf_model)
        .map_err(|e| anyhow::anyhow!("--pf-model: {e}"))?;
    if let Some(s) = args.max_delay {
        if !(s.is_finite() && s > 0.0 && s <= 1.0) {
            anyhow::bail!("--max-delay must be a delay in (0, 1] s (got {s})");
        }
        let ms = s * 1e3;
        if (ms - ms.round()).abs() > 1e-6 * ms.max(1.0) {
            anyhow::bail!(
                "--max-delay must be a whole number of milliseconds (got {ms} ms): the runs are \
                 delayed by whole samples"
            );
        }
        if args.particles == Some(0) {
            anyhow::bail!("--particles must be at least 1 with --max-delay (got 0)");
        }
    }
    let out = args.out.clone().unwrap_or_else(|| {
        PathBuf::from(format!(
            "experiment-{}-{}{}",
            label,
            variant.name(),
            if args.max_delay.is_some() {
                "-unknown-start"
            } else {
                ""
            }
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
    if let Some(max_delay) = args.max_delay {
        let particles = args
            .particles
            .unwrap_or(vibrissa_infer::methods::TABLE_PARTICLES);
        let others: Vec<&str> = vibrissa_infer::methods::NAMES
            .iter()
            .copied()
            .filter(|&n| n != "pf")
            .collect();
        let ev = evaluate_unknown_start(
            &family, variant, args.seed, particles, pf_model, max_delay, &others, &progress,
        )?;
        let json = out.join("results.json");
        crate::files::write_atomic(&json, serde_json::to_string_pretty(&ev)?.as_bytes())?;
        eprintln!("[{:6.2} s] done", start.elapsed().as_secs_f64());
        args.format.format().print(&StartReport {
            evaluation: ev,
            files: vec![json],
            seconds: start.elapsed().as_secs_f64(),
        })?;
        return Ok(());
    }
    let particles = args.particles.unwrap_or(match variant {
        Variant::Noisy => vibrissa_infer::methods::TABLE_PARTICLES,
        Variant::Clean => 0,
    });
    let evaluation = evaluate_with(&family, variant, args.seed, particles, pf_model, &progress)?;

    // Files: results.json and the figures.
    let mut files = Vec::new();
    let json = out.join("results.json");
    let saved = Saved {
        evaluation: &evaluation,
        scenario_file,
        sets: &args.sets,
        pf_model: pf_model.name(),
    };
    crate::files::write_atomic(&json, serde_json::to_string_pretty(&saved)?.as_bytes())?;
    files.push(json);
    files.extend(figures(&evaluation, &out)?);
    if args.report {
        eprintln!("[{:6.2} s] report", start.elapsed().as_secs_f64());
        let written = crate::report::write(&out, &crate::report::Selection::Default)?;
        files.push(written.path);
    }
    eprintln!("[{:6.2} s] done", start.elapsed().as_secs_f64());
    args.format.format().print(&Report { evaluation, files })?;
    Ok(())
}

/// The factor and unit in which an unknown is printed.
fn scale_unit(name: &str) -> (f64, &'static str) {
    match name {
        "d" => (1e3, "mm"),
        "t0" => (1e3, "ms"),
        _ => (1.0, "m/s"),
    }
}

/// The printed result of the unknown-start mode.
#[derive(Debug, Serialize)]
struct StartReport {
    #[serde(flatten)]
    evaluation: StartEvaluation,
    /// Files written.
    files: Vec<PathBuf>,
    /// Wall time of the whole command, s.
    seconds: f64,
}

impl Render for StartReport {
    fn render(&self, out: &mut dyn Write) -> io::Result<()> {
        let ev = &self.evaluation;
        writeln!(
            out,
            "experiment {} ({}), seed {}: pf ({} model) with {} particles on {} runs, each recorded from up to {} ms before the approach (t0 unknown)",
            ev.family,
            ev.variant.name(),
            ev.seed,
            ev.model.name(),
            ev.particles,
            ev.runs.len(),
            ev.max_delay * 1e3
        )?;
        let mut t = Table::new(&[
            ("unknown", Align::Left),
            ("MAE", Align::Right),
            ("unit", Align::Left),
            ("90% cover", Align::Right),
        ]);
        for (k, u) in ev.unknowns.iter().enumerate() {
            let (scale, unit) = scale_unit(u);
            t.row(vec![
                u.clone(),
                format!("{:.4}", ev.mae[k] * scale),
                unit.into(),
                format!("{:.0}%", ev.coverage[k] * 100.0),
            ]);
        }
        t.write(out, "  ")?;
        if !ev.methods.is_empty() {
            writeln!(
                out,
                "the other methods, on the same recordings cut to the experiment's length, read \
                 for a lead-in of up to {} ms:",
                ev.max_delay * 1e3
            )?;
            let mut cols = vec![("method", Align::Left)];
            let heads: Vec<String> = ev
                .methods
                .first()
                .map(|m| {
                    (0..m.mae.len())
                        .flat_map(|k| {
                            let (_, unit) = scale_unit(&ev.unknowns[k]);
                            [
                                format!("MAE {} ({unit})", ev.unknowns[k]),
                                format!("90% cover {}", ev.unknowns[k]),
                            ]
                        })
                        .collect()
                })
                .unwrap_or_default();
            cols.extend(heads.iter().map(|h| (h.as_str(), Align::Right)));
            cols.push(("fit (s)", Align::Right));
            let mut m_table = Table::new(&cols);
            for m in &ev.methods {
                let mut row = vec![m.name.clone()];
                for k in 0..m.mae.len() {
                    let (scale, _) = scale_unit(&ev.unknowns[k]);
                    row.push(format!("{:.4}", m.mae[k] * scale));
                    row.push(format!("{:.0}%", m.coverage[k] * 100.0));
                }
                row.push(format!("{:.2}", m.train_seconds));
                m_table.row(row);
            }
            m_table.write(out, "  ")?;
        }
        writeln!(
            out,
            "filtered {:.2} s of data in {:.2} s: real-time factor {:.2}; wall time {:.2} s; files:",
            ev.data_seconds,
            ev.filter_seconds,
            ev.real_time_factor(),
            self.seconds
        )?;
        for f in &self.files {
            writeln!(out, "  {}", f.display())?;
        }
        Ok(())
    }
}

impl Render for Report {
    fn render(&self, out: &mut dyn Write) -> io::Result<()> {
        let ev = &self.evaluation;
        let two = ev.unknowns.len() == 2;
        writeln!(
            out,
            "experiment {} ({}), seed {}: {} runs, {} evaluated; template σ² = {} rad²",
            ev.family,
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
        // The seed paper's figures, for its own experiments only.
        if let [d, rest @ ..] = &ev.paper_mae[..] {
            let mut paper = vec![
                "paper (seed)".to_string(),
                "paper".into(),
                "".into(),
                format!("{:.2}", d * 1e3),
            ];
            if let (true, Some(v)) = (two, rest.first()) {
                paper.push(format!("{v:.3}"));
            }
            t.row(paper);
        }
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
            "noise: recordings made with sensor σ = [{}] (theta01, theta12 rad; m0 N·m; fx, fy N), process {} N·s^½·m^-½",
            ev.noise.sensor.iter().map(|s| sig(*s, 3)).collect::<Vec<_>>().join(", "),
            sig(ev.noise.process, 2)
        )?;
        writeln!(
            out,
            "       estimators measured σ = [{}] on them, and train with process {}",
            ev.estimated_noise
                .sensor
                .iter()
                .map(|s| sig(*s, 3))
                .collect::<Vec<_>>()
                .join(", "),
            sig(ev.estimated_noise.process, 2)
        )?;
        for m in &ev.methods {
            let get = |k: &str| m.settings.iter().find(|(n, _)| n == k).map(|(_, x)| *x);
            if let (Some(steps), Some(diverged), Some(refused)) = (
                get("particle_steps"),
                get("diverged_steps"),
                get("refused_moves"),
            ) {
                writeln!(
                    out,
                    "{}: {steps:.0} particle steps, {diverged:.0} diverged; {refused:.0} moves undone (a moved box the whisker could not follow)",
                    m.name
                )?;
            }
        }
        writeln!(out, "wall time {:.2} s; files:", ev.seconds)?;
        for f in &self.files {
            writeln!(out, "  {}", f.display())?;
        }
        Ok(())
    }
}

/// Draws the experiment's figures into `dir` (PNG and SVG, each appearing whole); returns their
/// paths.
fn figures(ev: &Evaluation, dir: &Path) -> Result<Vec<PathBuf>> {
    let two = ev.unknowns.len() == 2;
    let templates: Vec<usize> = (0..ev.grid.len()).filter(|&k| ev.is_template[k]).collect();
    let mut figs = Vec::new();

    // Fig. 6: theta12 of the templates.
    let sets: Vec<XySet> = templates
        .iter()
        .enumerate()
        .map(|(i, &k)| XySet {
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
            mark: Mark::Line,
            colour: Some(i),
        })
        .collect();
    figs.push((
        "templates".to_string(),
        XyFigure {
            title: "theta12 of the templates (cf. the paper's Fig. 6)".into(),
            x_desc: "t (ms)".into(),
            y_desc: "theta12 (rad)".into(),
            log_y: false,
            columns: 1,
            legend_lower_right: false,
            panels: vec![XyPanel {
                caption: String::new(),
                sets,
            }],
        },
    ));

    // Fig. 7: responsibilities against distance, one panel per speed of the grid for e2.
    let mut speeds: Vec<f64> = Vec::new();
    if two {
        for g in &ev.grid {
            if !speeds.iter().any(|v| (v - g[1]).abs() < 1e-9) {
                speeds.push(g[1]);
            }
        }
        speeds.sort_by(f64::total_cmp);
    }
    let panel = |speed: Option<f64>| XyPanel {
        caption: speed.map_or(String::new(), |v| format!("runs at v = {v:.1} m/s")),
        sets: ev
            .template_params
            .iter()
            .enumerate()
            .map(|(i, p)| XySet {
                label: if two {
                    format!("template d = {:.0} mm, v = {:.1} m/s", p[0] * 1e3, p[1])
                } else {
                    format!("template d = {:.0} mm", p[0] * 1e3)
                },
                points: (0..ev.grid.len())
                    .filter(|&k| speed.is_none_or(|v| (ev.grid[k][1] - v).abs() < 1e-9))
                    .map(|k| (ev.grid[k][0] * 1e3, ev.responsibilities[k][i]))
                    .collect(),
                mark: Mark::LineDots,
                colour: Some(i),
            })
            .collect(),
    };
    let (title, panels) = if two {
        (
            "template responsibilities against d, one panel per speed (cf. the paper's Fig. 7)",
            speeds.iter().map(|&v| panel(Some(v))).collect(),
        )
    } else {
        (
            "template responsibilities against d (cf. the paper's Fig. 7)",
            vec![panel(None)],
        )
    };
    figs.push((
        "responsibilities".to_string(),
        XyFigure {
            title: title.into(),
            x_desc: "d (mm)".into(),
            y_desc: "responsibility".into(),
            log_y: false,
            columns: 3,
            legend_lower_right: false,
            panels,
        },
    ));

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
        let mut sets: Vec<XySet> = chosen
            .iter()
            .filter_map(|n| ev.methods.iter().find(|m| &m.name == n))
            .enumerate()
            .map(|(i, m)| XySet {
                label: m.name.clone(),
                points: m
                    .predictions
                    .iter()
                    .map(|p| (p.truth[u] * f, p.estimate[u].mean * f))
                    .collect(),
                mark: Mark::Dots,
                colour: Some(i),
            })
            .collect();
        let r = ev.ranges[u];
        sets.push(XySet {
            label: "truth".into(),
            points: vec![(r[0] * f, r[0] * f), (r[1] * f, r[1] * f)],
            mark: Mark::Dashed,
            colour: None,
        });
        let fig = if u == 0 { "Figs. 8, 9" } else { "Fig. 10" };
        figs.push((
            format!("estimated-{name}"),
            XyFigure {
                title: format!("estimated against true {name} (cf. the paper's {fig})"),
                x_desc: format!("true {name} ({unit})"),
                y_desc: format!("estimated {name} ({unit})"),
                log_y: false,
                columns: 1,
                legend_lower_right: false,
                panels: vec![XyPanel {
                    caption: String::new(),
                    sets,
                }],
            },
        ));
    }

    // Drawn first, then renamed into place together.
    let mut pending = Vec::new();
    // Calibration of the particle filter: nominal against observed coverage of its intervals.
    if let Some(pf) = ev.methods.iter().find(|m| m.name == "pf") {
        let cal = calibration(pf);
        let levels = vibrissa_infer::evaluate::CALIBRATION_LEVELS;
        let mut sets: Vec<XySet> = cal
            .iter()
            .enumerate()
            .map(|(u, obs)| XySet {
                label: format!("{} (mean ± z·std)", ev.unknowns[u]),
                points: levels
                    .iter()
                    .zip(obs)
                    .map(|(p, o)| (p * 100.0, o * 100.0))
                    .collect(),
                mark: Mark::LineDots,
                colour: Some(u),
            })
            .collect();
        sets.push(XySet {
            label: "calibrated".into(),
            points: vec![(0.0, 0.0), (100.0, 100.0)],
            mark: Mark::Dashed,
            colour: None,
        });
        figs.push((
            "pf_calibration".to_string(),
            XyFigure {
                title: format!(
                    "pf calibration, {} {} ({} runs)",
                    ev.family,
                    ev.variant.name(),
                    pf.predictions.len()
                ),
                x_desc: "nominal coverage (%)".into(),
                y_desc: "observed coverage (%)".into(),
                log_y: false,
                columns: 1,
                legend_lower_right: true,
                panels: vec![XyPanel {
                    caption: String::new(),
                    sets,
                }],
            },
        ));
    }
    for (name, fig) in &figs {
        pending.extend(plot::render_xy(&dir.join(format!("{name}.png")), fig)?);
    }
    let mut files = Vec::new();
    for (path, file) in pending {
        file.commit()?;
        files.push(path);
    }
    Ok(files)
}
