//! Beam profiles shared by the references' tests.

use super::{BeamProfile, UniformBeam};

/// Uniform test beam: L = 50 mm, EI = 2e-7 N·m².
pub(super) const BEAM: UniformBeam = UniformBeam {
    length: 0.05,
    ei: 2e-7,
    rho_a: 3e-5,
};

/// Power-law taper: EI = ei0·r^pe, ρA = ra0·r^pr, r = 1 − (1 − tip)·s/L; constant κ0.
pub(super) struct Taper {
    pub(super) len: f64,
    pub(super) ei0: f64,
    pub(super) ra0: f64,
    pub(super) pe: i32,
    pub(super) pr: i32,
    pub(super) tip: f64,
    pub(super) k0: f64,
}

impl BeamProfile for Taper {
    fn length(&self) -> f64 {
        self.len
    }
    fn ei(&self, s: f64) -> f64 {
        self.ei0 * (1.0 - (1.0 - self.tip) * s / self.len).powi(self.pe)
    }
    fn rho_a(&self, s: f64) -> f64 {
        self.ra0 * (1.0 - (1.0 - self.tip) * s / self.len).powi(self.pr)
    }
    fn rest_curvature(&self, _s: f64) -> f64 {
        self.k0
    }
}

/// A 40-mm taper with tip ratio `tip` and rest curvature `k0`.
pub(super) fn taper(pe: i32, pr: i32, tip: f64, k0: f64) -> Taper {
    Taper {
        len: 0.04,
        ei0: 3e-7,
        ra0: 4e-5,
        pe,
        pr,
        tip,
        k0,
    }
}

/// Relative difference of `a` from `b`.
pub(super) fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}
