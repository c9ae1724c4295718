//! `vibrissa sweep`: every combination of a grid of parameter values, run in parallel, one file
//! per run, with a manifest.
//!
//! A grid names `--set` keys (`d`, `v`, `whisker.length`, `objects.0.friction`) with lists or
//! ranges of values; every combination is one run, its values applied as overrides after the
//! command line's own `--set`s. A built-in experiment (or a file naming one) with no `--grid`
//! sweeps its own grid from EXPERIMENTS.md.
//!
//! Each run writes its series and, beside it, a JSON sidecar with its metadata (`d0.015_v0.3.csv`
//! and `d0.015_v0.3.json`). Both are renamed into place only when complete, the series last, so
//! a run is finished when both files are in the folder: started again on the same folder, a
//! sweep skips those runs, and runs again any whose series or sidecar is missing.
//! `manifest.csv` lists the finished runs with their parameters and figures; it is rewritten
//! (atomically) after every run, so a killed sweep leaves a truthful one. A run that fails is
//! reported with its parameters; the others still run, and the sweep then exits non-zero.

use crate::files;
use crate::output::{grouped, sig, FormatArgs, Render};
use crate::progress::Progress;
use crate::simulate::to_series;
use anyhow::{anyhow, bail, Context, Result};
use clap::builder::PossibleValuesParser;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::HashMap;
use std::fs;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;
use vibrissa_core::sim;
use vibrissa_io::scenario::{self, Experiment, Loaded};
use vibrissa_io::series::{self, EXTENSIONS};

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

/// Name of the manifest in the output folder.
const MANIFEST: &str = "manifest.csv";
/// Longest file name of a run, bytes (file systems allow 255).
const MAX_NAME: usize = 200;

/// One key varied over a list of values.
#[derive(Debug, Clone, PartialEq, Serialize)]
struct Grid {
    /// The `--set` key.
    key: String,
    /// Its values, as `--set` values (TOML).
    values: Vec<String>,
}

/// One run of the sweep.
#[derive(Debug, Clone, PartialEq)]
struct Job {
    /// `(key, value)` for each grid, in the grids' order.
    params: Vec<(String, String)>,
    /// File name of its series in the output folder.
    file: String,
}

impl Job {
    /// `key=value` overrides.
    fn sets(&self) -> impl Iterator<Item = String> + '_ {
        self.params.iter().map(|(k, v)| format!("{k}={v}"))
    }

    /// The parameters as written on a command line: `d=0.015 v=0.3`.
    fn label(&self) -> String {
        self.sets().collect::<Vec<_>>().join(" ")
    }

    /// Whether the run is finished in `dir`: its series and its sidecar are both there.
    fn done(&self, dir: &Path) -> bool {
        let file = dir.join(&self.file);
        file.is_file() && series::sidecar_path(&file).is_file()
    }
}

