//! `vibrissa estimate`: distance (and speed) of the object from recorded time series.
//!
//! Reads one or more contract CSV files at any constant sample rate and length, trains the chosen
//! method on runs of the scenario family (`--scenario FILE.toml`, or the built-in `--experiment
//! e1|e2`) simulated at the files' rate and length (once per distinct timing), and prints one
//! estimate per file in the contract's JSON form, named by the family's unknowns.

use crate::files::Pending;
use crate::output::{sig, FormatArgs, Render};
use crate::plot::{Axis, Curve, Panel};
use anyhow::{anyhow, bail, Context, Result};
use serde::Serialize;
use serde_json::{json, Map, Value};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use vibrissa_infer::check::{self, Check};
use vibrissa_infer::{batch, lead_in};
use vibrissa_infer::{
    methods, Estimate, Family, Method, Reader, Recording, Trained, Variant, CHANNELS,
};
use vibrissa_io::scenario::WhiskerSources;

/// Arguments of `vibrissa estimate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    // Fields are read by the pf path too (crate::estimate_pf).
    /// The built-in experiment the series come from: e1 or e2 (shorthand for --scenario e1|e2).
    #[arg(long, value_name = "EXPERIMENT", conflicts_with = "scenario")]
    pub(crate) experiment: Option<String>,
    /// The scenario family the series come from: a TOML scenario file with an [unknowns] table
    /// (or naming an experiment), e.g. the output of `vibrissa calibrate`.
    #[arg(long, value_name = "FILE.toml")]
    pub(crate) scenario: Option<String>,
    /// Overrides of the scenario's keys (key=value), applied before anything is trained.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub(crate) sets: Vec<String>,
    /// The estimator (see --list).
    #[arg(long, value_name = "NAME", required_unless_present_any = ["list", "shapes"])]
    pub(crate) method: Option<String>,
    /// Which object struck the whiskers: the class posterior and pose for a shape family, the
    /// built-in `e3` or a TOML file whose [classes] table names each class's scenario file.
    #[arg(long, value_name = "e3|FILE.toml", conflicts_with_all = ["experiment", "scenario"])]
    pub(crate) shapes: Option<String>,
    /// Shape families: the whiskers read, by name joined by `+` (default: all of the family's).
    #[arg(long, value_name = "NAMES", requires = "shapes")]
    pub(crate) whiskers: Option<String>,
    /// Shape families: training runs per class (default 800; 60 for shape-pf, which reads few).
    #[arg(long, value_name = "N", requires = "shapes", value_parser = crate::limits::training)]
    pub(crate) training: Option<usize>,
    /// Shape families with shape-bank: noise-free runs per class in its bank (default 3200).
    #[arg(long, value_name = "N", requires = "shapes", value_parser = crate::limits::bank)]
    pub(crate) bank: Option<usize>,
    /// Give the scenario (every whisker of a shape family) the whisker, chain and sensors of
    /// this scenario file of one whisker (one that `vibrissa calibrate` fitted to labelled
    /// strikes of your whisker, say), with its calibration record, so that the estimators train
    /// on your whisker in this experiment: calibrated on the `e2` box, read pegs or shapes.
    /// NAME=FILE.toml gives one whisker of the array its own (repeat for each whisker
    /// calibrated on its own strikes; it replaces a plain FILE.toml for that whisker). Contact
    /// is stepped as finely as in the most finely fitted file (`contact_substeps`: calibration
    /// fits at 20 µs), at the scenario's own time step.
    #[arg(long, value_name = "[NAME=]FILE.toml")]
    pub(crate) whisker_from: Vec<String>,
    /// Time-series CSV files in the contract's columns (t, theta01, theta12 required).
    #[arg(long, value_name = "FILE.csv", num_args = 1.., required_unless_present = "list")]
    pub(crate) obs: Vec<PathBuf>,
    /// The recordings' sensor noise: `auto` (estimated from the recordings, for every channel the
    /// scenario's [sensor_noise] does not state), `none` (clean recordings), or CHANNEL=SIGMA,...
    /// (SI; the channels not named as with auto).
    #[arg(long, value_name = "auto|none|CH=SIGMA,...", default_value = "auto")]
    pub(crate) noise: String,
    /// Deprecated and ignored: the noise is estimated from the recordings (see --noise).
    #[arg(long, value_name = "clean|noisy", hide = true)]
    pub(crate) variant: Option<String>,
    /// Train on runs whose whisker, sensor gains and chain are drawn around the scenario's
    /// (modulus, density and damping within a factor 0.74–1.35, half of them with a compliant
    /// follicle, half tapered, gains within 5%, half with 0.5–3 times the segments, half with
    /// the seed paper's stiffness rule; three times the training runs; contact stepped at 20 µs
    /// unless the file names `contact_substeps`, as a real whisker's or another engine's strikes
    /// are converged): estimates that hold, with wider intervals, on a whisker known only
    /// roughly, recorded by another chain. On a
    /// calibrated scenario (the output of `calibrate`) the draws are narrow instead: modulus,
    /// density, damping and follicle within a factor e^±0.1, gains within 2%, the chain as fitted
    /// (what calibration leaves uncertain: intervals that hold after calibration; the filter
    /// then keeps the fitted sensors and chain and varies the whisker alone). Not for
    /// `template` and `template-interp` (they keep the scenario's own templates); best with
    /// `krr-invariant`, which reads only what the prior leaves unchanged. The filter (`pf`)
    /// instead entertains 64 whiskers drawn alike (the scenario's and `--alternatives` others)
    /// and carries the sensors' gains and offsets as unknowns, reported as
    /// `sensors.<channel>.gain` and `.offset` (angle gains sd 0.5, the base wrench's common
    /// scale and each wrench sensor sd 5%, offsets sd 5 noise levels).
    /// On a calibrated scenario (a file written by `vibrissa calibrate`) this is the default.
    #[arg(long)]
    pub(crate) randomise: bool,
    /// Train on the scenario's whisker alone, even for a calibrated scenario (whose methods
    /// otherwise train over what its calibration leaves uncertain).
    #[arg(long, conflicts_with = "randomise")]
    pub(crate) no_randomise: bool,
    /// For recordings of an array of whiskers (columns `c1.theta01`, ...): the whisker whose
    /// columns are read. Required when the scenario holds `[[whiskers]]`: the methods then train
    /// on that whisker where the array mounts it (pf only on one at the origin).
    #[arg(long, value_name = "NAME")]
    pub(crate) whisker: Option<String>,
    /// Seed of the training runs.
    #[arg(long, default_value_t = 1)]
    pub(crate) seed: u64,
    /// List the methods and exit.
    #[arg(long)]
    list: bool,
    /// pf: number of particles [default: 1000, or 4000 with --randomise]; shape-pf and
    /// shape-mix: particles per class [default: 1000].
    #[arg(long, value_name = "N", value_parser = crate::limits::particles)]
    pub(crate) particles: Option<usize>,
    /// pf: independent filters the particles are split among, each with its own random streams,
    /// merged at the end so that the intervals hold the spread between them (each keeps at
    /// least 1000 particles: 4000 run as 3 islands, 1000 as one) [default: 3, or 1 for a pooled
    /// batch, which filters again as 3 any recording on which its favourite whisker lost every
    /// particle].
    #[arg(long, value_name = "N", value_parser = crate::limits::islands)]
    pub(crate) islands: Option<usize>,
    /// pf with --randomise: whiskers entertained besides the scenario's.
    #[arg(long, default_value_t = vibrissa_infer::pf::ALTERNATIVES, value_name = "N",
          value_parser = crate::limits::alternatives)]
    pub(crate) alternatives: usize,
    /// pf: the recordings come from one whisker, which the filter learns from all of them
    /// together: it filters the batch, draws the whiskers it entertains around those the whole
    /// batch favours, and filters again (--pool-rounds times; no labels needed). For a whisker
    /// known only roughly (--randomise, or a scenario the recordings defy); at least 2
    /// recordings. The default for a batch of 5 or more when the filter entertains several
    /// whiskers and the scenario is not calibrated.
    #[arg(long, conflicts_with = "no_pool")]
    pub(crate) pool: bool,
    /// pf: filter every recording alone, even where pooling is the default (a batch that holds
    /// recordings of different whiskers).
    #[arg(long)]
    pub(crate) no_pool: bool,
    /// pf --pool: rounds of pooling after the first filtering of the batch.
    #[arg(long, default_value_t = vibrissa_infer::pf::pool::ROUNDS, value_name = "N")]
    pub(crate) pool_rounds: usize,
    /// pf --pool: the rounds before the last filter at most this many recordings, spread through
    /// the batch, while they search for its whisker; the last round filters every recording.
    #[arg(long, default_value_t = vibrissa_infer::pf::pool::SEARCH_RECORDINGS, value_name = "N")]
    pub(crate) pool_search: usize,
    /// pf --pool: each recording learns its joint angles' gains alone, as when the angles of the
    /// batch's recordings were read in different ways; by default a batch of 10 or more learns
    /// them together (they stand for the recording's chain and angle tracker, which its strikes
    /// share).
    #[arg(long)]
    pub(crate) no_pool_gains: bool,
    /// pf: write the posterior (mean, std, 90% interval of every unknown, and the effective sample
    /// size) at every sample to this CSV, and its plot beside it (same name, .png). One file only.
    #[arg(long, value_name = "FILE.csv")]
    pub(crate) trace: Option<PathBuf>,
    /// The recordings may start up to this many seconds before the approach. pf: the start delay
    /// `t0` becomes an unknown, uniform on [0, MAX]; other methods read series aligned at the
    /// contact's onset. Without it, a recording whose contact begins later than any run of the
    /// scenario makes contact is read so, with a warning.
    #[arg(long, value_name = "SECONDS", default_value_t = 0.0)]
    pub(crate) max_delay: f64,
    /// pf: transition model, `coarse` (5 segments at 1/3 ms, real time with 1000 particles) or
    /// `fine` (the recording's chain at 0.1 ms: about 20 times the cost, for 4000 particles).
    #[arg(long, value_name = "NAME", default_value = "coarse")]
    pub(crate) pf_model: String,
    /// pf: a uniform prior NAME=LO:HI for an unknown of the object (d, v, t0, size, mu; SI), which
    /// makes a fixed parameter unknown (size: the box's side, default 0.01 m; mu: its friction
    /// coefficient, default 0) or narrows or widens a free one; LO = HI fixes it at that value
    /// (then not estimated, nor reported). Repeatable.
    #[arg(long, value_name = "NAME=LO:HI")]
    pub(crate) prior: Vec<String>,
    /// pf: observed channels, comma-separated (theta01, theta12, m0, fx, fy).
    #[arg(long, value_name = "LIST", value_delimiter = ',')]
    pub(crate) channels: Vec<String>,
    /// pf: mix proposals from this method's estimates into the initial particles (hypothesis
    /// injection; a fraction of 0.5 of the particles).
    #[arg(long, value_name = "METHOD")]
    pub(crate) inject: Option<String>,
    /// Check each recording against the scenario at its estimate: the scenario is simulated there
    /// and each channel's residual compared with the sensor noise (a warning when the scenario
    /// does not explain the recording; `"check"` in the JSON).
    #[arg(long)]
    pub(crate) check: bool,
    /// With --check: draw the recording, the simulation at the estimate and the residual, one
    /// panel per channel, to this PNG (one recording only).
    #[arg(long, value_name = "FILE.png")]
    pub(crate) check_plot: Option<PathBuf>,
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

