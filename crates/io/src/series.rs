//! Time series in the contract's formats.
//!
//! A [`Series`] is a table of named `f64` columns plus `key = value` metadata (the segment count
//! of a run, its scenario, …). [`write()`] writes the data in the format its extension names and
//! the metadata in a JSON **sidecar** beside it, with the same name and the extension `.json`
//! (`run.json` beside `run.csv`; see [`sidecar_path`]):
//!
//! - **CSV** ([`write_csv`], read back by [`read_csv`]): the contract's format. One header row,
//!   then one row per sample, and nothing else, so that `numpy.genfromtxt(f, delimiter=",",
//!   names=True)`, `numpy.loadtxt(f, delimiter=",", skiprows=1)`, `pandas.read_csv(f)` and
//!   `polars.read_csv(f)` read it with their defaults. Values are written with enough digits to
//!   read back bit for bit, always as floating-point literals (`0.0`, `1.0`, `2.5e-12`), with
//!   `.` as decimal point and `NaN` for a missing value. The reader still accepts `#` comment
//!   lines anywhere, as the contract allows, and takes `# key = value` lines as metadata.
//! - **NPY** ([`write_npy`]): one 2-D little-endian `float64` array, rows × columns in C order,
//!   NPY format version 1.0 (`numpy.load` reads it). The columns are in the series' order, which
//!   for a simulated run is the contract's ([`vibrissa_core::sim::COLUMNS`]); the sidecar names
//!   them.
//! - **NPZ** ([`write_npz`]): a ZIP archive (stored, uncompressed) of one 1-D NPY array per
//!   column, named after it (`t.npy`, `theta01.npy`, …), so `numpy.load(f)["theta12"]` works. The
//!   archive holds only the columns; the metadata is in the sidecar as for the other formats.
//!
//! The sidecar ([`sidecar`] describes its layout) records the data file's name, its row count and
//! columns beside the metadata, so that a reader can tell whether it belongs to the data it sits
//! beside. [`read_csv_with_sidecar`] reads a CSV and adds its sidecar's metadata; a missing
//! sidecar is fine, and one that is malformed or does not match the data only gives a
//! [`SidecarWarning`]: the data file alone is always readable.
//!
//! Every writer first writes a temporary file beside the target and renames it into place when
//! everything has been written, so a failure never leaves a half-written file behind. [`write()`]
//! writes both files before renaming either, and renames the data file last: whenever the data
//! file is in place, its sidecar is complete.
//!
//! Values must be finite or `NaN`: infinities are refused on writing and on reading.

mod csv;
mod npy;
pub mod sidecar;

pub use csv::{read_csv, read_csv_str, to_csv_string, write_csv};
pub use npy::{npy_header, write_npy, write_npz};
pub use sidecar::{
    merge_sidecar, read_csv_with_sidecar, read_csv_with_sidecar_lines, sidecar_path, SidecarWarning,
};

pub(crate) use csv::parse_csv;

use crate::error::{Error, Result};
use std::path::Path;

/// Output formats by extension, as accepted by [`write()`].
pub const EXTENSIONS: [&str; 3] = ["csv", "npy", "npz"];

/// A table of named columns of `f64` plus metadata.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Series {
    /// Column names, in order.
    pub columns: Vec<String>,
    /// Values, column-major: `data[c][row]`; every column has the same length.
    pub data: Vec<Vec<f64>>,
    /// `key = value` metadata, in order: the sidecar's `meta` entries (and a read CSV's
    /// `# key = value` comment lines).
    pub meta: Vec<(String, String)>,
}

impl Series {
    /// An empty series (no rows) with these columns.
    pub fn new<S: AsRef<str>>(columns: &[S]) -> Self {
        Series {
            columns: columns.iter().map(|c| c.as_ref().to_string()).collect(),
            data: vec![Vec::new(); columns.len()],
            meta: Vec::new(),
        }
    }

    /// Appends one row.
    ///
    /// # Panics
    /// If `row` does not have one value per column.
    pub fn push_row(&mut self, row: &[f64]) {
        assert_eq!(
            row.len(),
            self.columns.len(),
            "a row needs one value per column"
        );
        for (col, &x) in self.data.iter_mut().zip(row) {
            col.push(x);
        }
    }

    /// Adds (or replaces) a metadata entry.
    pub fn set_meta(&mut self, key: impl Into<String>, value: impl ToString) {
        let (key, value) = (key.into(), value.to_string());
        match self.meta.iter_mut().find(|(k, _)| *k == key) {
            Some(entry) => entry.1 = value,
            None => self.meta.push((key, value)),
        }
    }

