//! The one interface of the shape estimators, and fitting one by name.

use super::bank::{CleanRuns, ShapeBank};
use super::estimator::{ShapeEstimate, ShapeKrr};
use super::family::{ShapeFamily, ShapeSample};
use super::filter::ShapePf;
use super::mix::ShapeMix;
use super::online::ShapeEsn;
use crate::error::{Error, Result};

/// The shape estimators, by name: `shape-krr` reads the whole recording at once, `shape-esn`
/// reads it one sample at a time (a class posterior after every sample), `shape-bank` weighs
/// the recording's likelihood under a bank of noise-free runs of every class, `shape-pf` runs a
/// particle filter over each class's pose and weighs the classes by their marginal likelihoods
/// (also online), `shape-mix` pools the class posteriors of `shape-bank` and `shape-pf`.
pub const SHAPE_METHODS: [&str; 5] = [
    ShapeKrr::NAME,
    ShapeEsn::NAME,
    ShapeBank::NAME,
    ShapePf::NAME,
    ShapeMix::NAME,
];

/// The estimators an experiment scores when none is named (`shape-bank` simulates a bank of
/// its own, several times the training runs, so it is scored when asked for).
pub const DEFAULT_SHAPE_METHODS: [&str; 2] = [ShapeKrr::NAME, ShapeEsn::NAME];

/// Whether estimator `name` needs noise-free runs ([`CleanRuns`]) beside the training runs.
pub fn needs_clean_runs(name: &str) -> bool {
    name == ShapeBank::NAME || name == ShapeMix::NAME
}

/// The estimators that run a particle filter and so take a particle count per class.
pub const FILTER_METHODS: [&str; 2] = [ShapePf::NAME, ShapeMix::NAME];

/// Whether estimator `name` runs a particle filter ([`FILTER_METHODS`]).
pub fn has_filter(name: &str) -> bool {
    FILTER_METHODS.contains(&name)
}

/// A fitted shape estimator.
pub trait ShapeMethod: Send + Sync {
    /// Its name (one of [`SHAPE_METHODS`]).
    fn name(&self) -> &'static str;
    /// The class posterior and the most probable class's pose from one recording
    /// (`[whiskers][CHANNELS][samples]`, the whiskers it was fitted on, in order).
    fn predict(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<ShapeEstimate>;
    /// The class posterior after every sample (`[samples][classes]`), for an online method;
    /// `None` for one that reads the recording whole.
    fn trace(&self, whiskers: &[Vec<Vec<f64>>]) -> Option<Result<Vec<Vec<f64>>>>;
    /// Fitted settings worth reporting.
    fn settings(&self) -> Vec<(String, f64)>;
}

impl ShapeMethod for ShapeKrr {
    fn name(&self) -> &'static str {
        Self::NAME
    }
    fn predict(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<ShapeEstimate> {
        ShapeKrr::predict(self, whiskers)
    }
    fn trace(&self, _: &[Vec<Vec<f64>>]) -> Option<Result<Vec<Vec<f64>>>> {
        None
    }
    fn settings(&self) -> Vec<(String, f64)> {
        ShapeKrr::settings(self)
    }
}

impl ShapeMethod for ShapeBank {
    fn name(&self) -> &'static str {
        Self::NAME
    }
    fn predict(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<ShapeEstimate> {
        ShapeBank::predict(self, whiskers)
    }
    fn trace(&self, whiskers: &[Vec<Vec<f64>>]) -> Option<Result<Vec<Vec<f64>>>> {
        Some(ShapeBank::trace(self, whiskers))
    }
    fn settings(&self) -> Vec<(String, f64)> {
        ShapeBank::settings(self)
    }
}

impl ShapeMethod for ShapePf {
    fn name(&self) -> &'static str {
        Self::NAME
    }
    fn predict(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<ShapeEstimate> {
        ShapePf::predict(self, whiskers)
    }
    fn trace(&self, whiskers: &[Vec<Vec<f64>>]) -> Option<Result<Vec<Vec<f64>>>> {
        Some(ShapePf::trace(self, whiskers))
    }
    fn settings(&self) -> Vec<(String, f64)> {
        ShapePf::settings(self)
    }
}

impl ShapeMethod for ShapeMix {
    fn name(&self) -> &'static str {
        Self::NAME
    }
    fn predict(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<ShapeEstimate> {
        ShapeMix::predict(self, whiskers)
    }
    fn trace(&self, whiskers: &[Vec<Vec<f64>>]) -> Option<Result<Vec<Vec<f64>>>> {
        Some(ShapeMix::trace(self, whiskers))
    }
    fn settings(&self) -> Vec<(String, f64)> {
        ShapeMix::settings(self)
    }
}

impl ShapeMethod for ShapeEsn {
    fn name(&self) -> &'static str {
        Self::NAME
    }
    fn predict(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<ShapeEstimate> {
        ShapeEsn::predict(self, whiskers)
    }
    fn trace(&self, whiskers: &[Vec<Vec<f64>>]) -> Option<Result<Vec<Vec<f64>>>> {
        Some(ShapeEsn::trace(self, whiskers))
    }
    fn settings(&self) -> Vec<(String, f64)> {
        ShapeEsn::settings(self)
    }
}

/// Checks that `name` is a shape estimator.
pub fn check_shape_method(name: &str) -> Result<()> {
    if SHAPE_METHODS.contains(&name) {
        Ok(())
    } else {
        Err(Error::Setting(format!(
            "unknown shape method `{name}` (known: {})",
            SHAPE_METHODS.join(", ")
        )))
    }
}

/// Fits the shape estimator `name` on the runs `training` of `family` (and, for one that
/// [`needs_clean_runs`], the noise-free runs `clean`); a filter (`shape-pf`, and `shape-mix`'s)
/// takes `particles` per class.
pub fn fit_shape_method(
    name: &str,
    family: &ShapeFamily,
    training: &[ShapeSample],
    clean: Option<&CleanRuns>,
    particles: usize,
) -> Result<Box<dyn ShapeMethod>> {
    check_shape_method(name)?;
    Ok(if name == ShapeEsn::NAME {
        Box::new(ShapeEsn::fit(family, training)?)
    } else if name == ShapePf::NAME {
        Box::new(ShapePf::fit_with(family, training, particles)?)
    } else if name == ShapeBank::NAME || name == ShapeMix::NAME {
        let clean = clean.ok_or_else(|| Error::Fit {
            method: name.into(),
            detail: "needs noise-free runs beside the training runs".into(),
        })?;
        if name == ShapeMix::NAME {
            Box::new(ShapeMix::fit(family, training, clean, particles)?)
        } else {
            Box::new(ShapeBank::fit(family, training, clean)?)
        }
    } else {
        Box::new(ShapeKrr::fit(family, training)?)
    })
}
