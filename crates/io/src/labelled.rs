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
//!   are applied to the scenario as overrides and the result must load); a label whose value the
//!   scenario refuses is named with its line, its recording and what is allowed;
//! - a named recording that does not exist; a `.csv` file in the folder that `truth.csv` does not
//!   name (unless [`Options::ignore_unlisted`]);
//! - a recording without the columns `t`, `theta01` and `theta12`, with fewer than two rows, with
//!   a `t` that is not finite or not strictly increasing, or whose step varies by more than 1%
//!   ([`STEP_TOLERANCE`]) from its median (a gap);
//! - a recording whose sample rate differs by more than 1% from the rate most recordings share
//!   (on a tie, the rate of the earliest in `truth.csv`), named with its rate and theirs.
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

/// `key=value` overrides of labels, each value written to read back exactly: a whole number as
/// an integer (which a key of whole numbers, such as `segments`, needs, and a key of reals
/// accepts), any other as a real.
fn overrides(labels: &[(String, f64)]) -> Vec<String> {
    labels
        .iter()
        .map(|(k, v)| {
            let whole =
                v.fract() == 0.0 && v.abs() < 9.0e15 && !(*v == 0.0 && v.is_sign_negative());
            if whole {
                format!("{k}={}", *v as i64)
            } else {
                format!("{k}={v:?}")
            }
        })
        .collect()
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

    // Each label column must be a key the scenario accepts, and each row's labels must load. A
    // key whose first value the scenario refuses as out of range is a key it accepts: that value
    // is reported with its row below.
    let origin = truth_path.display().to_string();
    if let Some(first) = truth.rows.first() {
        for (c, key) in truth.keys.iter().enumerate() {
            let set = overrides(&[(key.clone(), first.labels[c])]);
            if let Err(e) = nominal.loaded_with(&set) {
                if out_of_range(&e).is_some() {
                    continue;
                }
                // A key the scenario has, given a value of another kind (a fraction for a
                // whole number): the value is what is wrong, and its row is named.
                let wrong_kind = e.to_string().contains("invalid type");
                let message = if wrong_kind {
                    format!(
                        "line {}: {} is not a value the key takes: {e}",
                        first.line, first.labels[c]
                    )
                } else {
                    format!(
                        "names no key that the scenario {} accepts: {e}",
                        nominal.origin()
                    )
                };
                return Err(Error::Field {
                    origin: origin.clone(),
                    field: key.clone(),
                    message,
                });
            }
        }
    }
    for row in &truth.rows {
        let labels = labels_of(&truth.keys, &row.labels);
        if let Err(e) = nominal.loaded_with(&overrides(&labels)) {
            return Err(row_error(nominal, &origin, row, &labels, &e));
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

    check_rates(dir, &recordings)?;

    Ok(Labelled {
        dir: dir.to_path_buf(),
        keys: truth.keys,
        recordings,
        ignored,
    })
}

/// The parameter, its value and what is allowed, when `e` is the scenario's verdict that a
/// value is out of range (the key itself was accepted).
fn out_of_range(e: &Error) -> Option<(&str, &str, &str)> {
    match e.core() {
        Some(vibrissa_core::Error::InvalidParameter {
            name,
            value,
            allowed,
        }) => Some((name, value, allowed)),
        _ => None,
    }
}

/// Why the labels of `row` (as `labels`) do not give a valid scenario, `e` the scenario's
/// verdict on them together: the first label whose value the scenario refuses on its own, named
/// with its value and what is allowed; else the label the verdict names; else the verdict.
fn row_error(
    nominal: &Document,
    origin: &str,
    row: &TruthRow,
    labels: &[(String, f64)],
    e: &Error,
) -> Error {
    let message = |key: &str, value: f64, (name, got, allowed): (&str, &str, &str)| {
        let what = if name == key {
            format!("allowed is {allowed}")
        } else {
            format!("it makes {name} = {got}, where allowed is {allowed}")
        };
        format!(
            "`{key}` = {value} for `{}` is out of range; {what}",
            row.file
        )
    };
    for (key, value) in labels {
        if let Err(alone) = nominal.loaded_with(&overrides(&[(key.clone(), *value)])) {
            if let Some(verdict) = out_of_range(&alone) {
                return Error::data(origin, row.line, message(key, *value, verdict));
            }
        }
    }
    if let Some(verdict) = out_of_range(e) {
        if let Some((key, value)) = labels.iter().find(|(k, _)| k == verdict.0) {
            return Error::data(
                origin,
                row.line,
                format!(
                    "{} (with the other labels of the row)",
                    message(key, *value, verdict)
                ),
            );
        }
    }
    Error::data(
        origin,
        row.line,
        format!(
            "the labels of `{}` do not give a valid scenario: {e}",
            row.file
        ),
    )
}

/// Checks that `recordings` share one sample rate. The reference is the rate that most of them
/// share (within [`STEP_TOLERANCE`]; on a tie, the group of the earliest in `truth.csv`); the
/// first recording that differs from it by more is refused, with its own rate and the rate of
/// the recordings that agree (computed without it).
fn check_rates(dir: &Path, recordings: &[Recording]) -> Result<()> {
    let n = recordings.len();
    let steps: Vec<f64> = recordings.iter().map(|r| r.step).collect();
    let close = |a: f64, b: f64| (a / b - 1.0).abs() <= STEP_TOLERANCE;
    let agreeing = |i: usize| steps.iter().filter(|&&s| close(s, steps[i])).count();
    let Some(anchor) = (0..n).max_by_key(|&i| (agreeing(i), std::cmp::Reverse(i))) else {
        return Ok(());
    };
    let mut group: Vec<f64> = steps
        .iter()
        .copied()
        .filter(|&s| close(s, steps[anchor]))
        .collect();
    let reference = median(&mut group);
    let Some(odd) = recordings.iter().find(|r| !close(r.step, reference)) else {
        return Ok(());
    };
    // The recordings that agree with the reference (the odd one is not among them), or all the
    // others should none agree exactly.
    let mut others: Vec<&Recording> = recordings
        .iter()
        .filter(|r| close(r.step, reference))
        .collect();
    if others.is_empty() {
        others = recordings
            .iter()
            .filter(|r| !std::ptr::eq(*r, odd))
            .collect();
    }
    let mut other_steps: Vec<f64> = others.iter().map(|r| r.step).collect();
    let rate = 1.0 / median(&mut other_steps);
    let folder = dir.display();
    let who = match (others.len(), n - 1) {
        (1, 1) => format!("the other recording of {folder}, {}, is", others[0].file),
        (k, m) if k == m => format!("the other {k} recordings of {folder} are"),
        (1, _) => format!("{} in {folder} is", others[0].file),
        (k, m) => format!("{k} of the other {m} recordings of {folder} are"),
    };
    Err(Error::data(
        &odd.path.display().to_string(),
        0,
        format!(
            "sampled at {:.6} Hz, while {who} at {rate:.6} Hz (rates must agree within {}%)",
            1.0 / odd.step,
            STEP_TOLERANCE * 100.0
        ),
    ))
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh folder for one test.
    fn folder(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("vibrissa-labelled-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// A recording of `n` rows at `rate` Hz with the required columns.
    fn recording(n: usize, rate: f64) -> String {
        let mut text = String::from("t,theta01,theta12\n");
        for k in 0..n {
            text.push_str(&format!("{},0,0\n", k as f64 / rate));
        }
        text
    }

    /// Writes recordings at `rates` (named r0.csv, r1.csv, …) and a truth.csv labelling them.
    fn recordings(dir: &Path, rates: &[f64]) {
        let mut truth = String::from("file,d,v\n");
        for (k, rate) in rates.iter().enumerate() {
            std::fs::write(dir.join(format!("r{k}.csv")), recording(30, *rate)).unwrap();
            truth.push_str(&format!("r{k}.csv,0.02,0.6\n"));
        }
        std::fs::write(dir.join(TRUTH), truth).unwrap();
    }

    fn refused(dir: &Path) -> String {
        let nominal = Document::load("e2", &[]).unwrap();
        match read_labelled(dir, &nominal, &Options::default()) {
            Ok(set) => panic!("expected a refusal, read {}", set.recordings.len()),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn a_label_out_of_range_is_named_with_its_line_recording_and_allowed_values() {
        let dir = folder("range");
        recordings(&dir, &[1000.0, 1000.0]);
        // In the first row (whose values also decide whether the columns are keys) and in a
        // later one.
        for (truth, line, file) in [
            ("file,d,v\nr0.csv,-0.02,0.6\nr1.csv,0.02,0.6\n", 2, "r0.csv"),
            ("file,d,v\nr0.csv,0.02,0.6\nr1.csv,-0.02,0.6\n", 3, "r1.csv"),
        ] {
            std::fs::write(dir.join(TRUTH), truth).unwrap();
            let e = refused(&dir);
            assert!(
                e.contains(&format!("truth.csv, line {line}: `d` = -0.02 for `{file}`"))
                    && e.contains("out of range; allowed is a distance from the base > 0 m")
                    && !e.contains("names no key"),
                "{e}"
            );
        }
        // A value that makes another parameter invalid names both.
        std::fs::write(
            dir.join(TRUTH),
            "file,d,v,whisker.base_radius\nr0.csv,0.02,0.6,1e-6\nr1.csv,0.02,0.6,1e-6\n",
        )
        .unwrap();
        let e = refused(&dir);
        assert!(
            e.contains("line 2: `whisker.base_radius` = 0.000001 for `r0.csv` is out of range")
                && e.contains("whisker.tip_radius"),
            "{e}"
        );
        // A column that is no key is still reported as such.
        std::fs::write(
            dir.join(TRUTH),
            "file,d,speed\nr0.csv,0.02,0.6\nr1.csv,0.02,0.6\n",
        )
        .unwrap();
        let e = refused(&dir);
        assert!(e.contains("`speed` names no key"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_recording_at_another_rate_is_compared_with_the_others_alone() {
        let dir = folder("rates");
        // Two recordings: the first one's rate is the reference.
        recordings(&dir, &[1000.0, 500.0]);
        let e = refused(&dir);
        assert!(
            e.contains("r1.csv: sampled at 500.000000 Hz")
                && e.contains("the other recording of")
                && e.contains("r0.csv, is at 1000.000000 Hz"),
            "{e}"
        );
        // The majority's rate is the reference, whichever comes first.
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        recordings(&dir, &[500.0, 1000.0, 1000.0]);
        let e = refused(&dir);
        assert!(
            e.contains("r0.csv: sampled at 500.000000 Hz")
                && e.contains("the other 2 recordings of")
                && e.contains("are at 1000.000000 Hz"),
            "{e}"
        );
        // Several rates: the most common one is the reference (on a tie, the first one's), and
        // the message says which recordings share it.
        for (rates, who) in [
            (
                &[1000.0, 1000.0, 500.0, 250.0][..],
                "2 of the other 3 recordings of",
            ),
            (&[1000.0, 500.0, 250.0][..], "while r0.csv in"),
        ] {
            let _ = std::fs::remove_dir_all(&dir);
            std::fs::create_dir_all(&dir).unwrap();
            recordings(&dir, rates);
            let e = refused(&dir);
            let odd = format!("r{}.csv: sampled at 500.000000 Hz", rates.len() - 2);
            assert!(
                e.contains(&odd) && e.contains(who) && e.contains("at 1000.000000 Hz"),
                "{e}"
            );
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
