//! The estimate object of the file contract: what `vibrissa estimate --json` prints for one
//! recording and what the Python package's `estimate` returns.
//!
//! ```json
//! {"d": {"mean": 0.0231, "std": 0.0004, "ci90": [0.0224, 0.0238]},
//!  "v": {"mean": 0.61, "std": 0.02, "ci90": [0.58, 0.64]},
//!  "method": "krr-local", "seconds": 0.0004,
//!  "noise": {"theta01": 0.0012, "theta12": 0.0011}}
//! ```
//!
//! One entry per unknown, named by its scenario key (or its name); for a shape family `class`,
//! each class's probability; `method`, `seconds` (the estimate's own
//! time, training excluded) and `noise` (the sensor noise used per channel read, SI); for the
//! particle filter its counts under `filter`; with a model check its result under `check`; for
//! `shape-bank` its `misfit`; for one of several recordings its `file`.

use crate::check::{self, Check};
use crate::method::Estimate;
use serde_json::{json, Map, Value};

/// One recording's estimate, as the contract's object ([`EstimateRow::to_json`]).
#[derive(Debug, Clone)]
pub struct EstimateRow {
    /// The recording, when it is one of several.
    pub file: Option<String>,
    /// For a shape family: each class's probability, in the family's order (empty otherwise).
    pub class: Vec<(String, f64)>,
    /// Its estimates, named by unknown.
    pub estimates: Vec<(String, Estimate)>,
    /// The method's name.
    pub method: String,
    /// Seconds the estimate took.
    pub seconds: f64,
    /// The sensor noise the method used per channel it reads, SI.
    pub noise: Vec<(String, f64)>,
    /// The particle filter's own counts; empty for other methods.
    pub filter: Vec<(&'static str, f64)>,
    /// The model check, when one was made.
    pub check: Option<Check>,
    /// For `shape-bank`: how many times farther the recording lies from the nearest simulated
    /// run than held-out simulated recordings typically do (1 when no farther; see
    /// [`crate::shapes::ShapeEstimate::misfit`]).
    pub misfit: Option<f64>,
}

impl EstimateRow {
    /// The contract's object.
    pub fn to_json(&self) -> Map<String, Value> {
        let mut obj = Map::new();
        if let Some(file) = &self.file {
            obj.insert("file".into(), json!(file));
        }
        if !self.class.is_empty() {
            let class: Map<String, Value> = self
                .class
                .iter()
                .map(|(k, p)| (k.clone(), json!(p)))
                .collect();
            obj.insert("class".into(), Value::Object(class));
        }
        for (n, e) in &self.estimates {
            obj.insert(
                n.clone(),
                json!({"mean": e.mean, "std": e.std, "ci90": e.ci90}),
            );
        }
        obj.insert("method".into(), json!(self.method));
        obj.insert("seconds".into(), json!(self.seconds));
        obj.insert(
            "noise".into(),
            Value::Object(
                self.noise
                    .iter()
                    .map(|(c, x)| (c.clone(), json!(x)))
                    .collect(),
            ),
        );
        if !self.filter.is_empty() {
            obj.insert(
                "filter".into(),
                Value::Object(
                    self.filter
                        .iter()
                        .map(|(k, x)| (k.to_string(), json!(x)))
                        .collect(),
                ),
            );
        }
        if let Some(m) = self.misfit {
            obj.insert("misfit".into(), json!(m));
        }
        if let Some(c) = &self.check {
            obj.insert(
                "check".into(),
                json!({
                    "explained": c.explained,
                    "limit": check::LIMIT,
                    "channels": c.channels.iter().map(|ch| (ch.channel.to_string(), json!({
                        "rms": ch.rms, "spread": ch.spread, "noise": ch.noise, "ratio": ch.ratio,
                        "lag1": ch.lag1,
                    }))).collect::<Map<String, Value>>(),
                }),
            );
        }
        obj
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_every_unknown_and_the_noise() {
        let row = EstimateRow {
            file: Some("a.csv".into()),
            class: Vec::new(),
            estimates: vec![
                ("d".into(), Estimate::normal(0.02, 0.001)),
                ("v".into(), Estimate::normal(0.6, 0.01)),
            ],
            method: "knn".into(),
            seconds: 0.5,
            noise: vec![("theta12".into(), 1e-3)],
            filter: Vec::new(),
            check: None,
            misfit: None,
        };
        let v = Value::Object(row.to_json());
        assert_eq!(v["file"], "a.csv");
        assert_eq!(v["d"]["mean"], 0.02);
        assert_eq!(v["v"]["ci90"].as_array().unwrap().len(), 2);
        assert_eq!(v["noise"]["theta12"], 1e-3);
        assert_eq!(v["method"], "knn");
        assert!(v.get("filter").is_none() && v.get("check").is_none());
        assert!(v.get("class").is_none());
    }
}
