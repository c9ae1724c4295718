//! `vibrissa estimate`: distance (and speed) of the object from recorded time series.
//!
//! Reads one or more contract CSV files (with the metadata of their JSON sidecars, where there
//! are any), checks them against the experiment (151 samples at 1 kHz), trains the chosen method once (on the templates, or on its simulated training runs),
//! and prints one estimate per file in the contract's JSON form.

use crate::output::{sig, FormatArgs, Render};
use anyhow::{bail, Context, Result};
use serde::Serialize;
use serde_json::{json, Map, Value};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;
use vibrissa_infer::experiment::{SAMPLES, SAMPLE_RATE};
use vibrissa_infer::{methods, training_for, Estimate, Experiment, Variant, CHANNELS};
use vibrissa_io::series::Series;

/// Arguments of `vibrissa estimate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    // Fields are read by the pf path too (crate::estimate_pf).
    /// The experiment the series come from: e1 or e2.
    #[arg(long, value_name = "EXPERIMENT", required_unless_present = "list")]
    pub(crate) experiment: Option<String>,
    /// The estimator (see --list).
    #[arg(long, value_name = "NAME", required_unless_present = "list")]
    pub(crate) method: Option<String>,
    /// Time-series CSV files in the contract's columns (t, theta01, theta12 required).
    #[arg(long, value_name = "FILE.csv", num_args = 1.., required_unless_present = "list")]
    pub(crate) obs: Vec<PathBuf>,
    /// Which runs to train on: clean or noisy.
    #[arg(long, default_value = "clean")]
    pub(crate) variant: String,
    /// Seed of the training runs.
    #[arg(long, default_value_t = 1)]
    pub(crate) seed: u64,
    /// List the methods and exit.
    #[arg(long)]
    list: bool,
    /// pf: number of particles.
    #[arg(long, default_value_t = 1000, value_name = "N")]
    pub(crate) particles: usize,
    /// pf: write the posterior (mean, std, 90% interval of every unknown, and the effective sample
    /// size) at every sample to this CSV, and its plot beside it (same name, .png). One file only.
    #[arg(long, value_name = "FILE.csv")]
    pub(crate) trace: Option<PathBuf>,
    /// pf: the recording may start up to this many seconds before the approach (the start delay
    /// `t0` becomes an unknown, uniform on [0, MAX]).
    #[arg(long, value_name = "SECONDS", default_value_t = 0.0)]
    pub(crate) max_delay: f64,
    /// pf: transition model, `coarse` (5 segments at 1/3 ms, real time with 1000 particles) or
    /// `fine` (the recording's chain at 0.1 ms: about 20 times the cost, for 4000 particles).
    #[arg(long, value_name = "NAME", default_value = "coarse")]
    pub(crate) pf_model: String,
    /// pf: a uniform prior NAME=LO:HI for an unknown of the object (d, v, t0, size, mu; SI), which
    /// makes a fixed parameter unknown (size: the box's side, default 0.01 m; mu: its friction
    /// coefficient, default 0) or narrows or widens a free one. Repeatable.
    #[arg(long, value_name = "NAME=LO:HI")]
    pub(crate) prior: Vec<String>,
    /// pf: observed channels, comma-separated (theta01, theta12, m0, fx, fy).
    #[arg(long, value_name = "LIST", value_delimiter = ',')]
    pub(crate) channels: Vec<String>,
    /// pf: mix proposals from this method's estimates into the initial particles (hypothesis
    /// injection; a fraction of 0.5 of the particles).
    #[arg(long, value_name = "METHOD")]
    pub(crate) inject: Option<String>,
    #[command(flatten)]
    pub(crate) format: FormatArgs,
}

/// One file's estimate.
#[derive(Debug, Serialize)]
struct Row {
    /// The contract's object.
    #[serde(flatten)]
    value: Map<String, Value>,
}

/// One file's path, its named estimates and the seconds the estimate took.
pub(crate) type FileEstimate = (PathBuf, Vec<(String, Estimate)>, f64);

