//! Randomised training runs: each simulated run gets its own whisker and sensors, drawn around
//! the scenario's, so that a method trained on them has seen whiskers that are not exactly the
//! one the scenario describes (domain randomisation).
//!
//! A user rarely knows their whisker to better than 10–25%: its modulus, density and damping,
//! whether the follicle is stiff, how much the whisker tapers, their sensors' gains. A method
//! trained on runs of the nominal whisker alone learns the nominal's signals exactly and is biased,
//! with intervals that are too narrow, on any other. Trained on runs whose whiskers vary as much as
//! the user's uncertainty, its predictions average over that uncertainty and its intervals (fitted
//! on held-out training runs) widen to hold it.
//!
//! The prior ([`Randomisation::default`]), per run and independently:
//! - modulus, density and the damping coefficient each times `e^u`, `u` uniform in ±0.3 (a factor
//!   0.74–1.35);
//! - with probability 1/2, the follicle becomes a spring whose compliance is 0.3–3 times the
//!   nominal chain's base joint's (log-uniform), damped with a time constant `e^±1` times the
//!   whisker's own; a follicle that is already a spring has its stiffness times `e^u`, `u` in ±0.5;
//! - with probability 1/2, the tip radius times a factor uniform in 0.5–0.95;
//! - every sensor gain times a factor uniform in 0.95–1.05.

use crate::error::{Error, Result};
use crate::reference::Reference;
use vibrissa_core::rng::Rng;
use vibrissa_core::sim::{Response, Scenario, SensorResponse};
use vibrissa_core::whisker::{Damping, Follicle};

/// How the whisker and sensors of randomised runs are drawn (see the module's documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Randomisation {
    /// Half-width of the uniform log-factor of the modulus.
    pub modulus: f64,
    /// Half-width of the uniform log-factor of the density.
    pub density: f64,
    /// Half-width of the uniform log-factor of the damping coefficient.
    pub damping: f64,
    /// Probability that a clamped follicle becomes a spring.
    pub follicle: f64,
    /// Range of its compliance, relative to the nominal chain's base joint (log-uniform).
    pub compliance: [f64; 2],
    /// Half-width of the uniform log-factor of a spring follicle's stiffness.
    pub spring: f64,
    /// Probability of a taper.
    pub taper: f64,
    /// Range of the taper's factor on the tip radius.
    pub tip: [f64; 2],
    /// Half-width of the uniform relative change of each sensor gain.
    pub gain: f64,
}

impl Default for Randomisation {
    fn default() -> Self {
        Randomisation {
            modulus: 0.3,
            density: 0.3,
            damping: 0.3,
            follicle: 0.5,
            compliance: [0.3, 3.0],
            spring: 0.5,
            taper: 0.5,
            tip: [0.5, 0.95],
            gain: 0.05,
        }
    }
}

/// What a randomisation needs of the nominal whisker: its chain's base-joint stiffness and the
/// damping time constant of its first mode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Around {
    /// The draws.
    pub prior: Randomisation,
    /// Stiffness of the nominal chain's base joint (clamped), N·m/rad.
    k0: f64,
    /// The whisker's own damping time constant, s.
    tau0: f64,
}

impl Around {
    /// The randomisation `prior` around the scenario `base`.
    pub fn new(base: &Scenario, prior: Randomisation) -> Result<Around> {
        for (what, x) in [
            ("modulus", prior.modulus),
            ("density", prior.density),
            ("damping", prior.damping),
            ("spring", prior.spring),
            ("gain", prior.gain),
        ] {
            if !(x.is_finite() && (0.0..1.0).contains(&x)) {
                return Err(Error::Setting(format!(
                    "randomisation: {what} = {x}: allowed is a half-width in [0, 1)"
                )));
            }
        }
        if !(0.0..=1.0).contains(&prior.follicle) || !(0.0..=1.0).contains(&prior.taper) {
            return Err(Error::Setting(
                "randomisation: probabilities must lie in [0, 1]".into(),
            ));
        }
        if !(prior.compliance[0] > 0.0 && prior.compliance[1] >= prior.compliance[0]) {
            return Err(Error::Setting(
                "randomisation: the compliance range must be positive and increasing".into(),
            ));
        }
        if !(prior.tip[0] > 0.0 && prior.tip[1] <= 1.0 && prior.tip[1] >= prior.tip[0]) {
            return Err(Error::Setting(
                "randomisation: the tip factor range must lie in (0, 1] and increase".into(),
            ));
        }
        let reference = Reference::of(base)?;
        Ok(Around {
            prior,
            k0: reference.k0,
            tau0: reference.beta0,
        })
    }

