//! `vibrissa sweep`: every combination of a grid of parameter values, run in parallel, one file
//! per run, with a manifest.
//!
//! A grid names `--set` keys (`d`, `v`, `whisker.length`, `objects.0.friction`) with lists or
//! ranges of values; every combination is one run, its values applied as overrides after the
//! command line's own `--set`s. A built-in experiment (or a file naming one) with no `--grid`
//! sweeps its own grid (docs/experiments.md).
//!
//! Each run writes its series and, beside it, a JSON sidecar with its metadata (`d0.015_v0.3.csv`
//! and `d0.015_v0.3.json`). Both are renamed into place only when complete, the series last, so
//! a run is finished when both files are in the folder: started again on the same folder, a
//! sweep skips those runs, and runs again any whose series or sidecar is missing.
//! `manifest.csv` lists the finished runs with their parameters and figures; it is rewritten
//! (atomically) after every run, so a killed sweep leaves a truthful one. A run that fails is
//! reported with its parameters; the others still run, and the sweep then exits non-zero.

use crate::output::{grouped, sig, FormatArgs, Render};
use crate::progress::Progress;
use anyhow::{anyhow, bail, Context, Result};
use clap::builder::PossibleValuesParser;
use rayon::prelude::*;
use serde::Serialize;
use std::fs;
use std::io::{self, Write};
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Instant;
use vibrissa_io::scenario::{self, Loaded};
use vibrissa_io::series::EXTENSIONS;
use vibrissa_io::sweep::{
    grids_for, plan, read_manifest, run_one, Grid, Job, Manifest, Row, MANIFEST,
};

/// Arguments of `vibrissa sweep`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scenario: a built-in experiment (e1, e2) or the path of a TOML scenario file.
    #[arg(value_name = "SCENARIO")]
    scenario: String,
    /// Folder for the runs' files (a series and its .json sidecar each) and `manifest.csv`
    /// (created if missing; an existing one is resumed: runs whose two files are there are
    /// skipped).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Overrides a scenario key for every run, e.g. `whisker.length=0.04` (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// A key to vary: `key=v1,v2,...` or `key=start:stop:count` (count values evenly from start
    /// to stop, both included). Repeatable: every combination runs. Without it, e1 and e2 sweep
    /// their own grids (e1: d = 15…30 mm; e2: d = 15…30 mm × v = 0.3…1.5 m/s).
    #[arg(long = "grid", value_name = "KEY=VALUES")]
    grids: Vec<String>,
    /// File format of the runs.
    #[arg(long, value_name = "FORMAT", default_value = "csv",
          value_parser = PossibleValuesParser::new(EXTENSIONS))]
    format: String,
    /// Runs at a time (default: one per core).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    jobs: Option<u32>,
    #[command(flatten)]
    output: FormatArgs,
}

/// Runs the sweep and prints its report; fails at the end if any run failed.
pub fn run(args: &Args) -> Result<()> {
    let start = Instant::now();

    // The grid: the command line's, or the experiment's own.
    let grids = grids_for(&args.scenario, &args.sets, &args.grids)?;
    let jobs = plan(&grids, &args.format)?;

    // Every run's scenario, loaded and checked before anything runs; an error shared by all
    // runs (a misspelt key) stops the sweep here.
    let loaded: Vec<Result<Loaded>> = jobs
        .iter()
        .map(|job| {
            let sets: Vec<String> = args.sets.iter().cloned().chain(job.sets()).collect();
            scenario::load_full(&args.scenario, &sets).map_err(anyhow::Error::from)
        })
        .collect();
    if loaded.iter().all(Result::is_err) {
        let first = loaded.into_iter().next().and_then(Result::err);
        return Err(first.unwrap_or_else(|| anyhow!("the grid has no runs")));
    }

    // Resume: a run whose series and sidecar both exist is finished.
    let dir = &args.out;
    fs::create_dir_all(dir)
        .with_context(|| format!("cannot create the folder `{}`", dir.display()))?;
    let manifest_path = dir.join(MANIFEST);
    let previous = read_manifest(&manifest_path);
    let rows: Vec<Option<Row>> = jobs
        .iter()
        .map(|job| {
            job.done(dir).then(|| {
                previous
                    .get(&job.file)
                    .cloned()
                    .unwrap_or_else(Row::unknown)
            })
        })
        .collect();
    let skipped = rows.iter().filter(|r| r.is_some()).count();
    let manifest = Manifest {
        path: manifest_path,
        keys: grids.iter().map(|g| g.key.clone()).collect(),
        rows,
    };
    manifest.write(&jobs)?;
    if skipped > 0 {
        eprintln!(
            "skipping {skipped} of {} runs: their series and sidecars are already in `{}`",
            jobs.len(),
            dir.display()
        );
    }

    // Runs whose scenario did not load have failed already; the others run in parallel.
    let mut failures = Vec::new();
    let mut todo = Vec::new();
    for (k, l) in loaded.iter().enumerate() {
        match l {
            _ if manifest.rows[k].is_some() => {}
            Ok(_) => todo.push(k),
            Err(e) => failures.push(Failure::new(k, &jobs[k], e)),
        }
    }
    for f in &failures {
        eprintln!("run {} failed: {}", f.parameters, f.error);
    }
    let threads = args.jobs.map_or_else(
        || std::thread::available_parallelism().map_or(1, |n| n.get()),
        |n| n as usize,
    );
    let state = Mutex::new(State {
        progress: Progress::count(todo.len(), "runs"),
        finished: 0,
        succeeded: 0,
        manifest,
        manifest_error: None,
        failures,
    });
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("cannot start the worker threads")?;
    pool.install(|| {
        todo.par_iter().for_each(|&k| {
            let job = &jobs[k];
            let result = match &loaded[k] {
                Ok(l) => {
                    run_one(l, &args.scenario, &args.sets, job, dir).map_err(anyhow::Error::from)
                }
                Err(e) => Err(anyhow!("{e:#}")),
            };
            let mut s = state.lock().unwrap_or_else(|p| p.into_inner());
            s.record(k, job, &jobs, result);
        })
    });
    let mut state = state.into_inner().unwrap_or_else(|p| p.into_inner());
    state.progress.finish();

    // The final manifest, then the report.
    state.manifest.write(&jobs)?;
    if let Some(e) = state.manifest_error {
        return Err(e);
    }
    let mut failures = state.failures;
    failures.sort_by_key(|f| f.index);
    let report = Report {
        scenario: args.scenario.clone(),
        dir: dir.display().to_string(),
        manifest: state.manifest.path.display().to_string(),
        grid: grids,
        runs: jobs.len(),
        ran: state.succeeded,
        skipped,
        failed: failures,
        threads,
        seconds: start.elapsed().as_secs_f64(),
    };
    args.output.format().print(&report)?;
    if !report.failed.is_empty() {
        // Each failure's message was shown as it happened and is in the report.
        let which: Vec<&str> = report
            .failed
            .iter()
            .map(|f| f.parameters.as_str())
            .collect();
        bail!(
            "{} of {} runs failed ({}); the other runs are in `{}`",
            report.failed.len(),
            report.runs,
            which.join("; "),
            report.dir
        );
    }
    Ok(())
}

