//! What drives one step besides the state: the base motion, point loads, process noise and
//! objects ([`Inputs`]), and their checks.

use crate::chain::Model;
use crate::error::{Error, Result};
use crate::objects::Object;

/// Prescribed rotation of the base (the follicle's mount) about the origin.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BaseMotion {
    /// Angle, rad.
    pub angle: f64,
    /// Angular rate, rad/s.
    pub rate: f64,
    /// Angular acceleration, rad/s².
    pub accel: f64,
}

/// A force applied at a point of a segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointLoad {
    /// Segment index, 0 at the base.
    pub segment: usize,
    /// Distance along the segment's chord from its proximal node, m.
    pub along: f64,
    /// Force in the world frame, N (a dead load: its direction does not follow the whisker).
    pub force: [f64; 2],
}

/// What drives one step besides the state itself.
#[derive(Debug, Clone, Copy, Default)]
pub struct Inputs<'a> {
    /// Base rotation at the end of the step.
    pub base: BaseMotion,
    /// Point loads held over the step.
    pub loads: &'a [PointLoad],
    /// White-noise process force intensity per unit length, N·s^½·m^-½: over a step `h` each
    /// segment of arc length `l` receives an independent Gaussian force with standard deviation
    /// `intensity·sqrt(l/h)` in x and in y at its centre of mass (so the forcing does not depend
    /// on N or h). Zero disables it.
    pub noise: f64,
    /// Rigid objects the whisker may touch (kinematic: their motion is prescribed).
    pub objects: &'a [Object],
}

/// Checks that every load names an existing segment and a point on it, with a finite force.
pub fn check_loads(model: &Model, loads: &[PointLoad]) -> Result<()> {
    for (k, l) in loads.iter().enumerate() {
        if l.segment >= model.n {
            return Err(Error::invalid(
                format!("loads[{k}].segment"),
                l.segment,
                format!("a segment index from 0 to {}", model.n - 1),
            ));
        }
        let len = model.len[l.segment];
        if !(l.along.is_finite() && (0.0..=len * (1.0 + 1e-12)).contains(&l.along)) {
            return Err(Error::invalid(
                format!("loads[{k}].along"),
                l.along,
                format!("in [0, {len}] m"),
            ));
        }
        if !(l.force[0].is_finite() && l.force[1].is_finite()) {
            return Err(Error::invalid(
                format!("loads[{k}].force"),
                format!("{:?}", l.force),
                "finite components",
            ));
        }
    }
    Ok(())
}

/// Checks a step's inputs: finite base motion and noise, loads on existing segments.
pub(super) fn check_inputs(model: &Model, inputs: &Inputs) -> Result<()> {
    let b = inputs.base;
    if !(b.angle.is_finite() && b.rate.is_finite() && b.accel.is_finite()) {
        return Err(Error::invalid(
            "base motion",
            format!("{b:?}"),
            "finite angle, rate and acceleration",
        ));
    }
    if !(inputs.noise.is_finite() && inputs.noise >= 0.0) {
        return Err(Error::invalid(
            "noise",
            inputs.noise,
            "a finite intensity >= 0",
        ));
    }
    if !inputs.loads.is_empty() {
        check_loads(model, inputs.loads)?;
    }
    Ok(())
}
