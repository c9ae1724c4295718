//! Labelled recordings (docs/files.md, "Labelled recordings"): a folder of time series in the
//! contract's CSV columns plus `truth.csv`, which names each recording in a `file` column and
//! gives its labels (the scenario keys whose values are known for it, such as `d` and `v`), in SI
//! units.
//!
//! [`read_labelled`] reads and checks the whole folder before anything is computed. It refuses,
//! with the file, line and field named:
//! - a folder without `truth.csv`, a `truth.csv` without a `file` column or without rows, a
//!   recording named twice, an empty or non-finite label;
//! - a label column that the nominal scenario does not accept as a `--set` key (each row's labels
//!   are applied to the scenario as overrides and the result must load);
//! - a named recording that does not exist; a `.csv` file in the folder that `truth.csv` does not
//!   name (unless [`Options::ignore_unlisted`]);
//! - a recording without the columns `t`, `theta01` and `theta12`, with fewer than two rows, with
//!   a `t` that is not finite or not strictly increasing, or whose step varies by more than 1%
//!   ([`STEP_TOLERANCE`]) from its median (a gap);
//! - a recording whose sample rate differs by more than 1% from the set's median rate.
//!
//! Lines starting with `#` are comments; any other file in the folder (a sidecar `.json`, a
//! README) is ignored.

use crate::error::{Error, Result};
use crate::scenario::Document;
use crate::series::{parse_csv, Series};
use std::path::{Path, PathBuf};

/// Name of the labels file inside the folder.
pub const TRUTH: &str = "truth.csv";

/// Columns every recording must have.
pub const REQUIRED: [&str; 3] = ["t", "theta01", "theta12"];

/// Largest relative deviation of a sample step from the recording's median step, and of a
/// recording's rate from the set's median rate.
pub const STEP_TOLERANCE: f64 = 0.01;

/// How to read a folder.
#[derive(Debug, Clone, Copy, Default)]
pub struct Options {
    /// Skip `.csv` files that `truth.csv` does not name instead of refusing the folder.
    pub ignore_unlisted: bool,
}

/// One labelled recording.
#[derive(Debug, Clone)]
pub struct Recording {
    /// The name `truth.csv` gives it (relative to the folder).
    pub file: String,
    /// Its path.
    pub path: PathBuf,
    /// Its columns (`t`, `theta01`, `theta12` at least).
    pub series: Series,
    /// Its labels, in `truth.csv`'s column order: scenario key and value (SI).
    pub labels: Vec<(String, f64)>,
    /// Median sample step, s.
    pub step: f64,
}

impl Recording {
    /// The labels as `key=value` overrides of a scenario.
    pub fn overrides(&self) -> Vec<String> {
        overrides(&self.labels)
    }

    /// Sample times, s.
    pub fn t(&self) -> &[f64] {
        self.series.column("t").unwrap_or(&[])
    }

    /// A channel's values, if the recording has it.
    pub fn channel(&self, name: &str) -> Option<&[f64]> {
        self.series.column(name)
    }

    /// Sample rate, Hz (see [`sample_rate`]).
    pub fn rate(&self) -> f64 {
        sample_rate(self.t())
    }
}

/// The sample rate of constant-rate times `t` (at least two): samples per second over the whole
/// span, rounded to 9 significant digits so that times written as decimals (0.001, 0.002, …)
/// give the rate they were made at (1000 Hz, not 999.9999999997 Hz: a simulator that divides
/// the sample period into time steps would otherwise take a different step).
pub fn sample_rate(t: &[f64]) -> f64 {
    let n = t.len();
    if n < 2 {
        return f64::NAN;
    }
    let rate = (n - 1) as f64 / (t[n - 1] - t[0]);
    if !(rate.is_finite() && rate > 0.0) {
        return rate;
    }
    let scale = 10f64.powi(8 - rate.log10().floor() as i32);
    (rate * scale).round() / scale
}

/// A checked folder of labelled recordings.
#[derive(Debug, Clone)]
pub struct Labelled {
    /// The folder.
    pub dir: PathBuf,
    /// The label columns of `truth.csv` (scenario keys), in order.
    pub keys: Vec<String>,
    /// The recordings, in `truth.csv`'s order.
    pub recordings: Vec<Recording>,
    /// `.csv` files of the folder that `truth.csv` does not name, skipped as asked.
    pub ignored: Vec<String>,
}

/// `key=value` overrides of labels (values written to read back exactly).
fn overrides(labels: &[(String, f64)]) -> Vec<String> {
    labels.iter().map(|(k, v)| format!("{k}={v:?}")).collect()
}

