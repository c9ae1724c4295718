//! The whisker description: geometry, material, follicle and damping, with presets.
//!
//! A [`WhiskerParams`] is what a user writes; [`WhiskerParams::check`] turns it into a [`Whisker`],
//! the only form the rest of the library accepts. All quantities are SI.

use crate::beam::BeamProfile;
use crate::error::{check_finite, check_non_negative, check_positive, Error, Result};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// How the whisker's base is held.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Follicle {
    /// Rigidly clamped at the base.
    Clamped,
    /// A rotational spring (N·m/rad) and damper (N·m·s/rad) between base and whisker.
    Spring {
        /// Rotational stiffness, N·m/rad.
        stiffness: f64,
        /// Rotational damping, N·m·s/rad.
        damping: f64,
    },
}

/// How bending motion is damped.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Damping {
    /// No structural damping.
    None,
    /// Stiffness-proportional (Rayleigh) damping scaled so that the first bending mode of the
    /// discretised whisker has this damping ratio; higher modes are damped in proportion to
    /// their frequency.
    ModalRatio {
        /// First-mode damping ratio ζ1 (0.05 is a Q of about 10).
        ratio: f64,
    },
    /// The seed paper's rule: every joint damper is set from the Q-value of an isolated segment,
    /// γ = sqrt(J·k)/Q, with J the segment's moment of inertia about its proximal joint.
    SegmentQ {
        /// Q-value of one segment on its spring.
        q: f64,
    },
    /// Stiffness-proportional damping with an explicit coefficient: every joint damper is β·k.
    StiffnessProportional {
        /// β, in s.
        beta: f64,
    },
}

/// A whisker as a user describes it. Check it with [`WhiskerParams::check`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WhiskerParams {
    /// Arc length, m.
    pub length: f64,
    /// Radius at the base, m.
    pub base_radius: f64,
    /// Radius at the tip, m (equal to `base_radius` for a uniform whisker; a conical taper otherwise).
    pub tip_radius: f64,
    /// Intrinsic (rest) curvature, 1/m, constant along the length; positive curls counter-clockwise.
    pub rest_curvature: f64,
    /// Young's modulus, Pa.
    pub youngs_modulus: f64,
    /// Density, kg/m³.
    pub density: f64,
    /// The follicle.
    pub follicle: Follicle,
    /// Structural damping.
    pub damping: Damping,
}

/// Names of the built-in whisker presets.
pub const PRESETS: [&str; 3] = ["w30", "rat", "robot"];

/// The preset of a scenario whose whisker names none (the seed paper's 30 mm whisker).
pub const DEFAULT_PRESET: &str = "w30";

impl WhiskerParams {
    /// The seed experiments' whisker (docs/experiments.md): 30 mm, uniform radius 0.1 mm, E = 3 GPa,
    /// ρ = 1100 kg/m³, straight, clamped, first-mode damping ratio 0.05 (stiffness-proportional).
    pub fn w30() -> Self {
        WhiskerParams {
            length: 0.030,
            base_radius: 1.0e-4,
            tip_radius: 1.0e-4,
            rest_curvature: 0.0,
            youngs_modulus: 3.0e9,
            density: 1100.0,
            follicle: Follicle::Clamped,
            damping: Damping::ModalRatio { ratio: 0.05 },
        }
    }

    /// A rat-like macrovibrissa: 35 mm long, conical from 75 µm to 5 µm radius, curved at rest
    /// with a 50 mm radius of curvature, E = 3.5 GPa, ρ = 1300 kg/m³, clamped, first-mode damping
    /// ratio 0.1. Values are representative of the published rat measurements (lengths and
    /// base/tip radii of the C-row whiskers, moduli of 3–4 GPa and intrinsic curvature of the
    /// order reported for rat whiskers); see the documentation for sources.
    pub fn rat() -> Self {
        WhiskerParams {
            length: 0.035,
            base_radius: 75.0e-6,
            tip_radius: 5.0e-6,
            rest_curvature: 20.0,
            youngs_modulus: 3.5e9,
            density: 1300.0,
            follicle: Follicle::Clamped,
            damping: Damping::ModalRatio { ratio: 0.1 },
        }
    }

    /// A robot whisker: 150 mm, straight, tapered polymer rod from 0.75 mm to 0.25 mm radius,
    /// E = 2.5 GPa, ρ = 1200 kg/m³, clamped, first-mode damping ratio 0.03. Representative of the
    /// moulded or printed plastic whiskers of mobile whiskered robots.
    pub fn robot() -> Self {
        WhiskerParams {
            length: 0.150,
            base_radius: 0.75e-3,
            tip_radius: 0.25e-3,
            rest_curvature: 0.0,
            youngs_modulus: 2.5e9,
            density: 1200.0,
            follicle: Follicle::Clamped,
            damping: Damping::ModalRatio { ratio: 0.03 },
        }
    }

    /// A preset by name (see [`PRESETS`]).
    pub fn preset(name: &str) -> Result<Self> {
        match name {
            "w30" => Ok(Self::w30()),
            "rat" => Ok(Self::rat()),
            "robot" => Ok(Self::robot()),
            _ => Err(Error::invalid(
                "whisker.preset",
                name,
                format!("one of {}", PRESETS.join(", ")),
            )),
        }
    }