/// What the workers share.
struct State {
    /// Progress on standard error.
    progress: Progress,
    /// Runs finished (successfully or not) in this invocation.
    finished: usize,
    /// Runs finished successfully in this invocation.
    succeeded: usize,
    /// The manifest, rewritten after every successful run.
    manifest: Manifest,
    /// The first failure to rewrite the manifest (the sweep goes on, and fails at the end).
    manifest_error: Option<anyhow::Error>,
    /// Runs that failed.
    failures: Vec<Failure>,
}

impl State {
    /// Records the outcome of job `k`.
    fn record(&mut self, k: usize, job: &Job, jobs: &[Job], result: Result<Row>) {
        match result {
            Ok(row) => {
                self.manifest.rows[k] = Some(row);
                self.succeeded += 1;
                if let Err(e) = self.manifest.write(jobs) {
                    self.manifest_error.get_or_insert(e.into());
                }
            }
            Err(e) => {
                let failure = Failure::new(k, job, &e);
                self.progress.message(&format!(
                    "run {} failed: {}",
                    failure.parameters, failure.error
                ));
                self.failures.push(failure);
            }
        }
        self.finished += 1;
        self.progress.set_count(self.finished);
    }
}

/// A run that failed.
#[derive(Debug, Serialize)]
struct Failure {
    /// Position of the run in the grid.
    #[serde(skip)]
    index: usize,
    /// Its parameters: `d=0.015 v=0.3`.
    parameters: String,
    /// The file it would have written.
    file: String,
    /// What went wrong.
    error: String,
}

impl Failure {
    fn new(index: usize, job: &Job, error: &anyhow::Error) -> Failure {
        Failure {
            index,
            parameters: job.label(),
            file: job.file.clone(),
            error: format!("{error:#}"),
        }
    }
}

/// What `vibrissa sweep` prints.
#[derive(Debug, Serialize)]
struct Report {
    /// The scenario as named.
    scenario: String,
    /// The output folder.
    dir: String,
    /// The manifest's path.
    manifest: String,
    /// The keys varied and their values.
    grid: Vec<Grid>,
    /// Runs in the grid.
    runs: usize,
    /// Runs completed in this invocation.
    ran: usize,
    /// Runs skipped because their series and sidecars existed.
    skipped: usize,
    /// Runs that failed.
    failed: Vec<Failure>,
    /// Worker threads.
    threads: usize,
    /// Wall time of the whole sweep, s.
    seconds: f64,
}

impl Render for Report {
    fn render(&self, out: &mut dyn Write) -> io::Result<()> {
        let shape: Vec<String> = self
            .grid
            .iter()
            .map(|g| format!("{} ({} values)", g.key, g.values.len()))
            .collect();
        writeln!(
            out,
            "sweep of {}: {} runs over {}",
            self.scenario,
            grouped(self.runs as f64),
            shape.join(" × ")
        )?;
        let line =
            |out: &mut dyn Write, key: &str, value: String| writeln!(out, "  {key:<10} {value}");
        line(
            out,
            "ran",
            format!(
                "{}, failed {}, skipped {} (already done)",
                self.ran,
                self.failed.len(),
                self.skipped
            ),
        )?;
        line(
            out,
            "wall time",
            format!(
                "{} s on {} thread{}",
                sig(self.seconds, 3),
                self.threads,
                if self.threads == 1 { "" } else { "s" }
            ),
        )?;
        line(out, "folder", self.dir.clone())?;
        line(out, "manifest", self.manifest.clone())?;
        for f in &self.failed {
            line(out, "failed", format!("{}: {}", f.parameters, f.error))?;
        }
        Ok(())
    }
}