/// Estimates for one or more files.
#[derive(Debug, Serialize)]
struct Report {
    rows: Vec<FileEstimate>,
    method: String,
    train_seconds: f64,
    train_runs: usize,
}

impl Render for Report {
    fn render(&self, out: &mut dyn Write) -> io::Result<()> {
        writeln!(
            out,
            "method {} (trained on {} runs in {:.2} s)",
            self.method, self.train_runs, self.train_seconds
        )?;
        for (file, est, secs) in &self.rows {
            let parts: Vec<String> = est
                .iter()
                .map(|(n, e)| match n.as_str() {
                    "d" => format!(
                        "d = {:.2} mm ± {:.2} (90%: {:.2}…{:.2})",
                        e.mean * 1e3,
                        e.std * 1e3,
                        e.ci90[0] * 1e3,
                        e.ci90[1] * 1e3
                    ),
                    _ => format!(
                        "{n} = {} ± {} (90%: {}…{})",
                        sig(e.mean, 3),
                        sig(e.std, 2),
                        sig(e.ci90[0], 3),
                        sig(e.ci90[1], 3)
                    ),
                })
                .collect();
            writeln!(
                out,
                "{}: {} [{:.3} ms]",
                file.display(),
                parts.join(", "),
                secs * 1e3
            )?;
        }
        Ok(())
    }
}

/// Lists the methods.
#[derive(Debug, Serialize)]
struct List {
    methods: Vec<Value>,
}

impl Render for List {
    fn render(&self, out: &mut dyn Write) -> io::Result<()> {
        for m in &self.methods {
            writeln!(
                out,
                "{:16} {:6} {}",
                m["name"].as_str().unwrap_or(""),
                m["budget"].as_str().unwrap_or(""),
                m["description"].as_str().unwrap_or("")
            )?;
        }
        Ok(())
    }
}

/// Reads, trains, estimates and prints.
pub fn run(args: &Args) -> Result<()> {
    let format = args.format.format();
    if args.list {
        let list = List {
            methods: methods::NAMES
                .iter()
                .map(|n| {
                    let m = methods::by_name(n).expect("listed");
                    json!({"name": n, "budget": m.budget().name(),
                           "channels": m.channels().iter().map(|c| CHANNELS[*c]).collect::<Vec<_>>(),
                           "description": methods::describe(n)})
                })
                .collect(),
        };
        return Ok(format.print(&list)?);
    }
    let experiment = Experiment::parse(args.experiment.as_deref().unwrap_or_default())?;
    let variant = Variant::parse(&args.variant)?;
    if args.method.as_deref() == Some("pf") {
        return crate::estimate_pf::run(args, experiment, variant);
    }
    if args.trace.is_some()
        || args.inject.is_some()
        || !args.channels.is_empty()
        || !args.prior.is_empty()
    {
        bail!("--trace, --inject, --channels and --prior apply to --method pf only");
    }
    let mut method = methods::by_name(args.method.as_deref().unwrap_or_default())?;

    // Read and check every file before training.
    let needs = method.channels();
    let obs = args
        .obs
        .iter()
        .map(|f| read_obs(f, &needs, method.name()))
        .collect::<Result<Vec<_>>>()?;

    // Train once.
    let t0 = Instant::now();
    eprintln!(
        "training {} ({} budget)…",
        method.name(),
        method.budget().name()
    );
    let training = training_for(experiment, variant, method.as_ref(), args.seed)?;
    method.fit(&training)?;
    let train_seconds = t0.elapsed().as_secs_f64();
    eprintln!(
        "trained on {} simulated runs in {:.2} s",
        training.samples.len() + training.calibration.len(),
        train_seconds
    );

    let mut rows = Vec::new();
    for (file, o) in args.obs.iter().zip(&obs) {
        let t = Instant::now();
        let est = method
            .predict(o)
            .with_context(|| format!("estimating from `{}`", file.display()))?;
        let secs = t.elapsed().as_secs_f64();
        let named = experiment
            .unknowns()
            .iter()
            .map(|n| n.to_string())
            .zip(est)
            .collect();
        rows.push((file.clone(), named, secs));
    }
    let report = Report {
        rows,
        method: method.name().into(),
        train_seconds,
        train_runs: training.samples.len() + training.calibration.len(),
    };
    match format {
        crate::output::Format::Human => format.print(&report)?,
        crate::output::Format::Json => print_json(&report, args.obs.len() > 1)?,
    }
    Ok(())
}