/// One file's estimate.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct FileEstimate {
    /// The recording.
    pub file: PathBuf,
    /// Its estimates, named by unknown.
    pub estimates: Vec<(String, Estimate)>,
    /// Seconds the estimate took.
    pub seconds: f64,
    /// The sensor noise the method used per channel it reads, SI.
    pub noise: Vec<(String, f64)>,
    /// The particle filter's own counts (particles, resamplings, particle steps, diverged
    /// steps, moves undone, misfit); empty for other methods.
    pub filter: Vec<(&'static str, f64)>,
}

/// Estimates for one or more files.
#[derive(Debug, Serialize)]
struct Report {
    rows: Vec<FileEstimate>,
    method: String,
    train_seconds: f64,
    train_runs: usize,
    /// With `--check`: each row's model check (`None`: not checked, or it could not be).
    checks: Vec<Option<Check>>,
}

impl Render for Report {
    fn render(&self, out: &mut dyn Write) -> io::Result<()> {
        writeln!(
            out,
            "method {} (trained on {} runs in {:.2} s)",
            self.method, self.train_runs, self.train_seconds
        )?;
        for row in &self.rows {
            let (file, est, secs) = (&row.file, &row.estimates, row.seconds);
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
        render_checks(out, &self.rows, &self.checks)?;
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
    if let Some(spec) = &args.shapes {
        return crate::estimate_shapes::run(args, spec);
    }
    // Clap lets these through beside --experiment or --scenario (which --shapes conflicts with).
    let shape_only = [
        ("--whiskers", args.whiskers.is_some()),
        ("--training", args.training.is_some()),
        ("--bank", args.bank.is_some()),
    ];
    if let Some((name, _)) = shape_only.iter().find(|(_, given)| *given) {
        bail!(
            "{name} is for shape families (--shapes e3|FILE.toml), not for --experiment or \
             --scenario"
        );
    }
    // For an array's recordings, the named whisker at its place in the array.
    let family = family_of(args)?.for_whisker(
        args.whisker.as_deref(),
        args.method.as_deref() == Some("pf"),
    )?;
    if let Some(v) = &args.variant {
        Variant::parse(v)?;
        eprintln!(
            "warning: --variant is deprecated and ignored: the sensor noise is estimated from the \
             recordings (state it with --noise CHANNEL=SIGMA,... or --noise none for clean ones)"
        );
    }
    let stated = stated_noise(&family, &args.noise)?;
    // A fitted whisker is known only as well as its fit: on a calibrated scenario every method
    // trains over what the calibration leaves uncertain, unless told not to.
    let randomise = args.randomise || (family.is_calibrated() && !args.no_randomise);
    let family = family.for_method(randomise, args.method.as_deref().unwrap_or_default())?;
    if family.is_calibrated() && randomise && !args.randomise {
        let fitted = family.around().is_some_and(|a| a.is_fitted());
        let how = if args.method.as_deref() == Some("pf") {
            // The filter holds the fitted gains; its alternatives come from the narrow prior.
            "the filter's alternative whiskers from a narrow prior around the fitted one"
        } else if fitted {
            "whiskers drawn from the fit's standard errors and correlations"
        } else {
            "a narrow prior: the file records no correlations; calibrate again to record them"
        };
        eprintln!(
            "the scenario is calibrated: training over what its calibration leaves uncertain \
             ({how}); --no-randomise trains on the fitted whisker alone"
        );
    }
    if args.method.as_deref() == Some("pf") {
        check_arguments(args)?;
        return crate::estimate_pf::run(args, &family, &stated);
    }
    check_arguments(args)?;
    if args.trace.is_some()
        || args.inject.is_some()
        || !args.channels.is_empty()
        || !args.prior.is_empty()
    {
        bail!("--trace, --inject, --channels and --prior apply to --method pf only");
    }
    if args.pool || args.no_pool || args.no_pool_gains {
        bail!(
            "--pool, --no-pool and --no-pool-gains apply to --method pf only (the filter learns \
             the whisker)"
        );
    }
    let name = args.method.as_deref().unwrap_or_default();
    let probe = methods::by_name(name)?;

    // Read and check every file before training.
    let needs = probe.channels();
    let recordings = args
        .obs
        .iter()
        .map(|f| {
            read_recording(
                f,
                &needs,
                Reader::Method(probe.name()),
                args.whisker.as_deref(),
            )
        })
        .collect::<Result<Vec<_>>>()?;
    check_sample_rates(&family, &args.obs, &recordings)?;
    warn_of_units(&family, &args.obs, &recordings, &needs)?;

    // The sensor noise of every recording, then training once per distinct timing, noise
    // level and lead-in, on the family's runs at that rate and length with that noise.
    let levels = noise_levels(&args.obs, &recordings, &needs, &stated)?;
    let names: Vec<String> = args.obs.iter().map(|f| f.display().to_string()).collect();
    for w in vibrissa_infer::batch::without_strikes(&names, &recordings, &levels, &needs) {
        eprintln!("warning: {w}");
    }
    let leads = lead_ins(args.max_delay, &family, &args.obs, &recordings, &levels)?;
    // A scenario that is neither calibrated nor randomised, which most of the recordings defy
    // at their estimates, is not their whisker: estimate again on whiskers drawn around it.
    let mut trained = Trained::default();
    let (family, estimates) = batch::discriminative(
        &family,
        &names,
        &recordings,
        &levels,
        &leads,
        name,
        args.seed,
        !args.randomise && !args.no_randomise,
        &batch::COMMAND_LINE,
        &mut trained,
        &mut |m| eprintln!("{m}"),
    )?;
    let mut rows = Vec::new();
    let mut checks = Vec::new();
    let mut figure = None;
    for ((((file, rec), level), &lead), (est, secs)) in args
        .obs
        .iter()
        .zip(&recordings)
        .zip(&levels)
        .zip(&leads)
        .zip(estimates)
    {
        if args.check {
            let point: Vec<f64> = est.iter().map(|e| e.mean).collect();
            let c = check_recording(&family.nominal(), file, rec, &point, level, &needs, lead);
            if let (Some(c), Some(png)) = (&c, &args.check_plot) {
                figure = Some(draw_check(png, file, rec, c)?);
            }
            checks.push(c);
        }
        rows.push(FileEstimate {
            file: file.clone(),
            estimates: family.named(est),
            seconds: secs,
            noise: named_noise(level, &needs),
            filter: Vec::new(),
        });
    }
    ensure_finite(&rows, probe.name())?;
    let report = Report {
        rows,
        method: probe.name().into(),
        train_seconds: trained.seconds,
        train_runs: trained.runs,
        checks,
    };
    match format {
        crate::output::Format::Human => format.print(&report)?,
        crate::output::Format::Json => print_json(&report, args.obs.len() > 1)?,
    }
    if let (Some(f), Some(png)) = (figure, &args.check_plot) {
        f.commit()?;
        eprintln!("wrote {}", png.display());
    }
    Ok(())
}

/// Refuses to print estimates that are not numbers (a method that could not read a recording,
/// say with a stated noise level so large that every candidate is equally likely): the error
/// names the file, the unknown and what to check, and nothing is printed.
pub(crate) fn ensure_finite(rows: &[FileEstimate], method: &str) -> Result<()> {
    for row in rows {
        for (name, e) in &row.estimates {
            let numbers = [e.mean, e.std, e.ci90[0], e.ci90[1]];
            if numbers.iter().any(|x| !x.is_finite()) {
                bail!(
                    "{method} could not estimate `{name}` from `{}` (mean {}, std {}, 90% \
                     interval {}…{}): check the recording and the noise levels it was read \
                     with ({})",
                    row.file.display(),
                    e.mean,
                    e.std,
                    e.ci90[0],
                    e.ci90[1],
                    row.noise
                        .iter()
                        .map(|(c, s)| format!("{c} {s:.3e}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                );
            }
        }
    }
    Ok(())
}

/// The contract's estimate objects: one, or JSON Lines with `"file"` for several files.
pub(crate) fn print_json_rows(
    rows: &[FileEstimate],
    checks: &[Option<Check>],
    method: &str,
    lines: bool,
) -> Result<()> {
    print_json(
        &Report {
            rows: rows.to_vec(),
            method: method.into(),
            train_seconds: 0.0,
            train_runs: 0,
            checks: checks.to_vec(),
        },
        lines,
    )
}

/// The model checks of `rows` as text (see `--check`).
pub(crate) fn render_checks(
    out: &mut dyn Write,
    rows: &[FileEstimate],
    checks: &[Option<Check>],
) -> io::Result<()> {
    for (row, check) in rows.iter().zip(checks) {
        if let Some(c) = check {
            writeln!(
                out,
                "check of {}: {} (the residual's robust spread / noise level, its lag-1 \
                 correlation; at most {} is explained)",
                row.file.display(),
                if c.explained {
                    "explained by the scenario"
                } else {
                    "NOT explained by the scenario"
                },
                check::LIMIT
            )?;
            for ch in &c.channels {
                writeln!(
                    out,
                    "  {:8} {:>6.2}  {:>5.2}  (spread {}, RMS {}, noise {})",
                    ch.channel,
                    ch.ratio,
                    ch.lag1,
                    sig(ch.spread, 3),
                    sig(ch.rms, 3),
                    sig(ch.noise, 3)
                )?;
            }
        }
    }
    Ok(())
}

/// Refuses `--check-plot` without `--check` or with several recordings, and a figure path that
/// is not a PNG, before anything is trained.
fn check_arguments(args: &Args) -> Result<()> {
    if args.check_plot.is_some() && !args.check {
        bail!("--check-plot draws the check: give --check as well");
    }
    if args.check_plot.is_some() && args.obs.len() != 1 {
        bail!(
            "--check-plot draws one recording: give one --obs file (not {})",
            args.obs.len()
        );
    }
    if let Some(png) = &args.check_plot {
        crate::plot::check_png(png)?;
        crate::files::check_folder(png, "--check-plot")?;
    }
    Ok(())
}

/// The contract's objects of a report.
fn print_json(report: &Report, lines: bool) -> Result<()> {
    let stdout = io::stdout();
    let mut out = stdout.lock();
    for (k, row) in report.rows.iter().enumerate() {
        let obj = vibrissa_infer::contract::EstimateRow {
            file: lines.then(|| row.file.display().to_string()),
            class: Vec::new(),
            estimates: row.estimates.clone(),
            method: report.method.clone(),
            seconds: row.seconds,
            noise: row.noise.clone(),
            filter: row.filter.clone(),
            check: report.checks.get(k).cloned().flatten(),
            misfit: None,
        }
        .to_json();
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

/// The scenario family of `--scenario` or `--experiment` (one of them is required).
pub(crate) fn family_of(args: &Args) -> Result<Family> {
    let spec = match (&args.scenario, &args.experiment) {
        (Some(s), _) => s.as_str(),
        (None, Some(e)) => {
            if vibrissa_io::scenario::builtin(e).is_none() {
                bail!(
                    "unknown experiment `{e}`: choose one of {} (or give a scenario file with \
                     --scenario)",
                    vibrissa_io::scenario::BUILTINS.join(", ")
                );
            }
            e.as_str()
        }
        (None, None) => bail!(
            "say what the recordings are: --scenario FILE.toml (a scenario with [unknowns]) or \
             --experiment e1|e2"
        ),
    };
    let whisker = whisker_source(args)?;
    Ok(Family::open_adopting(
        spec,
        None,
        &args.sets,
        whisker.as_ref(),
    )?)
}

/// The scenarios named by `--whisker-from`, read, if any.
pub(crate) fn whisker_source(args: &Args) -> Result<Option<WhiskerSources>> {
    if args.whisker_from.is_empty() {
        return Ok(None);
    }
    let sources = WhiskerSources::read(&args.whisker_from)
        .with_context(|| format!("--whisker-from {}", args.whisker_from.join(" ")))?;
    Ok(Some(sources))
}

/// Checks `--trace`, if given: one `--obs` file, a `.csv` name, a folder that exists.
pub(crate) fn check_trace_file(args: &Args) -> Result<()> {
    if let Some(trace) = &args.trace {
        if args.obs.len() != 1 {
            bail!(
                "--trace takes exactly one --obs file (got {})",
                args.obs.len()
            );
        }
        if crate::files::extension(trace).as_deref() != Some("csv") {
            bail!("--trace must name a .csv file (got `{}`)", trace.display());
        }
        crate::files::check_folder(trace, "--trace")?;
    }
    Ok(())
}

/// The sensor noise the recordings are taken to have per channel of [`CHANNELS`]: the
/// scenario's stated channels, overridden by `--noise` (`auto`: none; `none`: every channel 0;
/// `CHANNEL=SIGMA,...`: those channels). `None`: estimated from the recordings.
pub(crate) fn stated_noise(family: &Family, noise: &str) -> Result<[Option<f64>; 5]> {
    let given =
        vibrissa_infer::noise::parse_statement(noise).map_err(|e| anyhow!("--noise: {e}"))?;
    let mut stated = family.stated_noise();
    for (c, g) in given.iter().enumerate() {
        if g.is_some() {
            stated[c] = *g;
        }
    }
    Ok(stated)
}

/// The sensor noise level of every recording on the channels `needs` (see
/// [`vibrissa_infer::recording::batch_noise`]), with its warnings and summary on standard error.
pub(crate) fn noise_levels(
    files: &[PathBuf],
    recordings: &[Recording],
    needs: &[usize],
    stated: &[Option<f64>; 5],
) -> Result<Vec<[f64; 5]>> {
    let names: Vec<String> = files.iter().map(|f| f.display().to_string()).collect();
    let report = vibrissa_infer::recording::batch_noise(
        &names,
        recordings,
        needs,
        stated,
        "--noise CHANNEL=SIGMA,...",
    )?;
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    eprintln!("{}", report.summary);
    Ok(report.levels)
}

/// The noise of `channels`, named, for the estimate's `"noise"`.
pub(crate) fn named_noise(level: &[f64; 5], channels: &[usize]) -> Vec<(String, f64)> {
    channels
        .iter()
        .map(|&c| (CHANNELS[c].to_string(), level[c]))
        .collect()
}

/// The method `name` fitted for `rec`'s timing and `noise` (see [`Trained::get`]), with what is
/// trained reported on standard error.
pub(crate) fn trained_for<'a>(
    trained: &'a mut Trained,
    family: &Family,
    rec: &Recording,
    noise: &[f64; 5],
    name: &str,
    seed: u64,
    lead: usize,
) -> Result<&'a dyn Method> {
    Ok(trained.get(family, rec, noise, name, seed, lead, &mut |m| {
        eprintln!("{m}")
    })?)
}

/// Per recording, the lead-in its method allows ([`lead_in::batch_leads`]), with warnings on
/// standard error.
pub(crate) fn lead_ins(
    max_delay: f64,
    family: &Family,
    files: &[PathBuf],
    recordings: &[Recording],
    noise: &[[f64; 5]],
) -> Result<Vec<usize>> {
    let names: Vec<String> = files.iter().map(|f| f.display().to_string()).collect();
    Ok(lead_in::batch_leads(
        max_delay,
        family,
        &names,
        recordings,
        noise,
        &mut |w| eprintln!("warning: {w}"),
    )?)
}

/// Reads one recording (see [`Recording::from_series`]), with its sidecar's metadata where
/// there is one: what is wrong with the sidecar is a warning, never an error.
pub(crate) fn read_recording(
    file: &Path,
    needs: &[usize],
    reader: Reader,
    whisker: Option<&str>,
) -> Result<Recording> {
    let (series, lines, warnings) = vibrissa_io::series::read_csv_with_sidecar_lines(file)
        .with_context(|| format!("cannot read `{}`", file.display()))?;
    for w in warnings {
        eprintln!("warning: {w}");
    }
    let name = file.display().to_string();
    let series = vibrissa_infer::recording::whisker_view(&series, &name, whisker)?;
    // Messages name the file's line of a bad row, as the CSV reader's own do.
    Ok(Recording::from_series_at_lines(
        &series, &name, needs, reader, &lines,
    )?)
}

/// Refuses, naming the file, a recording sampled too slowly for `family`'s run
/// ([`Family::check_sample_rate`]).
pub(crate) fn check_sample_rates(
    family: &Family,
    files: &[PathBuf],
    recordings: &[Recording],
) -> Result<()> {
    for (file, rec) in files.iter().zip(recordings) {
        family
            .check_sample_rate(rec.rate)
            .map_err(|e| anyhow!("`{}`: {e}", file.display()))?;
    }
    Ok(())
}

/// Warns of channels that span far more than the scenario's runs do: a recording in other
/// units ([`vibrissa_infer::units`]).
pub(crate) fn warn_of_units(
    family: &Family,
    files: &[PathBuf],
    recordings: &[Recording],
    needs: &[usize],
) -> Result<()> {
    let names: Vec<String> = files.iter().map(|f| f.display().to_string()).collect();
    for w in vibrissa_infer::units::unit_warnings(family, &names, recordings, needs)? {
        eprintln!("warning: {w}");
    }
    Ok(())
}

/// The model check of one recording at `point` (see [`vibrissa_infer::check`]; `lead`: the
/// samples of lead-in allowed), with a warning on standard error when the scenario does not
/// explain it; `None` (with a warning) when the scenario cannot be simulated at the estimate.
pub(crate) fn check_recording(
    family: &Family,
    file: &Path,
    rec: &Recording,
    point: &[f64],
    noise: &[f64; 5],
    channels: &[usize],
    lead: usize,
) -> Option<Check> {
    let result = family
        .for_recording(rec)
        .and_then(|timed| check::check(&timed, &rec.values, point, noise, channels, lead));
    match result {
        Ok(c) => {
            if let (false, Some(w)) = (c.explained, c.worst()) {
                eprintln!(
                    "warning: `{}`: the scenario does not explain this recording at its estimate: \
                     {} leaves {:.1} times its noise level (residual lag-1 correlation {:.2}); the \
                     estimate and its interval assume a model that does not fit (calibrate the \
                     scenario: vibrissa calibrate; for recordings made by another simulator, \
                     state its chain's `segments` and `discretisation`)",
                    file.display(),
                    w.channel,
                    w.ratio,
                    w.lag1
                );
            }
            Some(c)
        }
        Err(e) => {
            eprintln!(
                "warning: `{}`: cannot check the recording at its estimate: {e}",
                file.display()
            );
            None
        }
    }
}

/// The check's figure: per checked channel, the recording, the simulation at the estimate and
/// the residual.
pub(crate) fn draw_check(png: &Path, file: &Path, rec: &Recording, c: &Check) -> Result<Pending> {
    let units = vibrissa_infer::calibrate::UNITS;
    let n = rec.t.len();
    let series: Vec<(usize, Vec<f64>, Vec<f64>)> = c
        .channels
        .iter()
        .filter_map(|ch| CHANNELS.iter().position(|n| *n == ch.channel))
        .map(|k| {
            let sim: Vec<f64> = (0..n)
                .map(|i| c.simulated[k].get(i).copied().unwrap_or(f64::NAN))
                .collect();
            let res: Vec<f64> = rec.values[k].iter().zip(&sim).map(|(y, s)| y - s).collect();
            (k, sim, res)
        })
        .collect();
    let panels: Vec<Panel> = series
        .iter()
        .map(|(k, sim, res)| Panel {
            quantity: CHANNELS[*k],
            unit: units[*k],
            curves: vec![
                Curve {
                    name: "recorded",
                    values: &rec.values[*k],
                    dashed: false,
                },
                Curve {
                    name: "simulated at the estimate",
                    values: sim,
                    dashed: true,
                },
                Curve {
                    name: "residual",
                    values: res,
                    dashed: false,
                },
            ],
        })
        .collect();
    crate::plot::render_series(
        png,
        &format!(
            "check of {}: {}",
            file.display(),
            if c.explained {
                "explained by the scenario"
            } else {
                "not explained by the scenario"
            }
        ),
        &Axis {
            quantity: "t",
            unit: "s",
            values: &rec.t,
        },
        &panels,
        None,
    )
}
