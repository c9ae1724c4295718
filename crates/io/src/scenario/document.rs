//! A scenario file as a TOML document: read (a built-in or a file), edited with `key=value`
//! overrides or values of its unknowns, checked into a [`Loaded`] scenario, hashed for caches,
//! and written back as a file that loads the same way.

use super::calibration::Calibration;
use super::{builtin, overrides, read_scenario_text, schema, Loaded};
use crate::error::{Error, Result};
use std::path::{Path, PathBuf};
use toml::Value;

/// A scenario file as parsed, with its edits.
#[derive(Debug, Clone)]
pub struct Document {
    /// The text as read (errors in it are shown with their line and column).
    text: String,
    /// The document with every edit applied.
    table: toml::Table,
    /// The overrides applied, as given (named in messages).
    sets: Vec<String>,
    /// Whether `table` was edited by other means than `sets`.
    edited: bool,
    /// The file's path or the built-in's name.
    origin: String,
    /// Folder that relative paths in the document start from.
    base_dir: PathBuf,
}

impl PartialEq for Document {
    /// Two documents are equal when they read into the same table from the same place.
    fn eq(&self, other: &Self) -> bool {
        self.table == other.table && self.origin == other.origin && self.base_dir == other.base_dir
    }
}

impl Document {
    /// Reads a scenario as [`super::load`] does (a built-in name or a TOML file) and applies
    /// `sets`, without checking it against the schema yet.
    pub fn load(spec: &str, sets: &[String]) -> Result<Document> {
        // A built-in name wins over a file of the same name (write ./e1 for the file).
        if let Some(text) = builtin(spec) {
            return Document::parse(
                text,
                &format!("built-in scenario `{spec}`"),
                Path::new(""),
                sets,
            );
        }
        let path = Path::new(spec);
        let text = read_scenario_text(spec, path)?;
        let dir = path.parent().unwrap_or(Path::new(""));
        let doc = Document::parse(&text, &path.display().to_string(), dir, &[])?;
        // A file with nothing in it (or only comments) is more likely a mistake than a wish for
        // every default: a whisker at rest with nothing to touch.
        if doc.table.is_empty() {
            return Err(Error::Toml {
                origin: doc.origin,
                message: "the scenario file is empty: give at least `experiment = \"e2\"` (or \
                          another built-in), or a [whisker] and the [[objects]] it meets"
                    .to_string(),
            });
        }
        Document::parse(&text, &path.display().to_string(), dir, sets)
    }

    /// Parses TOML text and applies the overrides.
    pub(super) fn parse(
        text: &str,
        origin: &str,
        base_dir: &Path,
        sets: &[String],
    ) -> Result<Document> {
        let table: toml::Table = toml::from_str(text).map_err(|e| toml_error(origin, e))?;
        let mut doc = Document {
            text: text.to_string(),
            table,
            sets: Vec::new(),
            edited: false,
            origin: origin.to_string(),
            base_dir: base_dir.to_path_buf(),
        };
        for set in sets {
            doc.set(set)?;
        }
        Ok(doc)
    }

    /// The file's path or the built-in's name, as used in messages.
    pub fn origin(&self) -> &str {
        &self.origin
    }

    /// Applies one `key=value` override (the syntax of `--set`); whether the key exists is
    /// decided when the document is read ([`Document::loaded`]).
    pub fn set(&mut self, text: &str) -> Result<()> {
        overrides::apply(&mut self.table, text)?;
        self.sets.push(text.to_string());
        Ok(())
    }

    /// Whether the document (as edited) gives the top-level key `key` itself, rather than
    /// leaving it to its default.
    pub fn names(&self, key: &str) -> bool {
        self.table.contains_key(key)
    }

    /// The document as edited.
    pub(super) fn table(&self) -> &toml::Table {
        &self.table
    }

    /// The document, to be edited in place (then [`Document::mark_edited`]).
    pub(super) fn table_mut(&mut self) -> &mut toml::Table {
        &mut self.table
    }

    /// Records an edit made directly to the table (`what` names it in messages).
    pub(super) fn mark_edited(&mut self, what: &str) {
        self.edited = true;
        self.origin = format!("{} with {what}", self.origin);
    }