    /// Checks every field and returns the validated whisker.
    pub fn check(&self) -> Result<Whisker> {
        check_positive("whisker.length", self.length)?;
        check_positive("whisker.base_radius", self.base_radius)?;
        check_positive("whisker.tip_radius", self.tip_radius)?;
        if self.tip_radius > self.base_radius {
            return Err(Error::invalid(
                "whisker.tip_radius",
                self.tip_radius,
                format!("at most whisker.base_radius = {}", self.base_radius),
            ));
        }
        if self.base_radius > 0.1 * self.length {
            return Err(Error::invalid(
                "whisker.base_radius",
                self.base_radius,
                format!(
                    "at most a tenth of whisker.length (a slender beam), here {}",
                    0.1 * self.length
                ),
            ));
        }
        check_finite("whisker.rest_curvature", self.rest_curvature)?;
        if self.rest_curvature.abs() * self.length > PI {
            return Err(Error::invalid(
                "whisker.rest_curvature",
                self.rest_curvature,
                format!(
                    "|curvature| * length <= pi, so |curvature| <= {}",
                    PI / self.length
                ),
            ));
        }
        check_positive("whisker.youngs_modulus", self.youngs_modulus)?;
        check_positive("whisker.density", self.density)?;
        if let Follicle::Spring { stiffness, damping } = self.follicle {
            check_positive("whisker.follicle.stiffness", stiffness)?;
            check_non_negative("whisker.follicle.damping", damping)?;
        }
        match self.damping {
            Damping::None => {}
            Damping::ModalRatio { ratio } => {
                if !(ratio.is_finite() && ratio > 0.0 && ratio < 1.0) {
                    return Err(Error::invalid(
                        "whisker.damping.ratio",
                        ratio,
                        "a number in (0, 1)",
                    ));
                }
            }
            Damping::SegmentQ { q } => {
                check_positive("whisker.damping.q", q)?;
            }
            Damping::StiffnessProportional { beta } => {
                check_positive("whisker.damping.beta", beta)?;
            }
        }
        Ok(Whisker(self.clone()))
    }
}

/// A checked whisker description. Obtain one from [`WhiskerParams::check`].
#[derive(Debug, Clone, PartialEq)]
pub struct Whisker(WhiskerParams);

impl Whisker {
    /// The checked parameters.
    pub fn params(&self) -> &WhiskerParams {
        &self.0
    }

    /// Radius at arc length `s`, m (linear taper).
    pub fn radius(&self, s: f64) -> f64 {
        let p = &self.0;
        p.base_radius + (p.tip_radius - p.base_radius) * (s / p.length).clamp(0.0, 1.0)
    }

    /// Area moment of inertia at `s`, m⁴.
    pub fn second_moment(&self, s: f64) -> f64 {
        0.25 * PI * self.radius(s).powi(4)
    }

    /// Whether the section is the same everywhere.
    pub fn is_uniform(&self) -> bool {
        self.0.base_radius == self.0.tip_radius
    }

    /// Total mass, kg.
    pub fn mass(&self) -> f64 {
        let p = &self.0;
        let (a, b) = (p.base_radius, p.tip_radius);
        p.density * PI * p.length * (a * a + a * b + b * b) / 3.0
    }
}

impl BeamProfile for Whisker {
    fn length(&self) -> f64 {
        self.0.length
    }
    fn ei(&self, s: f64) -> f64 {
        self.0.youngs_modulus * self.second_moment(s)
    }
    fn rho_a(&self, s: f64) -> f64 {
        self.0.density * PI * self.radius(s).powi(2)
    }
    fn rest_curvature(&self, _s: f64) -> f64 {
        self.0.rest_curvature
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn w30_matches_experiments_constants() {
        let w = WhiskerParams::w30().check().unwrap();
        // docs/experiments.md: EI = 2.3562e-7 N·m², mass per length 3.4558e-5 kg/m, mass 1.0367e-6 kg.
        assert!((w.ei(0.01) / 2.3562e-7 - 1.0).abs() < 1e-4);
        assert!((w.rho_a(0.01) / 3.4558e-5 - 1.0).abs() < 1e-4);
        assert!((w.mass() / 1.0367e-6 - 1.0).abs() < 1e-4);
    }

    #[test]
    fn presets_check() {
        for name in PRESETS {
            WhiskerParams::preset(name).unwrap().check().unwrap();
        }
        assert!(WhiskerParams::preset("cat").is_err());
        // A scenario that names no whisker has the default preset's.
        assert_eq!(
            WhiskerParams::preset(DEFAULT_PRESET).unwrap(),
            crate::sim::Scenario::default().whisker
        );
    }

    #[test]
    fn bad_values_name_the_field() {
        let mut p = WhiskerParams::w30();
        p.length = -1.0;
        let e = p.check().unwrap_err().to_string();
        assert!(e.contains("whisker.length"), "{e}");
        let mut p = WhiskerParams::w30();
        p.density = f64::NAN;
        assert!(p
            .check()
            .unwrap_err()
            .to_string()
            .contains("whisker.density"));
        let mut p = WhiskerParams::w30();
        p.damping = Damping::ModalRatio { ratio: 0.0 };
        assert!(p
            .check()
            .unwrap_err()
            .to_string()
            .contains("whisker.damping.ratio"));
        let mut p = WhiskerParams::w30();
        p.tip_radius = 2e-4;
        assert!(p
            .check()
            .unwrap_err()
            .to_string()
            .contains("whisker.tip_radius"));
    }

    #[test]
    fn cone_mass_by_quadrature() {
        let w = WhiskerParams::rat().check().unwrap();
        let n = 10_000;
        let h = w.length() / n as f64;
        let m: f64 = (0..n).map(|i| w.rho_a((i as f64 + 0.5) * h) * h).sum();
        assert!((m / w.mass() - 1.0).abs() < 1e-6);
    }
}
