//! One scenario's whisker put into another: the whisker, its chain and the sensors of a file
//! (one written by calibration, say) given to every whisker of another scenario (a shape
//! family's class files, whose objects, array and timing stay their own), or to one named
//! whisker of its array (a whisker of a real array calibrated on its own strikes).

use super::Document;
use crate::error::{Error, Result};
use toml::{Table, Value};

/// The top-level keys that describe the whisker and how it is recorded: its parameters, the
/// chain it is simulated on (a calibrated whisker is fitted on its chain, and its angle gains
/// absorb that chain's joint spacing), the sensors' gains and offsets, and calibration's record
/// (so that what the fit left uncertain travels with it). How finely contact is stepped
/// (`contact_substeps`) travels too, as a substep rather than a count ([`Document::adopt`]).
pub const WHISKER_KEYS: [&str; 5] = [
    "whisker",
    "segments",
    "discretisation",
    "sensors",
    "calibration",
];

/// The whisker of a scenario file, to be given to other scenarios ([`Document::adopt`]).
#[derive(Debug, Clone, PartialEq)]
pub struct WhiskerSource {
    /// The file's path or the built-in's name.
    origin: String,
    /// The tables and values of [`WHISKER_KEYS`] the file has.
    entries: Vec<(String, Value)>,
    /// The longest substep near contact, s, where the file names `contact_substeps` (its time
    /// step over that count): calibration fits the whisker with contact stepped so, and a
    /// whisker fitted so responds otherwise when stepped more coarsely.
    contact_step: Option<f64>,
}

impl WhiskerSource {
    /// Reads the whisker of a scenario (a built-in name or a TOML file), checked by reading the
    /// whole scenario. An array's file is refused: its whiskers may differ, and which one to
    /// give would be a guess.
    pub fn read(spec: &str) -> Result<WhiskerSource> {
        let doc = Document::load(spec, &[])?;
        let integrator = doc.loaded()?.scenario.integrator;
        let contact_step = doc
            .names("contact_substeps")
            .then(|| integrator.dt / integrator.contact_substeps as f64);
        let table = doc.table();
        if table.get("whiskers").is_some() {
            return Err(Error::Field {
                origin: doc.origin().to_string(),
                field: "whiskers".to_string(),
                message: "is an array of whiskers, which may differ: give a scenario of one \
                          whisker (one written by `vibrissa calibrate`, say)"
                    .to_string(),
            });
        }
        let entries = WHISKER_KEYS
            .iter()
            .filter_map(|k| table.get(*k).map(|v| (k.to_string(), v.clone())))
            .collect();
        Ok(WhiskerSource {
            origin: doc.origin().to_string(),
            entries,
            contact_step,
        })
    }

    /// The file's path or the built-in's name.
    pub fn origin(&self) -> &str {
        &self.origin
    }

    /// Whether the file carries calibration's record.
    pub fn is_calibrated(&self) -> bool {
        self.entries.iter().any(|(k, _)| k == "calibration")
    }
}

/// The whiskers given to a scenario ([`Document::adopt_all`]): one for every whisker
/// (`FILE`), and one for each named whisker of its array (`NAME=FILE`), which replaces the
/// former for that whisker.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct WhiskerSources {
    /// Given to every whisker.
    pub every: Option<WhiskerSource>,
    /// Given to the whisker of each name, in the order given.
    pub own: Vec<(String, WhiskerSource)>,
}

impl From<WhiskerSource> for WhiskerSources {
    fn from(source: WhiskerSource) -> Self {
        WhiskerSources {
            every: Some(source),
            own: Vec::new(),
        }
    }
}

impl WhiskerSources {
    /// Reads each of `specs`: `FILE` (a built-in name or a TOML file) gives its whisker to every
    /// whisker, `NAME=FILE` to the array's whisker `NAME` alone. At most one `FILE`, and each
    /// name once.
    pub fn read(specs: &[String]) -> Result<WhiskerSources> {
        let mut out = WhiskerSources::default();
        for spec in specs {
            // A file whose own name holds `=` is read as a file.
            let named = spec
                .split_once('=')
                .filter(|(name, file)| vibrissa_core::array::is_name(name) && !file.is_empty())
                .filter(|_| !std::path::Path::new(spec).is_file());
            match named {
                Some((name, file)) => {
                    if out.own.iter().any(|(n, _)| n == name) {
                        return Err(Error::Field {
                            origin: spec.clone(),
                            field: name.to_string(),
                            message: "is given a whisker twice: name each whisker once".to_string(),
                        });
                    }
                    out.own.push((name.to_string(), WhiskerSource::read(file)?));
                }
                None => {
                    if let Some(first) = &out.every {
                        return Err(Error::Field {
                            origin: spec.clone(),
                            field: "whisker".to_string(),
                            message: format!(
                                "is a second whisker for every whisker (the first is {}): \
                                 give one file, and NAME=FILE for a whisker of the array \
                                 that differs",
                                first.origin
                            ),
                        });
                    }
                    out.every = Some(WhiskerSource::read(spec)?);
                }
            }
        }
        Ok(out)
    }