    /// Sets (or replaces) the `[calibration]` table.
    pub fn set_calibration(&mut self, calibration: &Calibration) -> Result<()> {
        let value = Value::try_from(calibration).map_err(|e| Error::Toml {
            origin: self.origin.clone(),
            message: format!("cannot write the [calibration] table: {e}"),
        })?;
        self.table.insert("calibration".to_string(), value);
        self.edited = true;
        Ok(())
    }

    /// Reads the document into a checked scenario.
    pub fn loaded(&self) -> Result<Loaded> {
        let ctx = schema::Ctx {
            origin: &self.origin,
            base_dir: &self.base_dir,
        };
        if self.sets.is_empty() && !self.edited {
            // Straight from the text, so that errors carry line and column.
            let file: schema::FileTable =
                toml::from_str(&self.text).map_err(|e| toml_error(&self.origin, e))?;
            return file.into_loaded(&ctx);
        }
        match schema::FileTable::deserialize_table(self.table.clone()) {
            Ok(file) => file.into_loaded(&ctx),
            Err(e) => {
                // An error the file has without the edits is shown where it is in the file.
                if let Err(plain) = toml::from_str::<schema::FileTable>(&self.text) {
                    if plain.message() == e.message() {
                        return Err(toml_error(&self.origin, plain));
                    }
                }
                let origin = if self.sets.is_empty() {
                    format!("{} as edited", self.origin)
                } else {
                    format!("{} with --set {}", self.origin, self.sets.join(" --set "))
                };
                let mut error = toml_error(&origin, e);
                if let Error::Toml { message, .. } = &mut error {
                    *message = indexed_path(message, &self.sets);
                }
                Err(error)
            }
        }
    }

    /// The document with `sets` applied as well, read into a checked scenario.
    pub fn loaded_with(&self, sets: &[String]) -> Result<Loaded> {
        let mut doc = self.clone();
        for set in sets {
            doc.set(set)?;
        }
        doc.loaded()
    }

    /// The scenario with `values` set (each a dotted key and a number), read and checked like a
    /// file.
    pub fn with_values<S: AsRef<str>>(&self, values: &[(S, f64)]) -> Result<Loaded> {
        let mut table = self.table.clone();
        for (key, x) in values {
            let key = key.as_ref();
            overrides::set_value(&mut table, key, Value::Float(*x)).map_err(|message| {
                Error::Field {
                    origin: self.origin.clone(),
                    field: key.to_string(),
                    message,
                }
            })?;
        }
        let file = schema::FileTable::deserialize_table(table).map_err(|e| {
            let keys: Vec<String> = values
                .iter()
                .map(|(k, x)| format!("{}={x}", k.as_ref()))
                .collect();
            Error::Toml {
                origin: format!("{} with {}", self.origin, keys.join(", ")),
                message: e.to_string().trim_end().to_string(),
            }
        })?;
        file.into_loaded(&schema::Ctx {
            origin: &self.origin,
            base_dir: &self.base_dir,
        })
    }

    /// A stable digest of the document (FNV-1a over its canonical TOML text), for caches.
    pub fn digest(&self) -> u64 {
        let text = toml::to_string(&self.table).unwrap_or_default();
        text.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
            (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
        })
    }

    /// The document as TOML text for a file in the folder `dir`: a relative base trajectory
    /// path is rewritten so that it still names the same file from there.
    pub fn to_toml(&self, dir: &Path) -> Result<String> {
        let mut table = self.table.clone();
        let file = table
            .get_mut("base")
            .and_then(|b| b.as_table_mut())
            .and_then(|b| b.get_mut("file"));
        if let Some(Value::String(name)) = file {
            let relative = Path::new(name.as_str());
            let same_dir = || match (self.base_dir.canonicalize(), dir.canonicalize()) {
                (Ok(a), Ok(b)) => a == b,
                _ => false,
            };
            if relative.is_relative() && !same_dir() {
                let full = self.base_dir.join(relative);
                let full = full.canonicalize().unwrap_or(full);
                *name = full.display().to_string();
            }
        }
        toml::to_string(&table).map_err(|e| Error::Toml {
            origin: self.origin.clone(),
            message: format!("cannot write the document: {e}"),
        })
    }

    /// Writes the document to `path` (whole or not at all), after checking that the text
    /// written loads as a scenario from there.
    pub fn write(&self, path: &Path) -> Result<()> {
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let text = self.to_toml(&dir)?;
        Document::parse(&text, &path.display().to_string(), &dir, &[])?.loaded()?;
        crate::atomic::stage(path, |w| {
            use std::io::Write;
            w.write_all(text.as_bytes())
        })?
        .commit()
    }
}

