//! What an estimator is: the [`Method`] trait, its training data and its [`Estimate`]s.

use crate::error::Result;
use crate::experiment::{Noise, Sample};
use crate::family::Family;
use serde::Serialize;

/// z-value of a central 90% interval of a normal distribution.
pub const Z90: f64 = 1.644_853_626_951_472_2;

/// One unknown's estimate.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Estimate {
    /// Point estimate, SI.
    pub mean: f64,
    /// Standard deviation, SI (from the method's own calibration).
    pub std: f64,
    /// Central 90% interval `[lo, hi]`, SI.
    pub ci90: [f64; 2],
}

impl Estimate {
    /// A normal estimate: `mean ± 1.645·std`.
    pub fn normal(mean: f64, std: f64) -> Estimate {
        Estimate {
            mean,
            std,
            ci90: [mean - Z90 * std, mean + Z90 * std],
        }
    }

    /// Whether the 90% interval holds `truth`.
    pub fn covers(&self, truth: f64) -> bool {
        self.ci90[0] <= truth && truth <= self.ci90[1]
    }
}

/// Which runs a method may learn from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Budget {
    /// Only the experiment's template runs.
    Paper,
    /// Any simulated runs except the evaluated ones.
    Free,
}

impl Budget {
    /// `paper` or `free`.
    pub fn name(self) -> &'static str {
        match self {
            Budget::Paper => "paper",
            Budget::Free => "free",
        }
    }
}

/// The runs a method is fitted on.
#[derive(Debug, Clone)]
pub struct Training {
    /// The scenario family the runs come from (its unknowns, ranges and timing).
    pub family: Family,
    /// Runs to fit on (the templates, for the paper's budget).
    pub samples: Vec<Sample>,
    /// Further runs, held out of the fit, that calibrate the uncertainty (empty under the
    /// paper's budget).
    pub calibration: Vec<Sample>,
    /// The noise of the recordings to be estimated from, as far as it is known: the sensor noise
    /// per channel (estimated from the recordings, or stated) and the scenario's process noise.
    /// Simulated training runs carry it; the particle filter takes its sensor noise from it.
    pub noise: Noise,
}

/// An estimator of the unknowns from one run's observations.
pub trait Method: Send + Sync {
    /// Short name (`template`, `knn`, …).
    fn name(&self) -> &'static str;
    /// Which runs it may learn from.
    fn budget(&self) -> Budget;
    /// Indices into [`crate::CHANNELS`] of the channels it needs.
    fn channels(&self) -> Vec<usize>;
    /// Learns from `training`.
    fn fit(&mut self, training: &Training) -> Result<()>;
    /// Estimates every unknown from `obs` (channel-major `[CHANNELS][samples]`, sampled as the
    /// training family's runs; channels it does not need may be empty).
    fn predict(&self, obs: &[Vec<f64>]) -> Result<Vec<Estimate>>;
    /// Fitted settings worth reporting (`sigma2`, `k`, …), SI.
    fn settings(&self) -> Vec<(String, f64)> {
        Vec::new()
    }
}
