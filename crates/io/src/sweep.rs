//! Sweeps: every combination of a grid of parameter values, one file per run, with a manifest.
//!
//! A grid names scenario keys (`d`, `v`, `whisker.length`, `objects.0.friction`) with lists or
//! ranges of values ([`parse_grid`]); every combination is one run ([`plan`]), its values
//! applied as overrides after any given for all runs. A built-in experiment (or a file naming
//! one) sweeps its own grid ([`experiment_grid`]).
//!
//! Each run writes its series and, beside it, a JSON sidecar with its metadata
//! (`d0.015_v0.3.csv` and `d0.015_v0.3.json`, [`run_one`]). Both are renamed into place only
//! when complete, so a run is finished when both files are in the folder ([`Job::done`]): a
//! sweep started again on the same folder skips those runs. `manifest.csv` ([`Manifest`]) lists
//! the finished runs with their parameters and figures. The command line's `vibrissa sweep` runs
//! the plan on threads; the Python package runs the same plan locally or on a Ray cluster and
//! writes the same files.

use crate::error::{Error, Result};
use crate::scenario::{Experiment, Loaded};
use crate::series::{self, Series};
use serde::Serialize;
use std::collections::HashMap;
use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;
use vibrissa_core::sim::{self, Output, COLUMNS};

/// The series of a run with its metadata: the version that made it, the scenario as named, the
/// overrides, the experiment's unknowns, the chain's segments and time step, and the seed.
pub fn series_of(loaded: &Loaded, output: &Output, spec: &str, sets: &[String]) -> Series {
    let mut series = Series::new(&COLUMNS);
    for row in &output.rows {
        series.push_row(row);
    }
    series.set_meta("vibrissa", env!("CARGO_PKG_VERSION"));
    series.set_meta("scenario", spec);
    if !sets.is_empty() {
        series.set_meta("set", sets.join(" "));
    }
    if let Some(e) = &loaded.experiment {
        series.set_meta("experiment", e.experiment.name());
        series.set_meta("d", e.d);
        series.set_meta("v", e.v);
    }
    series.set_meta("segments", output.segments);
    series.set_meta("dt", output.dt);
    series.set_meta("seed", loaded.scenario.seed);
    series
}

/// The series of a run of a whisker array (see [`vibrissa_core::array`]): the shared `t`, then
/// every other column of each whisker prefixed with its name and a dot (`c1.theta01`, ...,
/// `c2.theta01`, ...), and the metadata of [`series_of`] (segments, dt and steps of the first
/// whisker's chain; they are the same for all) with the whiskers' names.
pub fn array_series_of(loaded: &Loaded, outputs: &[Output], spec: &str, sets: &[String]) -> Series {
    let mut columns = vec!["t".to_string()];
    for m in &loaded.whiskers {
        columns.extend(COLUMNS[1..].iter().map(|c| format!("{}.{c}", m.name)));
    }
    let mut series = Series::new(&columns);
    let rows = outputs.first().map_or(0, |o| o.rows.len());
    let mut row = Vec::with_capacity(columns.len());
    for k in 0..rows {
        row.clear();
        row.push(outputs[0].rows[k][0]);
        for o in outputs {
            row.extend_from_slice(&o.rows[k][1..]);
        }
        series.push_row(&row);
    }
    let first = series_of(loaded, &outputs[0], spec, sets);
    series.meta = first.meta;
    series.set_meta(
        "whiskers",
        loaded
            .whiskers
            .iter()
            .map(|m| m.name.as_str())
            .collect::<Vec<_>>()
            .join(" "),
    );
    series
}

/// Runs `loaded` (a single whisker or an array) and its series.
pub fn run_series(loaded: &Loaded, spec: &str, sets: &[String]) -> Result<(Series, Vec<Output>)> {
    if loaded.whiskers.is_empty() {
        let output = sim::run(&loaded.scenario, &mut |_| {})?;
        let series = series_of(loaded, &output, spec, sets);
        Ok((series, vec![output]))
    } else {
        let outputs = vibrissa_core::array::run(&loaded.scenario, &loaded.whiskers)?;
        let series = array_series_of(loaded, &outputs, spec, sets);
        Ok((series, outputs))
    }
}

/// The grids of a sweep: `texts` (`key=v1,v2,...` or `key=start:stop:count`), or, when there are
/// none, the grid of the experiment that the scenario `spec` (with `sets`) names.
pub fn grids_for(spec: &str, sets: &[String], texts: &[String]) -> Result<Vec<Grid>> {
    if !texts.is_empty() {
        return parse_grids(texts);
    }
    let base = crate::scenario::load_full(spec, sets)?;
    match base.experiment {
        Some(e) => Ok(experiment_grid(e.experiment)),
        None => Err(Error::Grid(format!(
            "{}: no grid given, and the scenario names no experiment with a grid of its own; \
             give one or more key=v1,v2,... or key=start:stop:count",
            base.origin
        ))),
    }
}