/// A TOML error of `origin`, as the library reports it.
fn toml_error(origin: &str, e: toml::de::Error) -> Error {
    let message = e.to_string().trim_end().to_string();
    let hint = hint_for(&message);
    Error::Toml {
        origin: origin.to_string(),
        message: match hint {
            Some(h) => format!("{message}\n{h}"),
            None => message,
        },
    }
}

/// The parser names a key of an array of tables without its index (`in `objects.radius``); where
/// exactly one of `sets` wrote that key, its index is put back (`in `objects[0].radius``).
fn indexed_path(message: &str, sets: &[String]) -> String {
    let Some(start) = message.find("in `").map(|k| k + 4) else {
        return message.to_string();
    };
    let Some(len) = message[start..].find('`') else {
        return message.to_string();
    };
    let path = &message[start..start + len];
    let is_index = |part: &&str| !part.is_empty() && part.bytes().all(|b| b.is_ascii_digit());
    let mut written: Vec<String> = sets
        .iter()
        .filter_map(|set| {
            let key = set.split_once('=')?.0.trim();
            let parts: Vec<&str> = key.split('.').collect();
            let plain: Vec<&str> = parts.iter().filter(|p| !is_index(p)).copied().collect();
            (plain.join(".") == path && plain.len() < parts.len()).then(|| {
                parts.iter().fold(String::new(), |mut out, part| {
                    if is_index(part) {
                        out.push_str(&format!("[{part}]"));
                    } else {
                        if !out.is_empty() {
                            out.push('.');
                        }
                        out.push_str(part);
                    }
                    out
                })
            })
        })
        .collect();
    written.sort();
    written.dedup();
    match written.as_slice() {
        [one] => format!("{}{one}{}", &message[..start], &message[start + len..]),
        _ => message.to_string(),
    }
}

/// A line for the parser's messages that leave out what is wanted: a table of a few forms named
/// by `kind`, or a number given as text.
fn hint_for(message: &str) -> Option<String> {
    const TABLES: [(&str, &str); 3] = [
        (
            "`whisker.damping`",
            "`whisker.damping` is a table: { kind = \"none\" }, { kind = \"modal_ratio\", ratio = 0.05 }, \
             { kind = \"segment_q\", q = 10 } or { kind = \"stiffness_proportional\", beta = 1e-4 } \
             (with --set, give the whole table: --set 'whisker.damping={ kind = \"modal_ratio\", ratio = 0.04 }')",
        ),
        (
            "`whisker.follicle`",
            "`whisker.follicle` is a table: { kind = \"clamped\" } or { kind = \"spring\", stiffness = \
             1.4e-4, damping = 4.5e-8 } (N·m/rad and N·m·s/rad; with --set, give the whole table)",
        ),
        (
            "`base`",
            "`base` is a table whose `kind` is fixed, sinusoid, ramp or trajectory, with that kind's \
             keys (with --set, give the whole table)",
        ),
    ];
    for (at, hint) in TABLES {
        let about_it = message.contains(&format!("in {at}"));
        let shape = message.contains("missing field `kind`") || message.contains("expected struct");
        if about_it && shape {
            return Some(format!("hint: {hint}"));
        }
    }
    if message.contains("missing field `shape`") && message.contains("in `objects`") {
        return Some(
            "hint: an object needs its `shape`, its size (`radius`, or `width` and `height`), \
             `position` and `velocity`; a key such as `objects.0.radius` on a scenario without \
             [[objects]] of its own (the built-in e1 and e2, whose box comes from `d` and `v`) \
             makes a new object of that one key"
                .to_string(),
        );
    }
    if message.contains("invalid type: map") && message.contains("in `objects`") {
        return Some(
            "hint: `objects` is an array of tables: index it (`objects.0.friction`), or give a \
             whole object (--set 'objects.0={ shape = \"circle\", radius = 0.002, position = \
             [0.02, -0.01], velocity = [0.0, 0.5] }')"
                .to_string(),
        );
    }
    if message.contains("invalid type: string") && message.contains("expected f64") {
        return Some(
            "hint: a number is expected here, written as a number (0.01, 1e-3), not as text"
                .to_string(),
        );
    }
    None
}
