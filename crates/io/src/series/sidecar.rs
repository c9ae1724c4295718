//! The sidecar: a series' metadata in a JSON file beside its data file, with the same name and
//! the extension `.json` (`run.json` beside `run.csv`, `run.npy` or `run.npz`).
//!
//! ```json
//! {
//!   "file": "run.csv",
//!   "rows": 151,
//!   "columns": ["t", "theta01", "theta12", "m0", "fx", "fy", "contact", "cx", "cy", "s"],
//!   "meta": { "vibrissa": "0.1.0", "scenario": "e2", "segments": "20", "dt": "0.0001" }
//! }
//! ```
//!
//! `file`, `rows` and `columns` say which data the metadata belongs to; `meta` holds the
//! metadata entries in order, each value a string. On reading, only `meta` is required, a number
//! or `true`/`false` is taken as its text, and other keys are ignored.

use super::{is_meta_key, Series};
use crate::atomic::{stage, Staged};
use crate::error::Result;
use serde::de::{Deserializer, MapAccess, Visitor};
use serde::ser::Serializer;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::fmt;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

/// The sidecar of a data file: the same path with the extension `.json` (`run.csv` →
/// `run.json`).
pub fn sidecar_path(data: impl AsRef<Path>) -> PathBuf {
    data.as_ref().with_extension("json")
}

/// Something wrong with a sidecar found on reading. None of these is an error: the data file is
/// read all the same, without the sidecar's metadata (or, for a conflict, with the data file's
/// own value).
#[derive(Debug, thiserror::Error)]
pub enum SidecarWarning {
    /// The sidecar exists but cannot be read (a folder, no permission, not UTF-8).
    #[error("cannot read `{}`: {error}; its metadata is ignored", path.display())]
    Unreadable {
        /// The sidecar.
        path: PathBuf,
        /// What the operating system said.
        error: io::Error,
    },
    /// The sidecar is not JSON, or not in the sidecar's form.
    #[error("`{}` is not a valid sidecar: {message}; its metadata is ignored", path.display())]
    Malformed {
        /// The sidecar.
        path: PathBuf,
        /// What is wrong, with the line and column where the JSON parser gives them.
        message: String,
    },
    /// The sidecar records another file, other columns or another number of rows than the data
    /// file has: it describes other data.
    #[error("`{}` does not match `{}`: {message}; its metadata is ignored", path.display(), data.display())]
    Mismatch {
        /// The sidecar.
        path: PathBuf,
        /// The data file.
        data: PathBuf,
        /// What differs.
        message: String,
    },
    /// The data file carries a metadata entry itself (a `#` comment line of a CSV) that the
    /// sidecar gives another value.
    #[error("`{}` gives {key} = {in_sidecar:?}, but `{}` itself says {key} = {in_file:?}; the file's value is kept",
        path.display(), data.display())]
    Conflict {
        /// The sidecar.
        path: PathBuf,
        /// The data file.
        data: PathBuf,
        /// The metadata key.
        key: String,
        /// The data file's value.
        in_file: String,
        /// The sidecar's value.
        in_sidecar: String,
    },
}

/// The sidecar as written.
#[derive(Serialize)]
struct Written<'a> {
    file: String,
    rows: usize,
    columns: &'a [String],
    meta: OrderedMeta<'a>,
}

/// Metadata entries as a JSON object, in their order.
struct OrderedMeta<'a>(&'a [(String, String)]);

impl Serialize for OrderedMeta<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.collect_map(self.0.iter().map(|(k, v)| (k, v)))
    }
}

/// The JSON text of the sidecar of `series`, written as `data`.
fn sidecar_json(series: &Series, data: &Path) -> String {
    let written = Written {
        file: data
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        rows: series.rows(),
        columns: &series.columns,
        meta: OrderedMeta(&series.meta),
    };
    // Strings, numbers and arrays of strings always serialise.
    let mut text = serde_json::to_string_pretty(&written).unwrap_or_default();
    text.push('\n');
    text
}

/// Writes the sidecar of `series`, whose data goes to `data`, under a temporary name beside it.
pub(crate) fn stage_sidecar(series: &Series, data: &Path) -> Result<Staged> {
    let text = sidecar_json(series, data);
    stage(&sidecar_path(data), |w| w.write_all(text.as_bytes()))
}