/// Name of the manifest in the output folder.
pub const MANIFEST: &str = "manifest.csv";
/// Longest file name of a run, bytes (file systems allow 255).
pub const MAX_NAME: usize = 200;

/// One key varied over a list of values.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Grid {
    /// The `--set` key.
    pub key: String,
    /// Its values, as `--set` values (TOML).
    pub values: Vec<String>,
}

/// One run of the sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct Job {
    /// `(key, value)` for each grid, in the grids' order.
    pub params: Vec<(String, String)>,
    /// File name of its series in the output folder.
    pub file: String,
}

impl Job {
    /// `key=value` overrides.
    pub fn sets(&self) -> impl Iterator<Item = String> + '_ {
        self.params.iter().map(|(k, v)| format!("{k}={v}"))
    }

    /// The parameters as written on a command line: `d=0.015 v=0.3`.
    pub fn label(&self) -> String {
        self.sets().collect::<Vec<_>>().join(" ")
    }

    /// Whether the run is finished in `dir`: its series and its sidecar are both there.
    pub fn done(&self, dir: &Path) -> bool {
        let file = dir.join(&self.file);
        file.is_file() && series::sidecar_path(&file).is_file()
    }
}

/// Runs one job and writes its series and sidecar; returns its manifest row.
pub fn run_one(loaded: &Loaded, spec: &str, sets: &[String], job: &Job, dir: &Path) -> Result<Row> {
    let start = Instant::now();
    let all_sets: Vec<String> = sets.iter().cloned().chain(job.sets()).collect();
    let (series, outputs) = run_series(loaded, spec, &all_sets)?;
    write_run(&series, &outputs, job, dir, start.elapsed().as_secs_f64())
}

/// Runs several jobs of a sweep on this thread, each written and reported as [`run_one`] writes
/// and reports it: the runs of one whisker (not arrays) step together in lanes
/// ([`sim::run_together`]; each to the bits it reaches alone), and each is reported with an
/// equal share of their time plus its own writing.
pub fn run_batch(
    batch: &[(&Loaded, &Job)],
    spec: &str,
    sets: &[String],
    dir: &Path,
) -> Vec<Result<Row>> {
    let start = Instant::now();
    let singles: Vec<&Loaded> = batch
        .iter()
        .map(|(l, _)| *l)
        .filter(|l| l.whiskers.is_empty())
        .collect();
    let scenarios: Vec<sim::Scenario> = singles.iter().map(|l| l.scenario.clone()).collect();
    let mut outputs = sim::run_together(&scenarios).into_iter();
    let share = start.elapsed().as_secs_f64() / singles.len().max(1) as f64;
    batch
        .iter()
        .map(|&(loaded, job)| {
            if !loaded.whiskers.is_empty() {
                return run_one(loaded, spec, sets, job, dir);
            }
            let start = Instant::now();
            let output = outputs.next().expect("one output per run of one whisker")?;
            let all_sets: Vec<String> = sets.iter().cloned().chain(job.sets()).collect();
            let series = series_of(loaded, &output, spec, &all_sets);
            write_run(
                &series,
                &[output],
                job,
                dir,
                share + start.elapsed().as_secs_f64(),
            )
        })
        .collect()
}

/// Writes a run's `series` (of its `outputs`, one per whisker) as `job`'s file, and its row of
/// the manifest (`seconds`: the time it took).
fn write_run(
    series: &Series,
    outputs: &[Output],
    job: &Job,
    dir: &Path,
    seconds: f64,
) -> Result<Row> {
    let start = Instant::now();
    series::write(series, dir.join(&job.file))?;
    let penetration = outputs
        .iter()
        .map(|o| o.max_penetration)
        .fold(0.0, f64::max);
    Ok(Row {
        samples: series.rows().to_string(),
        steps: outputs.iter().map(|o| o.steps).sum::<usize>().to_string(),
        seconds: format!("{:.6}", seconds + start.elapsed().as_secs_f64()),
        max_penetration: if penetration == 0.0 {
            "0".to_string()
        } else {
            format!("{penetration:e}")
        },
    })
}

/// Parses the `--grid` arguments; a key may appear once.
pub fn parse_grids(texts: &[String]) -> Result<Vec<Grid>> {
    let mut grids: Vec<Grid> = Vec::new();
    for text in texts {
        let grid = parse_grid(text)?;
        if grids.iter().any(|g| g.key == grid.key) {
            return Err(Error::Grid(format!(
                "--grid `{text}`: `{}` is already varied by another --grid; give all its \
                 values in one",
                grid.key
            )));
        }
        grids.push(grid);
    }
    Ok(grids)
}

