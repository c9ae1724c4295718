//! Continuum Euler–Bernoulli references for a clamped whisker.

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