/// Reads and checks the folder `dir`; `nominal` is the scenario the labels must apply to.
pub fn read_labelled(dir: &Path, nominal: &Document, options: &Options) -> Result<Labelled> {
    let truth_path = dir.join(TRUTH);
    let folder_error = |message: String| Error::Labelled {
        path: dir.to_path_buf(),
        message,
    };
    if !dir.is_dir() {
        return Err(folder_error(
            "is not a folder of labelled recordings".to_string(),
        ));
    }
    if !truth_path.is_file() {
        return Err(folder_error(format!(
            "no {TRUTH} (a `file` column naming each recording, one column per label)"
        )));
    }
    let truth = read_truth(&truth_path)?;

    // Each label column must be a key the scenario accepts, and each row's labels must load.
    let origin = truth_path.display().to_string();
    if let Some(first) = truth.rows.first() {
        for (c, key) in truth.keys.iter().enumerate() {
            let set = overrides(&[(key.clone(), first.labels[c])]);
            if let Err(e) = nominal.loaded_with(&set) {
                return Err(Error::Field {
                    origin: origin.clone(),
                    field: key.clone(),
                    message: format!(
                        "names no key that the scenario {} accepts: {e}",
                        nominal.origin()
                    ),
                });
            }
        }
    }
    for row in &truth.rows {
        let labels = labels_of(&truth.keys, &row.labels);
        if let Err(e) = nominal.loaded_with(&overrides(&labels)) {
            return Err(Error::data(
                &origin,
                row.line,
                format!(
                    "the labels of `{}` do not give a valid scenario: {e}",
                    row.file
                ),
            ));
        }
    }

    // Every recording in the folder must be named (or skipped as asked).
    let mut ignored = Vec::new();
    let mut unlisted = Vec::new();
    for name in csv_files(dir)? {
        if name != TRUTH
            && !truth
                .rows
                .iter()
                .any(|r| Path::new(&r.file) == Path::new(&name))
        {
            if options.ignore_unlisted {
                ignored.push(name);
            } else {
                unlisted.push(name);
            }
        }
    }
    if !unlisted.is_empty() {
        return Err(folder_error(format!(
            "{} not named in {TRUTH}: {} (name {} there, or ignore unlisted files)",
            if unlisted.len() == 1 {
                "a recording is"
            } else {
                "recordings are"
            },
            unlisted.join(", "),
            if unlisted.len() == 1 { "it" } else { "them" },
        )));
    }

    // Read and check every named recording.
    let mut recordings = Vec::with_capacity(truth.rows.len());
    for row in &truth.rows {
        let path = dir.join(&row.file);
        if !path.is_file() {
            return Err(Error::data(
                &origin,
                row.line,
                format!(
                    "`file` names `{}`, which does not exist in {}",
                    row.file,
                    dir.display()
                ),
            ));
        }
        let (series, step) = read_recording(&path)?;
        recordings.push(Recording {
            file: row.file.clone(),
            path,
            series,
            labels: labels_of(&truth.keys, &row.labels),
            step,
        });
    }

    // One sample rate for the whole set.
    let mut steps: Vec<f64> = recordings.iter().map(|r| r.step).collect();
    let median = median(&mut steps);
    for r in &recordings {
        if (r.step / median - 1.0).abs() > STEP_TOLERANCE {
            return Err(Error::data(
                &r.path.display().to_string(),
                0,
                format!(
                    "sampled at {:.6} Hz, while the other recordings of {} are at {:.6} Hz \
                     (rates must agree within {}%)",
                    1.0 / r.step,
                    dir.display(),
                    1.0 / median,
                    STEP_TOLERANCE * 100.0
                ),
            ));
        }
    }

    Ok(Labelled {
        dir: dir.to_path_buf(),
        keys: truth.keys,
        recordings,
        ignored,
    })
}

/// `truth.csv` as read: label keys, and one row per recording.
struct Truth {
    keys: Vec<String>,
    rows: Vec<TruthRow>,
}

struct TruthRow {
    /// 1-based line in `truth.csv`.
    line: usize,
    file: String,
    labels: Vec<f64>,
}

fn labels_of(keys: &[String], values: &[f64]) -> Vec<(String, f64)> {
    keys.iter().cloned().zip(values.iter().copied()).collect()
}

