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
//!
//! A folder is resumed only by the sweep that made its runs: the same scenario, the same `--set`
//! values and the same `--grid` keys (the values may differ: new ones run, finished ones are
//! skipped). Each run's sidecar names its scenario and its `--set` values, and the manifest's
//! header names the grid's keys; a sweep of a scenario file also writes `.sweep.json`, which
//! records a digest of the file's content, so that a file edited since is noticed too. A sweep
//! that differs in any of these is refused before anything is written.
//!
//! A sweep has at most [`MAX_RUNS`] runs: larger grids are refused before anything is planned.

use crate::output::{grouped, sig, FormatArgs, Render};
use crate::progress::Progress;
use anyhow::{anyhow, bail, Context, Result};
use clap::builder::PossibleValuesParser;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::fs;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;
use vibrissa_core::dynamics::LANES;
use vibrissa_io::scenario::{self, Document, Loaded};
use vibrissa_io::series::{sidecar_path, EXTENSIONS};
use vibrissa_io::sweep::{
    grids_for, plan, read_manifest, run_batch, Grid, Job, Manifest, Row, MANIFEST,
};

/// Arguments of `vibrissa sweep`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scenario: a built-in experiment (e1, e2) or the path of a TOML scenario file.
    #[arg(value_name = "SCENARIO")]
    scenario: String,
    /// Folder for the runs' files (a series and its .json sidecar each) and `manifest.csv`
    /// (created if missing; an existing one is resumed: runs whose two files are there are
    /// skipped). A folder whose runs were made from another scenario, other --set values or
    /// other --grid keys is refused.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Overrides a scenario key for every run, e.g. `whisker.length=0.04` (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// A key to vary: `key=v1,v2,...` or `key=start:stop:count` (count values evenly from start
    /// to stop, both included). Repeatable: every combination runs. Without it, e1 and e2 sweep
    /// their own grids (e1: d = 15…30 mm; e2: d = 15…30 mm × v = 0.3…1.5 m/s). At most
    /// 1 000 000 runs in all.
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

    // The grid: the command line's, or the experiment's own; its size is checked before its
    // values and runs are made.
    check_range_counts(&args.grids)?;
    let grids = grids_for(&args.scenario, &args.sets, &args.grids)?;
    check_total_runs(&grids)?;
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

    // Resume: a run whose series and sidecar both exist is finished, if the folder's runs were
    // made by this same sweep.
    let dir = &args.out;
    let settings = Settings::of(args, &grids)?;
    let folder = check_folder(dir, &settings, &args.sets, &jobs)?;
    fs::create_dir_all(dir)
        .with_context(|| format!("cannot create the folder `{}`", dir.display()))?;
    if scenario::builtin(&args.scenario).is_none() {
        match folder {
            Folder::Fresh => settings.write(dir)?,
            Folder::Recorded => {}
            Folder::Unrecorded => eprintln!(
                "warning: `{}` has no {SETTINGS} (its runs were made by an earlier version or by \
                 the Python package): they were checked against the scenario's name and the \
                 --set values in their sidecars, not against the content of `{}`",
                dir.display(),
                args.scenario
            ),
        }
    }
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
    // A few runs per task, so that runs of one whisker step together in lanes (each to the bits
    // it reaches alone): full lane groups, unless there are too few runs for every thread.
    let chunk = todo.len().div_ceil(threads.max(1)).clamp(1, LANES);
    pool.install(|| {
        todo.par_chunks(chunk).for_each(|part| {
            // Every run in `todo` was loaded.
            let batch: Vec<(&Loaded, &Job)> = part
                .iter()
                .filter_map(|&k| loaded[k].as_ref().ok().map(|l| (l, &jobs[k])))
                .collect();
            let results = run_batch(&batch, &args.scenario, &args.sets, dir);
            for (&k, result) in part.iter().zip(results) {
                let mut s = state.lock().unwrap_or_else(|p| p.into_inner());
                s.record(k, &jobs[k], &jobs, result.map_err(anyhow::Error::from));
            }
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

/// Most runs one sweep may have, in all (and so the most values one `--grid` may give). Every
/// run's scenario is loaded and checked before the first run starts, a few kB each, so a million
/// runs already take a few GB of memory.
const MAX_RUNS: usize = 1_000_000;

/// Refuses a `--grid` range (`key=start:stop:count`) whose count is over [`MAX_RUNS`], before
/// its values are made. Other malformed grids are left to the grid's parser, which names them.
fn check_range_counts(texts: &[String]) -> Result<()> {
    for text in texts {
        let Some((_, values)) = text.split_once('=') else {
            continue;
        };
        let values = values.trim();
        if !values.contains(':') || values.contains([',', '"', '\'']) {
            continue;
        }
        let parts: Vec<&str> = values.split(':').map(str::trim).collect();
        let [_, _, count] = parts[..] else {
            continue;
        };
        let digits = count.strip_prefix('+').unwrap_or(count);
        if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
            continue;
        }
        let shown = match digits.parse::<usize>() {
            Ok(n) if n <= MAX_RUNS => continue,
            Ok(n) => grouped(n as f64),
            Err(_) => digits.to_string(),
        };
        bail!(
            "--grid `{text}`: a range of {shown} values; a sweep may have at most {} runs in all",
            grouped(MAX_RUNS as f64)
        );
    }
    Ok(())
}

/// Refuses grids whose combinations are more than [`MAX_RUNS`] runs, before they are planned.
fn check_total_runs(grids: &[Grid]) -> Result<()> {
    let total = grids
        .iter()
        .try_fold(1usize, |n, g| n.checked_mul(g.values.len()));
    if total.is_some_and(|n| n <= MAX_RUNS) {
        return Ok(());
    }
    let counts: Vec<String> = grids
        .iter()
        .map(|g| format!("{} {}", g.key, grouped(g.values.len() as f64)))
        .collect();
    let product: f64 = grids.iter().map(|g| g.values.len() as f64).product();
    bail!(
        "--grid: {} runs in all ({}); a sweep may have at most {} runs in all",
        grouped(product),
        counts.join(" × "),
        grouped(MAX_RUNS as f64)
    )
}

/// Name of the file in the output folder that records what a sweep of a scenario file is made
/// from. Hidden, and so never matched by `*.json` with the runs' sidecars; no run's file can be
/// named so, as grid keys do not start with a dot.
const SETTINGS: &str = ".sweep.json";

/// What a sweep's runs are made from, as `.sweep.json` records it.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Settings {
    /// Version of vibrissa that started the sweep in the folder.
    vibrissa: String,
    /// The scenario as named on the command line.
    scenario: String,
    /// Digest of the scenario before any `--set` (FNV-1a over its canonical TOML, so comments
    /// and layout do not count), 16 hexadecimal digits.
    scenario_digest: String,
    /// The `--set` values given for every run, in order.
    set: Vec<String>,
    /// The keys varied, in order.
    grid: Vec<String>,
}

impl Settings {
    /// The settings of this invocation.
    fn of(args: &Args, grids: &[Grid]) -> Result<Settings> {
        let doc = Document::load(&args.scenario, &[])?;
        Ok(Settings {
            vibrissa: env!("CARGO_PKG_VERSION").to_string(),
            scenario: args.scenario.clone(),
            scenario_digest: format!("{:016x}", doc.digest()),
            set: args.sets.clone(),
            grid: grids.iter().map(|g| g.key.clone()).collect(),
        })
    }

    /// Writes `.sweep.json` into `dir` (whole or not at all).
    fn write(&self, dir: &Path) -> Result<()> {
        let mut text = serde_json::to_string_pretty(self)?;
        text.push('\n');
        crate::files::write_atomic(&dir.join(SETTINGS), text.as_bytes())
    }

    /// The differences between the settings recorded in a folder (`self`) and `here`'s.
    fn differences(&self, here: &Settings) -> Vec<String> {
        let mut out = Vec::new();
        if self.scenario_digest != here.scenario_digest {
            out.push(if self.scenario == here.scenario {
                format!(
                    "the scenario `{}` has changed since its runs there were made",
                    here.scenario
                )
            } else {
                format!(
                    "its runs were made from the scenario `{}`, and this sweep's `{}` differs \
                     from it",
                    self.scenario, here.scenario
                )
            });
        }
        if self.set != here.set {
            out.push(format!(
                "its runs were made with {}, this sweep gives {}",
                sets_text(&self.set.join(" ")),
                sets_text(&here.set.join(" "))
            ));
        }
        if self.grid != here.grid {
            out.push(keys_text(&self.grid, &here.grid));
        }
        out
    }
}

/// `--set` values as a phrase: "--set `a=1 b=2`", or "no --set".
fn sets_text(joined: &str) -> String {
    if joined.is_empty() {
        "no --set".to_string()
    } else {
        format!("--set `{joined}`")
    }
}

/// The difference between the keys varied in a folder and by this sweep, as a phrase.
fn keys_text(there: &[String], here: &[String]) -> String {
    format!(
        "its runs vary `{}`, this sweep varies `{}`",
        there.join(" "),
        here.join(" ")
    )
}

/// What an output folder holds, once found to belong to this sweep.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Folder {
    /// No finished runs (or no folder yet) and no `.sweep.json`.
    Fresh,
    /// A `.sweep.json` that matches this sweep.
    Recorded,
    /// Finished runs without a `.sweep.json` (an earlier version's, or the Python package's).
    Unrecorded,
}

/// Checks that the runs already in `dir` were made by this sweep: by `.sweep.json` when there
/// is one, and by the grid's keys in `manifest.csv` otherwise; and in any case by the sidecars
/// of the runs that would be skipped and of the first run the manifest lists, each of which
/// names its scenario and its `--set` values. Refuses the folder, saying what differs, if
/// anything does.
fn check_folder(dir: &Path, here: &Settings, sets: &[String], jobs: &[Job]) -> Result<Folder> {
    if !dir.is_dir() {
        return Ok(Folder::Fresh);
    }
    let record_path = dir.join(SETTINGS);
    let record: Option<Settings> = match fs::read(&record_path) {
        Ok(bytes) => Some(serde_json::from_slice(&bytes).with_context(|| {
            format!(
                "`{}` does not read as a sweep's settings; give another --out folder",
                record_path.display()
            )
        })?),
        Err(e) if e.kind() == io::ErrorKind::NotFound => None,
        Err(e) => bail!("cannot read `{}`: {e}", record_path.display()),
    };
    let listed = first_listed(&dir.join(MANIFEST));

    let mut differences = match (&record, &listed) {
        (Some(r), _) => r.differences(here),
        (None, Some(l)) if l.keys != here.grid => vec![keys_text(&l.keys, &here.grid)],
        (None, _) => Vec::new(),
    };

    // The sidecars: of every run that would be skipped, then of the first one listed.
    let expected = |params: &mut dyn Iterator<Item = String>| -> String {
        sets.iter()
            .cloned()
            .chain(params)
            .collect::<Vec<_>>()
            .join(" ")
    };
    let mut runs: Vec<(String, String)> = jobs
        .iter()
        .filter(|job| job.done(dir))
        .map(|job| (job.file.clone(), expected(&mut job.sets())))
        .collect();
    let finished = !runs.is_empty() || listed.is_some();
    if let Some(l) = &listed {
        if dir.join(&l.file).is_file() && sidecar_path(dir.join(&l.file)).is_file() {
            let mut params = l
                .keys
                .iter()
                .zip(&l.values)
                .map(|(k, v)| format!("{k}={v}"));
            runs.push((l.file.clone(), expected(&mut params)));
        }
    }
    if differences.is_empty() {
        for (file, want) in &runs {
            let sidecar = sidecar_path(dir.join(file));
            let (scenario, set) = made_with(&sidecar)?;
            let name = sidecar.file_name().unwrap_or_default().to_string_lossy();
            if record.is_none() && !same_scenario(&scenario, &here.scenario) {
                differences.push(format!(
                    "`{name}` says its run was made from the scenario `{scenario}`, this \
                     sweep's is `{}`",
                    here.scenario
                ));
                break;
            }
            if set != *want {
                differences.push(format!(
                    "`{name}` says its run was made with {}, this sweep would make it with {}",
                    sets_text(&set),
                    sets_text(want)
                ));
                break;
            }
        }
    }
    if !differences.is_empty() {
        bail!(
            "--out `{}` holds runs of another sweep: {}; resuming there would mix their runs \
             with this sweep's. Give another --out folder, or the scenario, --set values and \
             --grid keys its runs were made with",
            dir.display(),
            differences.join("; ")
        );
    }
    Ok(match (record, finished) {
        (Some(_), _) => Folder::Recorded,
        (None, false) => Folder::Fresh,
        (None, true) => Folder::Unrecorded,
    })
}

/// The scenario and the `--set` values (space-separated, empty for none) that a run's sidecar
/// says it was made with.
fn made_with(sidecar: &Path) -> Result<(String, String)> {
    let text = fs::read_to_string(sidecar)
        .with_context(|| format!("cannot read `{}`", sidecar.display()))?;
    let json: serde_json::Value = serde_json::from_str(&text)
        .with_context(|| format!("`{}` is not a sidecar (JSON)", sidecar.display()))?;
    let meta = &json["meta"];
    let Some(scenario) = meta["scenario"].as_str() else {
        bail!(
            "`{}` does not name the scenario its run was made from; give another --out folder",
            sidecar.display()
        );
    };
    let set = meta["set"].as_str().unwrap_or_default();
    Ok((scenario.to_string(), set.to_string()))
}

/// Whether two scenarios as named are the same: the same name, or names of the same file.
fn same_scenario(a: &str, b: &str) -> bool {
    a == b
        || match (Path::new(a).canonicalize(), Path::new(b).canonicalize()) {
            (Ok(a), Ok(b)) => a == b,
            _ => false,
        }
}

/// The first run that an earlier manifest lists, with the grid's keys.
struct Listed {
    /// The grid's keys, from the header.
    keys: Vec<String>,
    /// The run's series.
    file: String,
    /// Its values of the keys.
    values: Vec<String>,
}

/// The first run listed in the manifest at `path`; none if it is missing, unreadable or lists
/// no run.
fn first_listed(path: &Path) -> Option<Listed> {
    let text = fs::read_to_string(path).ok()?;
    let mut lines = text.lines();
    let header = vibrissa_io::sweep::split_record(lines.next()?);
    let end = header.iter().position(|h| h == "samples")?;
    if header.first().map(String::as_str) != Some("file") || end < 1 {
        return None;
    }
    let row = lines
        .map(vibrissa_io::sweep::split_record)
        .find(|r| r.len() == header.len())?;
    Some(Listed {
        keys: header[1..end].to_vec(),
        file: row[0].clone(),
        values: row[1..end].to_vec(),
    })
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