    /// `s` with its whisker and sensor gains drawn from the prior by `seed` (the same seed gives
    /// the same draw).
    pub fn apply(&self, s: &mut Scenario, seed: u64) {
        let p = &self.prior;
        let mut rng = Rng::stream(seed, 0xD0_A1A5);
        let mut factor = |half: f64| (half * (2.0 * rng.uniform() - 1.0)).exp();
        let (fe, fr, fd) = (factor(p.modulus), factor(p.density), factor(p.damping));
        let fs = factor(p.spring);
        let w = &mut s.whisker;
        w.youngs_modulus *= fe;
        w.density *= fr;
        w.damping = match w.damping {
            Damping::ModalRatio { ratio } => Damping::ModalRatio {
                ratio: (ratio * fd).min(0.9),
            },
            Damping::SegmentQ { q } => Damping::SegmentQ { q: q * fd },
            Damping::StiffnessProportional { beta } => {
                Damping::StiffnessProportional { beta: beta * fd }
            }
            Damping::None => Damping::None,
        };
        let (u_follicle, u_compliance, u_tau) = (rng.uniform(), rng.uniform(), rng.uniform());
        w.follicle = match w.follicle {
            Follicle::Clamped if u_follicle < p.follicle => {
                let [lo, hi] = p.compliance;
                let compliance = (lo.ln() + u_compliance * (hi / lo).ln()).exp();
                let stiffness = self.k0 / compliance;
                Follicle::Spring {
                    stiffness,
                    damping: stiffness * self.tau0 * (2.0 * u_tau - 1.0).exp(),
                }
            }
            Follicle::Spring { stiffness, damping } => Follicle::Spring {
                stiffness: stiffness * fs,
                damping: damping * fs,
            },
            f => f,
        };
        let (u_taper, u_tip) = (rng.uniform(), rng.uniform());
        if u_taper < p.taper {
            let [lo, hi] = p.tip;
            w.tip_radius = (w.tip_radius * (lo + u_tip * (hi - lo))).min(w.base_radius);
        }
        let nominal = s.sensor_response.to_array();
        s.sensor_response = SensorResponse::from_array(std::array::from_fn(|c| Response {
            gain: nominal[c].gain * (1.0 + p.gain * (2.0 * rng.uniform() - 1.0)),
            offset: nominal[c].offset,
        }));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::family::Family;

    #[test]
    fn draws_vary_the_whisker_within_the_prior_and_repeat_by_seed() {
        let f = Family::builtin("e2").unwrap();
        let base = f.base().clone();
        let around = Around::new(&base, Randomisation::default()).unwrap();
        let (mut springs, mut tapers) = (0, 0);
        for seed in 0..200 {
            let mut s = base.clone();
            around.apply(&mut s, seed);
            let fe = s.whisker.youngs_modulus / base.whisker.youngs_modulus;
            assert!((0.74..=1.35).contains(&fe), "{fe}");
            let fr = s.whisker.density / base.whisker.density;
            assert!((0.74..=1.35).contains(&fr), "{fr}");
            springs += usize::from(matches!(s.whisker.follicle, Follicle::Spring { .. }));
            tapers += usize::from(s.whisker.tip_radius < base.whisker.tip_radius);
            for r in s.sensor_response.to_array() {
                assert!((0.95..=1.05).contains(&r.gain), "{}", r.gain);
            }
            s.whisker.check().expect("a valid whisker");
            let mut again = base.clone();
            around.apply(&mut again, seed);
            assert_eq!(again.whisker.youngs_modulus, s.whisker.youngs_modulus);
        }
        assert!((70..130).contains(&springs), "{springs}");
        assert!((70..130).contains(&tapers), "{tapers}");
    }

    #[test]
    fn a_bad_prior_is_refused_by_name() {
        let f = Family::builtin("e2").unwrap();
        let prior = Randomisation {
            density: f64::NAN,
            ..Randomisation::default()
        };
        let e = Around::new(f.base(), prior).unwrap_err().to_string();
        assert!(e.contains("density"), "{e}");
    }
}
