//! One scenario's whisker put into another: the whisker, its chain and the sensors of a file
//! (one written by calibration, say) given to every whisker of another scenario (a shape
//! family's class files, whose objects, array and timing stay their own).

use super::Document;
use crate::error::{Error, Result};
use toml::Value;

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

impl Document {
    /// Gives this scenario the whisker of `source`: its `[whisker]`, chain (`segments`,
    /// `discretisation`), `[sensors]` and `[calibration]` replace this file's (a key `source`
    /// does not set is removed, so that it takes the default as in `source`). Every whisker of
    /// an array gets it; a `[[whiskers]]` entry with a `whisker` table of its own is refused.
    ///
    /// Where `source` names `contact_substeps`, this scenario steps contact at least as finely:
    /// its own time step (which stays its own) over as many substeps as that takes (5 at 0.1 ms
    /// for a file calibrated at 20 µs), or its own count where that is finer. A time step set
    /// afterwards (`--set dt=...`) keeps the count.
    pub fn adopt(&mut self, source: &WhiskerSource) -> Result<()> {
        if let Some(Value::Array(mounts)) = self.table().get("whiskers") {
            for m in mounts {
                if let Some(own) = m.get("whisker") {
                    let name = m.get("name").and_then(Value::as_str).unwrap_or("?");
                    let keys = own
                        .as_table()
                        .map(|t| t.keys().cloned().collect::<Vec<_>>().join(", "))
                        .unwrap_or_default();
                    return Err(Error::Field {
                        origin: self.origin().to_string(),
                        field: format!("whiskers.{name}.whisker"),
                        message: format!(
                            "sets this whisker's own {keys}: the whisker of {} can only be \
                             given to an array whose whiskers are alike",
                            source.origin
                        ),
                    });
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
}