    /// Whether the whisker given to every whisker carries calibration's record.
    pub fn is_calibrated(&self) -> bool {
        self.every
            .as_ref()
            .is_some_and(WhiskerSource::is_calibrated)
    }

    /// What is given, in words (`fitted.toml; c3: c3.toml`), for messages.
    pub fn describe(&self) -> String {
        self.every
            .iter()
            .map(|s| s.origin.clone())
            .chain(self.own.iter().map(|(n, s)| format!("{n}: {}", s.origin)))
            .collect::<Vec<_>>()
            .join("; ")
    }
}

impl Document {
    /// Gives this scenario the whisker of `source`: its `[whisker]`, chain (`segments`,
    /// `discretisation`), `[sensors]` and `[calibration]` replace this file's (a key `source`
    /// does not set is removed, so that it takes the default as in `source`). Every whisker of
    /// an array gets it; a `[[whiskers]]` entry with a `whisker` or `sensors` table of its own
    /// is refused.
    ///
    /// Where `source` names `contact_substeps`, this scenario steps contact at least as finely:
    /// its own time step (which stays its own) over as many substeps as that takes (5 at 0.1 ms
    /// for a file calibrated at 20 µs), or its own count where that is finer. A time step set
    /// afterwards (`--set dt=...`) keeps the count.
    pub fn adopt(&mut self, source: &WhiskerSource) -> Result<()> {
        self.adopt_except(source, &[])
    }

    /// Gives this scenario the whiskers of `sources`: [`Document::adopt`] for the one given to
    /// every whisker, then each named whisker of the array its own: its `whisker` and `sensors`
    /// tables become those of its file (a file with no `[sensors]` gives gains of 1 and offsets
    /// of 0). The array's whiskers share one chain, so every file must be fitted on the same
    /// chain (`segments`, `discretisation`), which becomes the scenario's; contact is stepped
    /// as finely as the most finely fitted file asks. A named whisker's calibration record is
    /// not carried (it describes that whisker alone).
    pub fn adopt_all(&mut self, sources: &WhiskerSources) -> Result<()> {
        let named: Vec<&str> = sources.own.iter().map(|(n, _)| n.as_str()).collect();
        // One chain for the array: the first file's, which every other must share.
        let first = match (&sources.every, sources.own.first()) {
            (Some(every), _) => {
                self.adopt_except(every, &named)?;
                every
            }
            (None, Some((_, first))) => {
                for key in ["segments", "discretisation"] {
                    match first.entry(key) {
                        Some(v) => self.table_mut().insert(key.to_string(), v.clone()),
                        None => self.table_mut().remove(key),
                    };
                }
                first
            }
            (None, None) => return Ok(()),
        };
        for (name, source) in &sources.own {
            source.same_chain_as(first)?;
            self.adopt_for(name, source)?;
        }
        Ok(())
    }