/// Runs the sweep and prints its report; fails at the end if any run failed.
pub fn run(args: &Args) -> Result<()> {
    let start = Instant::now();

    // The grid: the command line's, or the experiment's own.
    let grids = if args.grids.is_empty() {
        let base = scenario::load_full(&args.scenario, &args.sets)?;
        match base.experiment {
            Some(e) => experiment_grid(e.experiment),
            None => bail!(
                "{}: no --grid given, and the scenario names no experiment with a grid of its \
                 own; give one or more --grid key=v1,v2,... or --grid key=start:stop:count",
                base.origin
            ),
        }
    } else {
        parse_grids(&args.grids)?
    };
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
                Ok(l) => run_one(l, &args.scenario, &args.sets, job, dir),
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
                    self.manifest_error.get_or_insert(e);
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

/// Runs one job and writes its series and sidecar; returns its manifest row.
fn run_one(loaded: &Loaded, spec: &str, sets: &[String], job: &Job, dir: &Path) -> Result<Row> {
    let start = Instant::now();
    let output = sim::run(&loaded.scenario, &mut |_| {})?;
    let all_sets: Vec<String> = sets.iter().cloned().chain(job.sets()).collect();
    let series = to_series(loaded, &output, spec, &all_sets);
    series::write(&series, dir.join(&job.file))?;
    Ok(Row {
        samples: output.rows.len().to_string(),
        steps: output.steps.to_string(),
        seconds: format!("{:.6}", start.elapsed().as_secs_f64()),
        max_penetration: if output.max_penetration == 0.0 {
            "0".to_string()
        } else {
            format!("{:e}", output.max_penetration)
        },
    })
}

/// Parses the `--grid` arguments; a key may appear once.
fn parse_grids(texts: &[String]) -> Result<Vec<Grid>> {
    let mut grids: Vec<Grid> = Vec::new();
    for text in texts {
        let grid = parse_grid(text)?;
        if grids.iter().any(|g| g.key == grid.key) {
            bail!(
                "--grid `{text}`: `{}` is already varied by another --grid; give all its \
                 values in one",
                grid.key
            );
        }
        grids.push(grid);
    }
    Ok(grids)
}

/// Parses one `--grid`: `key=v1,v2,...` or `key=start:stop:count`.
fn parse_grid(text: &str) -> Result<Grid> {
    let fail = |what: &str| {
        anyhow!(
            "--grid `{text}`: {what}; expected key=v1,v2,... or key=start:stop:count, \
             e.g. d=0.015,0.02 or d=0.015:0.03:16"
        )
    };
    let (key, values) = text
        .split_once('=')
        .ok_or_else(|| fail("no `=` after the key"))?;
    let key = key.trim();
    if key.is_empty() || key.contains(char::is_whitespace) {
        return Err(fail("the key is missing or has spaces"));
    }
    let values = values.trim();
    let values = if values.contains(':') && !values.contains([',', '"', '\'']) {
        // An evenly spaced range, both ends included.
        let parts: Vec<&str> = values.split(':').map(str::trim).collect();
        let [start, stop, count] = parts[..] else {
            return Err(fail("a range has three parts, start:stop:count"));
        };
        let number = |s: &str| s.parse::<f64>().ok().filter(|x| x.is_finite());
        let (Some(start), Some(stop)) = (number(start), number(stop)) else {
            return Err(fail("start and stop of a range must be finite numbers"));
        };
        let count = count
            .parse::<usize>()
            .ok()
            .filter(|&c| c >= 1)
            .ok_or_else(|| fail("the count of a range must be a whole number, at least 1"))?;
        (0..count)
            .map(|k| {
                let x = if k + 1 == count && count > 1 {
                    stop
                } else if count == 1 {
                    start
                } else {
                    start + (stop - start) * k as f64 / (count - 1) as f64
                };
                number_value(x)
            })
            .collect()
    } else {
        let list: Vec<String> = values.split(',').map(|v| v.trim().to_string()).collect();
        if list.iter().any(String::is_empty) {
            return Err(fail("a value is empty"));
        }
        list
    };
    Ok(Grid {
        key: key.to_string(),
        values,
    })
}

/// `x` as a `--set` value: 12 significant digits, without rounding noise; whole numbers as
/// integers (`3`, which integer keys such as `segments` need), very small or large magnitudes
/// in exponent form.
fn number_value(x: f64) -> String {
    let x: f64 = format!("{x:.11e}").parse().unwrap_or(x);
    if x == x.trunc() && x.abs() < 1e15 {
        format!("{}", x as i64)
    } else if x.abs() < 1e-4 || x.abs() >= 1e15 {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// The grid of an experiment family (EXPERIMENTS.md): e1 varies d = 15, 16, …, 30 mm; e2 also
/// v = 0.3, 0.6, …, 1.5 m/s.
fn experiment_grid(experiment: Experiment) -> Vec<Grid> {
    let d = Grid {
        key: "d".to_string(),
        values: (15..=30).map(|mm| number_value(mm as f64 / 1e3)).collect(),
    };
    let v = Grid {
        key: "v".to_string(),
        values: [0.3, 0.6, 0.9, 1.2, 1.5].map(number_value).to_vec(),
    };
    match experiment {
        Experiment::E1 => vec![d],
        Experiment::E2 => vec![d, v],
    }
}

/// Every combination of the grids (the first grid varies slowest), each with its file name.
fn plan(grids: &[Grid], ext: &str) -> Result<Vec<Job>> {
    let mut combos: Vec<Vec<(String, String)>> = vec![Vec::new()];
    for grid in grids {
        combos = combos
            .into_iter()
            .flat_map(|c| {
                grid.values.iter().map(move |v| {
                    let mut c = c.clone();
                    c.push((grid.key.clone(), v.clone()));
                    c
                })
            })
            .collect();
    }
    let mut names: HashMap<String, usize> = HashMap::new();
    let mut jobs = Vec::with_capacity(combos.len());
    for (k, params) in combos.into_iter().enumerate() {
        let file = file_name(&params, ext);
        let job = Job { params, file };
        if job.file.len() > MAX_NAME {
            bail!(
                "the file name of run {} would be {} bytes long; vary fewer keys or give \
                 shorter values",
                job.label(),
                job.file.len()
            );
        }
        if job.file == MANIFEST {
            bail!("run {} would be named like the manifest", job.label());
        }
        if let Some(&other) = names.get(&job.file) {
            let other: &Job = &jobs[other];
            bail!(
                "runs {} and {} would both be named `{}`; give values that differ in letters, \
                 digits, `.`, `-` or `+`",
                other.label(),
                job.label(),
                job.file
            );
        }
        names.insert(job.file.clone(), k);
        jobs.push(job);
    }
    Ok(jobs)
}

/// A run's file name: each key and its value run together, joined by `_`, then the extension
/// (`d0.015_v0.3.csv`). Letters, digits, `.`, `-` and `+` are kept; quotes are dropped; any
/// other character (`_` included, so that it only ever separates parameters) becomes `-`.
fn file_name(params: &[(String, String)], ext: &str) -> String {
    let safe = |s: &str| -> String {
        s.chars()
            .filter(|c| !matches!(c, '"' | '\''))
            .map(|c| {
                if c.is_ascii_alphanumeric() || matches!(c, '.' | '-' | '+') {
                    c
                } else {
                    '-'
                }
            })
            .collect()
    };
    let stem: Vec<String> = params
        .iter()
        .map(|(k, v)| format!("{}{}", safe(k), safe(v)))
        .collect();
    format!("{}.{ext}", stem.join("_"))
}

/// A manifest row's figures, as written (kept verbatim from an earlier manifest on resume).
#[derive(Debug, Clone, PartialEq)]
struct Row {
    /// Samples in the run's series.
    samples: String,
    /// Integrator steps.
    steps: String,
    /// Wall time of the run (simulation and writing), s.
    seconds: String,
    /// Largest penetration into an object, m.
    max_penetration: String,
}

impl Row {
    /// A finished run whose figures are not known (its files exist, the manifest lacked it).
    fn unknown() -> Row {
        let nan = || "NaN".to_string();
        Row {
            samples: nan(),
            steps: nan(),
            seconds: nan(),
            max_penetration: nan(),
        }
    }
}

/// `manifest.csv`: one row per finished run, in the grid's order.
#[derive(Debug)]
struct Manifest {
    /// Where it is written.
    path: PathBuf,
    /// The grid's keys (one column each).
    keys: Vec<String>,
    /// Per job: its row once finished.
    rows: Vec<Option<Row>>,
}

/// The manifest's columns after `file` and the grid's keys.
const FIGURES: [&str; 4] = ["samples", "steps", "seconds", "max_penetration"];

impl Manifest {
    /// Rewrites the file (atomically).
    fn write(&self, jobs: &[Job]) -> Result<()> {
        let mut text = String::new();
        let header: Vec<&str> = ["file"]
            .into_iter()
            .chain(self.keys.iter().map(String::as_str))
            .chain(FIGURES)
            .collect();
        push_record(&mut text, &header);
        for (job, row) in jobs.iter().zip(&self.rows) {
            let Some(row) = row else { continue };
            let fields: Vec<&str> = [job.file.as_str()]
                .into_iter()
                .chain(job.params.iter().map(|(_, v)| v.as_str()))
                .chain([
                    row.samples.as_str(),
                    &row.steps,
                    &row.seconds,
                    &row.max_penetration,
                ])
                .collect();
            push_record(&mut text, &fields);
        }
        files::write_atomic(&self.path, text.as_bytes())
    }
}

/// Appends one CSV record; a field with a comma, quote or line break is quoted.
fn push_record(text: &mut String, fields: &[&str]) {
    for (k, field) in fields.iter().enumerate() {
        if k > 0 {
            text.push(',');
        }
        if field.contains([',', '"', '\n', '\r']) {
            text.push('"');
            text.push_str(&field.replace('"', "\"\""));
            text.push('"');
        } else {
            text.push_str(field);
        }
    }
    text.push('\n');
}

/// Splits one CSV record written by [`push_record`].
fn split_record(line: &str) -> Vec<String> {
    let mut fields = Vec::new();
    let mut field = String::new();
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                chars.next();
                field.push('"');
            }
            ('"', _) => quoted = !quoted,
            (',', false) => fields.push(std::mem::take(&mut field)),
            _ => field.push(c),
        }
    }
    fields.push(field);
    fields
}