    /// The value of a metadata entry.
    pub fn meta_value(&self, key: &str) -> Option<&str> {
        self.meta
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    /// Number of rows (0 without columns).
    pub fn rows(&self) -> usize {
        self.data.first().map_or(0, Vec::len)
    }

    /// The values of a column.
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        self.columns
            .iter()
            .position(|c| c == name)
            .map(|k| self.data[k].as_slice())
    }

    /// The values of each named column, in the order asked; an error lists every missing column
    /// and the columns present.
    pub fn require(&self, names: &[&str]) -> Result<Vec<&[f64]>> {
        let missing: Vec<String> = names
            .iter()
            .filter(|n| self.column(n).is_none())
            .map(|n| n.to_string())
            .collect();
        if !missing.is_empty() {
            return Err(Error::MissingColumns {
                missing,
                present: self.columns.clone(),
            });
        }
        Ok(names.iter().filter_map(|n| self.column(n)).collect())
    }

    /// Checks that the series can be written: one data vector per column, all of one length,
    /// unique column names that a CSV header can hold, metadata keys that a `# key = value` line
    /// could also hold and values of one line, and no infinite values.
    pub fn check(&self) -> Result<()> {
        let bad = |m: String| Err(Error::InvalidSeries(m));
        // Shape.
        if self.data.len() != self.columns.len() {
            return bad(format!(
                "{} columns named but {} data vectors",
                self.columns.len(),
                self.data.len()
            ));
        }
        let rows = self.rows();
        for (name, col) in self.columns.iter().zip(&self.data) {
            if col.len() != rows {
                return bad(format!(
                    "column `{name}` has {} values, column `{}` has {rows}",
                    col.len(),
                    self.columns[0]
                ));
            }
        }
        // Names.
        for (k, name) in self.columns.iter().enumerate() {
            if !is_column_name(name) {
                return bad(format!("column name {name:?}: {COLUMN_NAME_RULE}"));
            }
            if self.columns[..k].contains(name) {
                return bad(format!("column `{name}` appears twice"));
            }
        }
        // Metadata.
        for (key, value) in &self.meta {
            if !is_meta_key(key) {
                return bad(format!(
                    "metadata key {key:?}: keys are letters, digits, `_`, `-` and `.`"
                ));
            }
            if value.contains(['\n', '\r']) {
                return bad(format!("metadata `{key}`: the value contains a line break"));
            }
        }
        // Values.
        for (name, col) in self.columns.iter().zip(&self.data) {
            if let Some(row) = col.iter().position(|x| x.is_infinite()) {
                return bad(format!(
                    "column `{name}`, row {row}: {} (values must be finite or NaN)",
                    col[row]
                ));
            }
        }
        Ok(())
    }
}

/// What a column name may hold, for messages.
pub(crate) const COLUMN_NAME_RULE: &str = "names must be non-empty, without commas, quotes, \
     control characters, byte-order marks or surrounding spaces, and must not start with `#`";

/// Whether `name` can be a column name in every format.
pub(crate) fn is_column_name(name: &str) -> bool {
    !name.is_empty()
        && name.trim() == name
        && !name.starts_with('#')
        && !name.contains([',', '"', '\u{feff}'])
        && !name.chars().any(char::is_control)
}

/// Whether `key` is a metadata key (what [`read_csv`] recognises on a comment line).
pub(crate) fn is_meta_key(key: &str) -> bool {
    !key.is_empty()
        && key
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'))
}

/// Writes `series` in the format its extension names, `.csv`, `.npy` or `.npz` (any case), and
/// its sidecar beside it ([`sidecar_path`]: the same name with the extension `.json`).
///
/// Both files are written under temporary names first; then the sidecar is renamed into place,
/// and the data file last. If anything fails, neither new file is left: an existing data file
/// keeps its old content (an existing sidecar may be gone, which readers take as no metadata).
pub fn write(series: &Series, path: impl AsRef<Path>) -> Result<()> {
    let path = path.as_ref();
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let data = match ext.as_deref() {
        Some("csv") => csv::stage_csv(series, path)?,
        Some("npy") => npy::stage_npy(series, path)?,
        Some("npz") => npy::stage_npz(series, path)?,
        _ => {
            return Err(Error::Format {
                path: path.to_path_buf(),
                allowed: EXTENSIONS.iter().map(|e| format!(".{e}")).collect(),
            })
        }
    };
    let sidecar = sidecar::stage_sidecar(series, path)?;
    sidecar.commit()?;
    if let Err(e) = data.commit() {
        // The data did not take its place: a sidecar without it would describe other data.
        let _ = std::fs::remove_file(sidecar_path(path));
        return Err(e);
    }
    Ok(())
}
