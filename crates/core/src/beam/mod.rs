//! Continuum Euler–Bernoulli references for a clamped whisker.
//!
//! These are the continuum solutions a segment-chain whisker simulator is checked
//! against (SI units throughout), for any [`BeamProfile`] (a straight uniform beam is
//! [`UniformBeam`]):
//!
//! * statics ([`statics`]): [`PointLoadCubic`], the small-deflection cantilever under a
//!   transverse point force (the seed paper's cubic), [`load_for_tip_deflection`] and
//!   [`point_compliance`]; [`elastica`], the large-deflection equilibrium under one dead
//!   point force (varying EI and rest curvature), accurate to about `1e-8` relative;
//! * vibration ([`modes`]): [`clamped_free_roots`] and [`clamped_free_uniform`], the
//!   closed-form clamped–free modes; [`clamped_free_fem`] and [`clamped_free_tapered`],
//!   the modes of non-uniform beams; [`kaneko_omega`], Kaneko's massless-beam / tip-mass
//!   frequency.

pub mod modes;
pub mod statics;
#[cfg(test)]
mod test_profiles;

pub use modes::{
    clamped_free_fem, clamped_free_roots, clamped_free_tapered, clamped_free_uniform, kaneko_omega,
};
pub use statics::{elastica, load_for_tip_deflection, point_compliance, Elastica, PointLoadCubic};

/// Cross-section properties of a beam along its arc length `s` in `[0, length]` (SI units).
pub trait BeamProfile: Sync {
    /// Length of the beam, m.
    fn length(&self) -> f64;
    /// Bending stiffness E·I(s), N·m².
    fn ei(&self, s: f64) -> f64;
    /// Mass per unit length ρ·A(s), kg/m.
    fn rho_a(&self, s: f64) -> f64;
    /// Rest (intrinsic) curvature κ0(s), 1/m; positive bends counter-clockwise.
    fn rest_curvature(&self, _s: f64) -> f64 {
        0.0
    }
}

/// A straight beam of constant section.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UniformBeam {
    /// Length, m.
    pub length: f64,
    /// Bending stiffness, N·m².
    pub ei: f64,
    /// Mass per unit length, kg/m.
    pub rho_a: f64,
}

impl BeamProfile for UniformBeam {
    fn length(&self) -> f64 {
        self.length
    }
    fn ei(&self, _s: f64) -> f64 {
        self.ei
    }
    fn rho_a(&self, _s: f64) -> f64 {
        self.rho_a
    }
}