/// Reads `truth.csv`: a header with a `file` column and label columns, then one row per
/// recording with a file name and finite numbers.
fn read_truth(path: &Path) -> Result<Truth> {
    let origin = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| Error::io("read", path, e))?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let mut header: Option<Vec<String>> = None;
    let mut file_col = 0;
    let mut rows: Vec<TruthRow> = Vec::new();
    for (k, raw) in text.lines().enumerate() {
        let (line, content) = (k + 1, raw.trim());
        if content.is_empty() || content.starts_with('#') {
            continue;
        }
        let cells: Vec<&str> = content.split(',').map(|c| unquote(c.trim())).collect();
        let Some(names) = &header else {
            // The header: `file` and unique, non-empty label names.
            for (c, name) in cells.iter().enumerate() {
                if name.is_empty() {
                    return Err(Error::data(
                        &origin,
                        line,
                        format!("column {} of the header has no name", c + 1),
                    ));
                }
                if cells[..c].contains(name) {
                    return Err(Error::data(
                        &origin,
                        line,
                        format!("column `{name}` appears twice in the header"),
                    ));
                }
            }
            file_col = cells.iter().position(|c| *c == "file").ok_or_else(|| {
                Error::data(
                    &origin,
                    line,
                    format!(
                        "the header `{}` has no `file` column naming the recordings",
                        cells.join(",")
                    ),
                )
            })?;
            header = Some(cells.iter().map(|c| c.to_string()).collect());
            continue;
        };
        if cells.len() != names.len() {
            return Err(Error::data(
                &origin,
                line,
                format!(
                    "{} values, but the header has {} columns",
                    cells.len(),
                    names.len()
                ),
            ));
        }
        let file = cells[file_col].to_string();
        if file.is_empty() {
            return Err(Error::data(&origin, line, "column `file` is empty"));
        }
        if let Some(first) = rows.iter().find(|r| r.file == file) {
            return Err(Error::data(
                &origin,
                line,
                format!("`{file}` is named twice (also on line {})", first.line),
            ));
        }
        let mut labels = Vec::with_capacity(names.len() - 1);
        for (c, cell) in cells.iter().enumerate() {
            if c == file_col {
                continue;
            }
            match cell.parse::<f64>() {
                Ok(x) if x.is_finite() => labels.push(x),
                Ok(_) => {
                    return Err(Error::data(
                        &origin,
                        line,
                        format!(
                            "column `{}`: `{cell}` is not finite (labels are finite numbers in SI units)",
                            names[c]
                        ),
                    ))
                }
                Err(_) => {
                    return Err(Error::data(
                        &origin,
                        line,
                        format!("column `{}`: `{cell}` is not a number", names[c]),
                    ))
                }
            }
        }
        rows.push(TruthRow { line, file, labels });
    }
    let Some(names) = header else {
        return Err(Error::data(
            &origin,
            0,
            "no header row (expected `file` and one column per label, e.g. `file,d,v`)",
        ));
    };
    if rows.is_empty() {
        return Err(Error::data(&origin, 0, "no recordings are named"));
    }
    let keys = names
        .into_iter()
        .enumerate()
        .filter(|&(c, _)| c != file_col)
        .map(|(_, n)| n)
        .collect();
    Ok(Truth { keys, rows })
}

/// `name` without surrounding double quotes.
fn unquote(name: &str) -> &str {
    name.strip_prefix('"')
        .and_then(|n| n.strip_suffix('"'))
        .unwrap_or(name)
}

/// Names of the `.csv` files (any case) directly inside `dir`, sorted.
fn csv_files(dir: &Path) -> Result<Vec<String>> {
    let mut names = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| Error::io("read", dir, e))? {
        let entry = entry.map_err(|e| Error::io("read", dir, e))?;
        let path = entry.path();
        let is_csv = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("csv"));
        if is_csv && path.is_file() {
            if let Some(name) = path.file_name().and_then(|n| n.to_str()) {
                names.push(name.to_string());
            }
        }
    }
    names.sort();
    Ok(names)
}

/// Reads one recording and checks its columns and times; returns it with its median step.
fn read_recording(path: &Path) -> Result<(Series, f64)> {
    let origin = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| Error::io("read", path, e))?;
    let (series, lines) = parse_csv(&text, &origin)?;
    let missing: Vec<&str> = REQUIRED
        .iter()
        .copied()
        .filter(|c| series.column(c).is_none())
        .collect();
    if !missing.is_empty() {
        return Err(Error::data(
            &origin,
            0,
            format!(
                "missing column{} {} (required: {}; present: {})",
                if missing.len() == 1 { "" } else { "s" },
                missing.join(", "),
                REQUIRED.join(", "),
                series.columns.join(", ")
            ),
        ));
    }
    let t = series.column("t").unwrap_or(&[]);
    if t.len() < 2 {
        return Err(Error::data(
            &origin,
            0,
            format!("{} rows: a recording needs at least two", t.len()),
        ));
    }
    // Finite and strictly increasing times.
    for k in 0..t.len() {
        if !t[k].is_finite() {
            return Err(Error::data(
                &origin,
                lines[k],
                format!("row {}: t is {} (times must be finite)", k + 1, t[k]),
            ));
        }
        if k > 0 && t[k] <= t[k - 1] {
            return Err(Error::data(
                &origin,
                lines[k],
                format!(
                    "row {}: t = {} does not increase (the previous row has t = {})",
                    k + 1,
                    t[k],
                    t[k - 1]
                ),
            ));
        }
    }
    // A constant step, within the tolerance.
    let mut steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    let step = median(&mut steps.clone());
    for (k, s) in steps.drain(..).enumerate() {
        if (s / step - 1.0).abs() > STEP_TOLERANCE {
            return Err(Error::data(
                &origin,
                lines[k + 1],
                format!(
                    "row {}: the step from the previous row is {s:.6e} s, more than {}% from \
                     the recording's step {step:.6e} s (a gap; resample to a constant rate)",
                    k + 2,
                    STEP_TOLERANCE * 100.0
                ),
            ));
        }
    }
    Ok((series, step))
}

/// Median of non-empty `x` (reordered).
fn median(x: &mut [f64]) -> f64 {
    x.sort_by(f64::total_cmp);
    let n = x.len();
    if n % 2 == 1 {
        x[n / 2]
    } else {
        0.5 * (x[n / 2 - 1] + x[n / 2])
    }
}