    /// [`Document::adopt`], leaving the refusal of a whisker (or sensors) of its own to the
    /// whiskers that `except` does not name (they are given one of their own next).
    fn adopt_except(&mut self, source: &WhiskerSource, except: &[&str]) -> Result<()> {
        if let Some(Value::Array(mounts)) = self.table().get("whiskers") {
            for m in mounts {
                let name = m.get("name").and_then(Value::as_str).unwrap_or("?");
                if except.contains(&name) {
                    continue;
                }
                for table in ["whisker", "sensors"] {
                    if let Some(own) = m.get(table) {
                        let keys = own
                            .as_table()
                            .map(|t| t.keys().cloned().collect::<Vec<_>>().join(", "))
                            .unwrap_or_default();
                        return Err(Error::Field {
                            origin: self.origin().to_string(),
                            field: format!("whiskers.{name}.{table}"),
                            message: format!(
                                "sets this whisker's own {keys}: the whisker of {} can only be \
                                 given to an array whose whiskers are alike (or name this one: \
                                 `{name}=FILE`)",
                                source.origin
                            ),
                        });
                    }
                }
            }
        }
        let substeps = match source.contact_step {
            Some(step) => Some(
                self.loaded()?
                    .scenario
                    .integrator
                    .contact_substeps_within(step),
            ),
            None => None,
        };
        for key in WHISKER_KEYS {
            self.table_mut().remove(key);
        }
        if let Some(m) = substeps {
            self.table_mut()
                .insert("contact_substeps".to_string(), Value::Integer(m as i64));
        }
        for (key, value) in &source.entries {
            self.table_mut().insert(key.clone(), value.clone());
        }
        self.mark_edited(&format!("the whisker of {}", source.origin));
        Ok(())
    }

    /// Gives the array's whisker `name` the whisker and sensors of `source`.
    fn adopt_for(&mut self, name: &str, source: &WhiskerSource) -> Result<()> {
        let names: Vec<String> = match self.table().get("whiskers") {
            Some(Value::Array(mounts)) => mounts
                .iter()
                .map(|m| {
                    m.get("name")
                        .and_then(Value::as_str)
                        .unwrap_or("?")
                        .to_string()
                })
                .collect(),
            _ => Vec::new(),
        };
        let Some(k) = names.iter().position(|n| n == name) else {
            let message = if names.is_empty() {
                format!(
                    "names no whisker `{name}`: it has no array of whiskers, so give {} \
                     without `{name}=`",
                    source.origin
                )
            } else {
                format!(
                    "has no whisker `{name}` to give {} to (`{name}=`): its whiskers are {}",
                    source.origin,
                    names.join(", ")
                )
            };
            return Err(Error::Field {
                origin: self.origin().to_string(),
                field: "whiskers".to_string(),
                message,
            });
        };
        if let Some(step) = source.contact_step {
            let m = self
                .loaded()?
                .scenario
                .integrator
                .contact_substeps_within(step);
            self.table_mut()
                .insert("contact_substeps".to_string(), Value::Integer(m as i64));
        }
        // A whisker table of a mount lies over the scenario's whisker; the file's lies over
        // the default preset, so it is given its preset explicitly.
        let mut whisker = match source.entry("whisker") {
            Some(Value::Table(t)) => t.clone(),
            _ => Table::new(),
        };
        if !whisker.contains_key("preset") {
            whisker.insert(
                "preset".to_string(),
                Value::String(vibrissa_core::whisker::DEFAULT_PRESET.to_string()),
            );
        }
        let sensors = match source.entry("sensors") {
            Some(Value::Table(t)) => t.clone(),
            _ => Table::new(),
        };
        if let Some(Value::Array(mounts)) = self.table_mut().get_mut("whiskers") {
            if let Some(Value::Table(mount)) = mounts.get_mut(k) {
                mount.insert("whisker".to_string(), Value::Table(whisker));
                mount.insert("sensors".to_string(), Value::Table(sensors));
            }
        }
        self.mark_edited(&format!("the whisker of {} for `{name}`", source.origin));
        Ok(())
    }
}

impl WhiskerSource {
    /// The file's value of one of [`WHISKER_KEYS`], if it has it.
    fn entry(&self, key: &str) -> Option<&Value> {
        self.entries.iter().find(|(k, _)| k == key).map(|(_, v)| v)
    }

    /// Refuses a file fitted on another chain than `first`'s: the whiskers of an array are
    /// simulated on one chain.
    fn same_chain_as(&self, first: &WhiskerSource) -> Result<()> {
        for key in ["segments", "discretisation"] {
            let (mine, theirs) = (self.entry(key), first.entry(key));
            if mine != theirs {
                let show =
                    |v: Option<&Value>| v.map_or("the default".to_string(), Value::to_string);
                return Err(Error::Field {
                    origin: self.origin.clone(),
                    field: key.to_string(),
                    message: format!(
                        "is {} where {} has {}: the whiskers of an array are simulated on one \
                         chain, so calibrate every whisker on the same one",
                        show(mine),
                        first.origin,
                        show(theirs)
                    ),
                });
            }
        }
        Ok(())
    }
}
