//! Constants of a nominal whisker that perturbations of it refer to: the stiffness of its chain's
//! base joint (a follicle's compliance is measured against it) and its damping time constant (a
//! follicle's damping is measured against it). Calibration parametrises the follicle by them;
//! randomised training and stand-in whiskers draw follicles relative to them.

use crate::error::{Error, Result};
use vibrissa_core::chain::Model;
use vibrissa_core::sim::Scenario;
use vibrissa_core::whisker::{Damping, Follicle, WhiskerParams};

/// Constants of the nominal whisker that follicle parameters refer to.
#[derive(Debug, Clone)]
pub(crate) struct Reference {
    /// The nominal whisker.
    pub whisker: WhiskerParams,
    /// Stiffness of the nominal chain's base joint with a clamped follicle, N·m/rad.
    pub k0: f64,
    /// Stiffness-proportional damping coefficient of the nominal chain, s (2ζ1/ω1, or the nominal
    /// β, or 1e-4 s without damping).
    pub beta0: f64,
}

impl Reference {
    /// The reference constants of `nominal`.
    pub fn of(nominal: &Scenario) -> Result<Reference> {
        let whisker = nominal.whisker.clone();
        let mut clamped = whisker.clone();
        clamped.follicle = Follicle::Clamped;
        let checked = clamped.check().map_err(|e| setting(e.to_string()))?;
        let model = Model::new(&checked, nominal.segments, nominal.discretisation)
            .map_err(|e| setting(e.to_string()))?;
        let k0 = model.stiffness[0];
        let beta0 = match whisker.damping {
            Damping::ModalRatio { ratio } => {
                let f1 = model
                    .modes()
                    .map_err(|e| setting(e.to_string()))?
                    .frequencies[0];
                2.0 * ratio / (2.0 * std::f64::consts::PI * f1)
            }
            Damping::StiffnessProportional { beta } => beta,
            Damping::SegmentQ { .. } | Damping::None => 1e-4,
        };
        Ok(Reference { whisker, k0, beta0 })
    }
}

fn setting(message: String) -> Error {
    Error::Setting(format!("the nominal whisker: {message}"))
}