/// The rows of an earlier manifest by file name (none if it is missing or unreadable).
fn read_manifest(path: &Path) -> HashMap<String, Row> {
    let Ok(text) = fs::read_to_string(path) else {
        return HashMap::new();
    };
    let mut lines = text.lines();
    let Some(header) = lines.next().map(split_record) else {
        return HashMap::new();
    };
    let column = |name: &str| header.iter().position(|h| h == name);
    let (Some(file), Some(samples), Some(steps), Some(seconds), Some(pen)) = (
        column("file"),
        column("samples"),
        column("steps"),
        column("seconds"),
        column("max_penetration"),
    ) else {
        return HashMap::new();
    };
    lines
        .map(split_record)
        .filter(|r| r.len() == header.len())
        .map(|r| {
            let row = Row {
                samples: r[samples].clone(),
                steps: r[steps].clone(),
                seconds: r[seconds].clone(),
                max_penetration: r[pen].clone(),
            };
            (r[file].clone(), row)
        })
        .collect()
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_and_ranges() {
        let g = parse_grid("d=0.015, 0.02").unwrap();
        assert_eq!(g.key, "d");
        assert_eq!(g.values, ["0.015", "0.02"]);
        let r = parse_grid("d=0.015:0.030:16").unwrap();
        assert_eq!(r.values.len(), 16);
        assert_eq!(r.values[1], "0.016");
        assert_eq!(r.values[15], "0.03");
        assert_eq!(
            parse_grid("segments=10:40:4").unwrap().values,
            ["10", "20", "30", "40"]
        );
        assert_eq!(parse_grid("v=0.5:0.9:1").unwrap().values, ["0.5"]);
        assert_eq!(
            parse_grid("whisker.preset=w30,rat").unwrap().values,
            ["w30", "rat"]
        );
    }

    #[test]
    fn malformed_grids_are_refused() {
        for bad in [
            "d", "=1,2", "d=1,,2", "d=1:2", "d=a:2:3", "d=0:1:0", "d=0:1:x",
        ] {
            let err = parse_grid(bad).unwrap_err().to_string();
            assert!(err.contains(bad) && err.contains("key=v1,v2"), "{err}");
        }
        let twice = parse_grids(&["d=1,2".to_string(), "d=3".to_string()]);
        assert!(twice.unwrap_err().to_string().contains("already varied"));
    }

    #[test]
    fn numbers_print_without_noise() {
        assert_eq!(number_value(0.015 + 0.001), "0.016");
        assert_eq!(number_value(3.0), "3");
        assert_eq!(number_value(-0.0), "0");
        assert_eq!(number_value(1e-7), "1e-7");
        assert_eq!(number_value(0.3), "0.3");
    }

    #[test]
    fn experiment_grids_match_the_spec() {
        let e1 = experiment_grid(Experiment::E1);
        assert_eq!(e1.len(), 1);
        assert_eq!(e1[0].values.len(), 16);
        assert_eq!(e1[0].values[0], "0.015");
        assert_eq!(e1[0].values[15], "0.03");
        let e2 = plan(&experiment_grid(Experiment::E2), "csv").unwrap();
        assert_eq!(e2.len(), 80);
        assert_eq!(e2[0].file, "d0.015_v0.3.csv");
        assert_eq!(e2[79].file, "d0.03_v1.5.csv");
    }

    #[test]
    fn file_names_are_safe_and_distinct() {
        let params = |pairs: &[(&str, &str)]| -> Vec<(String, String)> {
            pairs
                .iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect()
        };
        assert_eq!(
            file_name(
                &params(&[("objects.0.friction", "0.3"), ("whisker.preset", "\"rat\"")]),
                "npz"
            ),
            "objects.0.friction0.3_whisker.presetrat.npz"
        );
        assert_eq!(
            file_name(&params(&[("whisker.base_radius", "1e-4")]), "csv"),
            "whisker.base-radius1e-4.csv"
        );
        let clash = [Grid {
            key: "k".into(),
            values: vec!["a b".into(), "a/b".into()],
        }];
        assert!(plan(&clash, "csv")
            .unwrap_err()
            .to_string()
            .contains("both be named"));
    }

    #[test]
    fn manifest_records_round_trip() {
        let mut text = String::new();
        push_record(&mut text, &["a", "b,c", "d\"e"]);
        assert_eq!(text, "a,\"b,c\",\"d\"\"e\"\n");
        assert_eq!(split_record(text.trim_end()), ["a", "b,c", "d\"e"]);
    }
}