/// The sidecar as read: only `meta` is required.
#[derive(Deserialize)]
#[serde(expecting = "a JSON object with a `meta` object")]
struct Found {
    file: Option<String>,
    rows: Option<usize>,
    columns: Option<Vec<String>>,
    meta: Entries,
}

/// A JSON object's entries, in the order of the document.
struct Entries(Vec<(String, Value)>);

impl<'de> Deserialize<'de> for Entries {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct EntriesVisitor;
        impl<'de> Visitor<'de> for EntriesVisitor {
            type Value = Entries;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("an object of metadata entries")
            }
            fn visit_map<A: MapAccess<'de>>(
                self,
                mut map: A,
            ) -> std::result::Result<Entries, A::Error> {
                let mut entries = Vec::new();
                while let Some(entry) = map.next_entry::<String, Value>()? {
                    entries.push(entry);
                }
                Ok(Entries(entries))
            }
        }
        d.deserialize_map(EntriesVisitor)
    }
}

/// Parses a sidecar's text into its description and its metadata entries as text.
fn parse(text: &str) -> std::result::Result<(Found, Vec<(String, String)>), String> {
    let found: Found = serde_json::from_str(text).map_err(|e| e.to_string())?;
    let mut meta = Vec::with_capacity(found.meta.0.len());
    for (key, value) in &found.meta.0 {
        if !is_meta_key(key) {
            return Err(format!(
                "metadata key {key:?}: keys are letters, digits, `_`, `-` and `.`"
            ));
        }
        let value = match value {
            Value::String(s) => s.clone(),
            Value::Number(n) => n.to_string(),
            Value::Bool(b) => b.to_string(),
            _ => {
                return Err(format!(
                    "metadata `{key}` is {value}; values are strings (or numbers)"
                ))
            }
        };
        if value.contains(['\n', '\r']) {
            return Err(format!("metadata `{key}`: the value contains a line break"));
        }
        meta.push((key.clone(), value));
    }
    Ok((found, meta))
}

/// Lower-case extension of a file name.
fn extension(name: &Path) -> Option<String> {
    name.extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
}

/// Why a sidecar does not describe `series`, read from `data`, if it does not.
fn mismatch(found: &Found, series: &Series, data: &Path) -> Option<String> {
    // A sidecar names its file; one renamed together with its data still matches, but not one
    // written for data of another format that shares the name (`run.npz` beside `run.csv`).
    if let Some(file) = &found.file {
        if extension(Path::new(file)) != extension(data) {
            return Some(format!("it describes `{file}`"));
        }
    }
    if let Some(columns) = &found.columns {
        if *columns != series.columns {
            return Some(format!(
                "it lists the columns {}, the file has {}",
                columns.join(","),
                series.columns.join(",")
            ));
        }
    }
    if let Some(rows) = found.rows {
        if rows != series.rows() {
            return Some(format!(
                "it records {rows} rows, the file has {}",
                series.rows()
            ));
        }
    }
    None
}

/// What a JSON file beside a data file that is not its sidecar most likely is: empty, as the
/// file a shell has just created for a command's redirected output is (`vibrissa estimate --obs
/// run.csv --json > run.json`), or an estimate written there before.
fn not_a_sidecar(text: &str) -> Option<&'static str> {
    if text.trim().is_empty() {
        return Some("the file is empty: is a command's output being written to it?");
    }
    // One estimate (pretty-printed), or JSON Lines of several.
    let first = text.lines().find(|l| !l.trim().is_empty())?;
    let value: Value = serde_json::from_str(text)
        .or_else(|_| serde_json::from_str(first))
        .ok()?;
    value.get("method").is_some().then_some(
        "it holds an estimate, not a sidecar: write estimates under another name than the \
         recording's",
    )
}