/// The contract's estimate objects: one, or JSON Lines with `"file"` for several files.
pub(crate) fn print_json_rows(rows: &[FileEstimate], method: &str, lines: bool) -> Result<()> {
    print_json(
        &Report {
            rows: rows.to_vec(),
            method: method.into(),
            train_seconds: 0.0,
            train_runs: 0,
        },
        lines,
    )
}

/// The contract's objects of a report.
fn print_json(report: &Report, lines: bool) -> Result<()> {
    let stdout = io::stdout();
    let mut out = stdout.lock();
    for (file, est, secs) in &report.rows {
        let mut obj = Map::new();
        if lines {
            obj.insert("file".into(), json!(file.display().to_string()));
        }
        for (n, e) in est {
            obj.insert(
                n.clone(),
                json!({"mean": e.mean, "std": e.std, "ci90": e.ci90}),
            );
        }
        obj.insert("method".into(), json!(report.method));
        obj.insert("seconds".into(), json!(secs));
        let row = Row { value: obj };
        if lines {
            serde_json::to_writer(&mut out, &row)?;
        } else {
            serde_json::to_writer_pretty(&mut out, &row)?;
        }
        writeln!(out)?;
    }
    out.flush()?;
    Ok(())
}

/// Reads a recorded series with the metadata of its sidecar (`run.json` beside `run.csv`), if it
/// has one. What is wrong with the sidecar is a warning on standard error, never an error: the
/// CSV alone is always enough.
pub(crate) fn read_recording(file: &Path) -> Result<Series> {
    let (series, warnings) = vibrissa_io::series::read_csv_with_sidecar(file)
        .with_context(|| format!("cannot read `{}`", file.display()))?;
    for w in warnings {
        eprintln!("warning: {w}");
    }
    Ok(series)
}

/// Reads one observation file as channel-major `[CHANNELS][SAMPLES]` (missing channels empty).
fn read_obs(file: &Path, needs: &[usize], method: &str) -> Result<Vec<Vec<f64>>> {
    let series = read_recording(file)?;
    let name = file.display();
    let required = series
        .require(&["t", "theta01", "theta12"])
        .with_context(|| format!("`{name}` lacks a required column (t, theta01, theta12)"))?;
    let t = required[0];
    if t.len() != SAMPLES {
        bail!(
            "`{name}` has {} samples; the experiments' runs have {SAMPLES} (150 ms at 1 kHz)",
            t.len()
        );
    }
    let period = 1.0 / SAMPLE_RATE;
    let regular = t
        .iter()
        .enumerate()
        .all(|(k, &x)| (x - k as f64 * period).abs() < 1e-6);
    if !regular {
        bail!("`{name}`: t must run from 0 in steps of 1 ms (1 kHz), as in the experiments");
    }
    let mut obs = Vec::with_capacity(CHANNELS.len());
    for (c, ch) in CHANNELS.iter().enumerate() {
        match series.column(ch) {
            Some(v) => {
                if needs.contains(&c) {
                    if let Some(k) = v.iter().position(|x| !x.is_finite()) {
                        bail!("`{name}`: column {ch} has a non-finite value in row {}", k + 1);
                    }
                }
                obs.push(v.to_vec());
            }
            None if needs.contains(&c) => bail!(
                "method {method} needs column {ch}, which `{name}` lacks (the template method uses theta12 alone)"
            ),
            None => obs.push(Vec::new()),
        }
    }
    Ok(obs)
}