/// Parses one `--grid`: `key=v1,v2,...` or `key=start:stop:count`.
pub fn parse_grid(text: &str) -> Result<Grid> {
    let fail = |what: &str| {
        Error::Grid(format!(
            "--grid `{text}`: {what}; expected key=v1,v2,... or key=start:stop:count, \
             e.g. d=0.015,0.02 or d=0.015:0.03:16"
        ))
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
        let list: Vec<String> = split_values(values)
            .into_iter()
            .map(|v| v.trim().to_string())
            .collect();
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

/// A grid's values split at the commas that are not inside brackets or quotes, so that a value
/// may be an array (`[0.0, 0.3]`) or a string with a comma.
fn split_values(text: &str) -> Vec<&str> {
    let (mut out, mut start, mut depth, mut quote) = (Vec::new(), 0, 0i32, None);
    for (i, c) in text.char_indices() {
        match (c, quote) {
            ('"' | '\'', None) => quote = Some(c),
            (q, Some(open)) if q == open => quote = None,
            ('[', None) => depth += 1,
            (']', None) => depth -= 1,
            (',', None) if depth == 0 => {
                out.push(&text[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    out.push(&text[start..]);
    out
}

/// `x` as a `--set` value: 12 significant digits, without rounding noise; whole numbers as
/// integers (`3`, which integer keys such as `segments` need), very small or large magnitudes
/// in exponent form.
pub fn number_value(x: f64) -> String {
    let x: f64 = format!("{x:.11e}").parse().unwrap_or(x);
    if x == x.trunc() && x.abs() < 1e15 {
        format!("{}", x as i64)
    } else if x.abs() < 1e-4 || x.abs() >= 1e15 {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// The grid of an experiment family (docs/experiments.md): e1 varies d = 15, 16, …, 30 mm; e2 also
/// v = 0.3, 0.6, …, 1.5 m/s.
pub fn experiment_grid(experiment: Experiment) -> Vec<Grid> {
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
pub fn plan(grids: &[Grid], ext: &str) -> Result<Vec<Job>> {
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
            return Err(Error::Grid(format!(
                "the file name of run {} would be {} bytes long; vary fewer keys or give \
                 shorter values",
                job.label(),
                job.file.len()
            )));
        }
        if job.file == MANIFEST {
            return Err(Error::Grid(format!(
                "run {} would be named like the manifest",
                job.label()
            )));
        }
        if let Some(&other) = names.get(&job.file) {
            let other: &Job = &jobs[other];
            return Err(Error::Grid(format!(
                "runs {} and {} would both be named `{}`; give values that differ in letters, \
                 digits, `.`, `-` or `+`",
                other.label(),
                job.label(),
                job.file
            )));
        }
        names.insert(job.file.clone(), k);
        jobs.push(job);
    }
    Ok(jobs)
}

/// A run's file name: each key and its value run together, joined by `_`, then the extension
/// (`d0.015_v0.3.csv`). Letters, digits, `.`, `-` and `+` are kept; quotes are dropped; any
/// other character (`_` included, so that it only ever separates parameters) becomes `-`.
pub fn file_name(params: &[(String, String)], ext: &str) -> String {
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
pub struct Row {
    /// Samples in the run's series.
    pub samples: String,
    /// Integrator steps.
    pub steps: String,
    /// Wall time of the run (simulation and writing), s.
    pub seconds: String,
    /// Largest penetration into an object, m.
    pub max_penetration: String,
}

impl Row {
    /// A finished run whose figures are not known (its files exist, the manifest lacked it).
    pub fn unknown() -> Row {
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
pub struct Manifest {
    /// Where it is written.
    pub path: PathBuf,
    /// The grid's keys (one column each).
    pub keys: Vec<String>,
    /// Per job: its row once finished.
    pub rows: Vec<Option<Row>>,
}

/// The manifest's columns after `file` and the grid's keys.
const FIGURES: [&str; 4] = ["samples", "steps", "seconds", "max_penetration"];

impl Manifest {
    /// Rewrites the file (atomically).
    pub fn write(&self, jobs: &[Job]) -> Result<()> {
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
        crate::atomic::stage(&self.path, |w| w.write_all(text.as_bytes()))?.commit()
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

/// Splits one CSV record written by [`push_record`] (a field with a comma, quote or line break
/// is quoted, a quote inside doubled).
pub fn split_record(line: &str) -> Vec<String> {
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
pub fn read_manifest(path: &Path) -> HashMap<String, Row> {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_may_be_arrays_or_quoted() {
        let g = parse_grid("objects.0.velocity=[0.0, 0.3], [0.0,0.6]").unwrap();
        assert_eq!(g.values, ["[0.0, 0.3]", "[0.0,0.6]"]);
        let g = parse_grid("whisker.preset=\"w30\",'a,b'").unwrap();
        assert_eq!(g.values, ["\"w30\"", "'a,b'"]);
    }

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