/// Adds the metadata of the sidecar of `data` (see [`sidecar_path`]) to `series`, which was read
/// from `data`, and returns what was wrong with it.
///
/// No sidecar is not a problem: nothing is added and nothing is returned. A sidecar that cannot
/// be read, is not valid, or does not match the series (another format, other columns, another
/// number of rows) is ignored with a warning. Entries that `series` already has (a CSV's own
/// `# key = value` lines) keep their value; a sidecar that disagrees with one gets a warning.
pub fn merge_sidecar(series: &mut Series, data: impl AsRef<Path>) -> Vec<SidecarWarning> {
    let data = data.as_ref();
    let path = sidecar_path(data);
    let mut warnings = Vec::new();
    if path == data {
        // A data file named `.json` has no sidecar.
        return warnings;
    }
    let text = match std::fs::read_to_string(&path) {
        Ok(text) => text,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return warnings,
        Err(error) => {
            warnings.push(SidecarWarning::Unreadable { path, error });
            return warnings;
        }
    };
    let (found, meta) = match parse(&text) {
        Ok(parsed) => parsed,
        Err(message) => {
            let message = match not_a_sidecar(&text) {
                Some(why) => format!("{message} ({why})"),
                None => message,
            };
            warnings.push(SidecarWarning::Malformed { path, message });
            return warnings;
        }
    };
    if let Some(message) = mismatch(&found, series, data) {
        warnings.push(SidecarWarning::Mismatch {
            path,
            data: data.to_path_buf(),
            message,
        });
        return warnings;
    }
    for (key, value) in meta {
        match series.meta_value(&key) {
            None => series.set_meta(key, value),
            Some(own) if own == value => {}
            Some(own) => warnings.push(SidecarWarning::Conflict {
                path: path.clone(),
                data: data.to_path_buf(),
                in_file: own.to_string(),
                key,
                in_sidecar: value,
            }),
        }
    }
    warnings
}

/// Reads a CSV time series as [`read_csv`](super::read_csv) does, then adds the metadata of its
/// sidecar (see [`merge_sidecar`]). Only the CSV can make this fail; what is wrong with the
/// sidecar comes back as warnings.
pub fn read_csv_with_sidecar(path: impl AsRef<Path>) -> Result<(Series, Vec<SidecarWarning>)> {
    read_csv_with_sidecar_lines(path).map(|(series, _, warnings)| (series, warnings))
}

/// [`read_csv_with_sidecar`], with the file's line (from 1) of each data row, for messages that
/// name a row.
pub fn read_csv_with_sidecar_lines(
    path: impl AsRef<Path>,
) -> Result<(Series, Vec<usize>, Vec<SidecarWarning>)> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path).map_err(|e| crate::Error::io("read", path, e))?;
    let (mut series, lines) = super::parse_csv(&text, &path.display().to_string())?;
    let warnings = merge_sidecar(&mut series, path);
    Ok((series, lines, warnings))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sidecar_names_replace_the_extension() {
        assert_eq!(sidecar_path("out/run.csv"), Path::new("out/run.json"));
        assert_eq!(sidecar_path("a.b.NPZ"), Path::new("a.b.json"));
        assert_eq!(sidecar_path("run"), Path::new("run.json"));
    }

    #[test]
    fn written_sidecars_parse_back_in_order() {
        let mut s = Series::new(&["t", "x"]);
        s.push_row(&[0.0, 1.0]);
        s.set_meta("zeta", "last letter first");
        s.set_meta("alpha", 1e-7);
        s.set_meta("quote", "say \"hi\" \\ there");
        let text = sidecar_json(&s, Path::new("dir/run.npz"));
        let (found, meta) = parse(&text).unwrap();
        assert_eq!(found.file.as_deref(), Some("run.npz"));
        assert_eq!(found.rows, Some(1));
        assert_eq!(found.columns.as_deref(), Some(&s.columns[..]));
        assert_eq!(meta, s.meta);
    }

    #[test]
    fn malformed_sidecars_say_what_is_wrong() {
        for (text, says) in [
            ("", "EOF"),
            ("3", "a JSON object with a `meta` object"),
            ("{\"rows\": 3}", "missing field `meta`"),
            ("{\"meta\": []}", "an object of metadata entries"),
            ("{\"meta\": {\"a b\": \"1\"}}", "metadata key \"a b\""),
            ("{\"meta\": {\"a\": null}}", "metadata `a` is null"),
            ("{\"meta\": {\"a\": \"x\\ny\"}}", "line break"),
            ("{\"rows\": -1, \"meta\": {}}", "line 1"),
        ] {
            let e = parse(text).err().unwrap_or_default();
            assert!(e.contains(says), "{text:?}: {e}");
        }
        // Numbers and booleans are taken as their text; unknown keys are ignored.
        let (_, meta) =
            parse("{\"future\": 1, \"meta\": {\"n\": 20, \"d\": 0.02, \"ok\": true}}").unwrap();
        let texts: Vec<&str> = meta.iter().map(|(_, v)| v.as_str()).collect();
        assert_eq!(texts, ["20", "0.02", "true"]);
    }
}
