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
//! - with probability 1/2, the follicle becomes a spring whose compliance is 0.3–10 times the
//!   nominal chain's base joint's (log-uniform), damped so that the damper joint 0 receives
//!   through the series is `k_f·τ·e^u`, τ the whisker's own time constant and `u` in ±1;
//!   a follicle that is already a spring has its stiffness times `e^u`, `u` in ±0.5;
//! - with probability 1/2, the tip radius times a factor uniform in 0.5–0.95;
//! - every sensor gain times a factor uniform in 0.95–1.05;
//! - with probability 1/2, the chain is cut into another number of segments: the scenario's count
//!   times a factor log-uniform in 0.5–3 (rounded; 10–60 for the 20 segments of `e2`);
//! - with probability 1/2, the joints follow the seed paper's stiffness rule (`k = EI/l`) instead
//!   of the scenario's.
//!
//! A randomised family trains on three times as many random runs as the scenario's own
//! ([`Randomisation::runs`]).
//!
//! On a calibrated scenario whose file records the fit's correlations, the runs' whiskers and
//! gains are drawn from the fit's own uncertainty instead ([`FittedSpread`]): jointly normal in
//! the logarithms of the determined parameters, with the standard errors and correlations of
//! `[calibration]`. Without that record, [`Randomisation::calibrated`] is the prior.
//!
//! The last two stand for the recording's own chain, which a user rarely knows. Another engine,
//! or a rig whose angles are read off a tracked shape, measures `theta01` and `theta12` between
//! its own segments, and a joint angle is the curvature times the joint spacing: the same strike
//! on a 50-segment chain shows angles less than half those of a 20-segment one, while the base
//! moment and forces agree within a few percent. The stiffness rule moves compliance towards the
//! base (by half a segment with the seed rule).

use crate::error::{Error, Result};
use crate::reference::Reference;
use vibrissa_core::chain::{Discretisation, MAX_SEGMENTS};
use vibrissa_core::rng::Rng;
use vibrissa_core::sim::{Response, Scenario, SensorResponse};
use vibrissa_core::whisker::{Damping, Follicle};
use vibrissa_io::scenario::Calibration;

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
    /// Probability that a run's chain has another segment count than the scenario's.
    pub resegment: f64,
    /// Range of the factor on the scenario's segment count (log-uniform; the count is rounded
    /// and kept within 2 to [`MAX_SEGMENTS`]).
    pub segments: [f64; 2],
    /// Probability that a run's joints follow the seed paper's stiffness rule
    /// ([`Discretisation::Seed`]) instead of the scenario's.
    pub seed_rule: f64,
    /// How many times as many random training runs as for the scenario's own whisker
    /// ([`crate::evaluate::random_runs`]), 1 to [`MAX_RUNS`]: the runs also spread over the prior's
    /// whiskers, and a method needs more of them to see its neighbourhood of every strike.
    pub runs: usize,
}

/// Largest [`Randomisation::runs`] accepted.
pub const MAX_RUNS: usize = 20;

impl Default for Randomisation {
    fn default() -> Self {
        Randomisation {
            modulus: 0.3,
            density: 0.3,
            damping: 0.3,
            follicle: 0.5,
            compliance: [0.3, 10.0],
            spring: 0.5,
            taper: 0.5,
            tip: [0.5, 0.95],
            gain: 0.05,
            resegment: 0.5,
            segments: [0.5, 3.0],
            seed_rule: 0.5,
            runs: 3,
        }
    }
}

impl Randomisation {
    /// The prior around a calibrated scenario (one fitted to labelled strikes by
    /// `vibrissa calibrate`): the fit leaves its whisker uncertain by a few percent and its
    /// chain, follicle and taper as fitted, so only the modulus, density, damping and a spring
    /// follicle's stiffness vary, each by a factor within e^±0.1, and the sensor gains by ±2%.
    /// The width is the narrowest of 0.05, 0.1 and 0.2 whose intervals held the truth in 90% of
    /// strikes on average over calibrated stand-ins (`krr-local`).
    pub fn calibrated() -> Randomisation {
        Randomisation {
            modulus: 0.1,
            density: 0.1,
            damping: 0.1,
            follicle: 0.0,
            spring: 0.1,
            taper: 0.0,
            gain: 0.02,
            resegment: 0.0,
            seed_rule: 0.0,
            ..Randomisation::default()
        }
    }

    /// A digest of the prior, for caches of training runs.
    pub fn digest(&self) -> u64 {
        let p = self;
        [
            p.modulus,
            p.density,
            p.damping,
            p.follicle,
            p.compliance[0],
            p.compliance[1],
            p.spring,
            p.taper,
            p.tip[0],
            p.tip[1],
            p.gain,
            p.resegment,
            p.segments[0],
            p.segments[1],
            p.seed_rule,
            p.runs as f64,
        ]
        .iter()
        .fold(0xcbf2_9ce4_8422_2325u64, |h, x| {
            (h ^ x.to_bits()).wrapping_mul(0x0000_0100_0000_01b3)
        })
    }
}

/// What a randomisation needs of the nominal whisker: its chain's base-joint stiffness and the
/// damping time constant of its first mode; and, around a calibrated whisker, the fit's spread.
#[derive(Debug, Clone, PartialEq)]
pub struct Around {
    /// The draws.
    pub prior: Randomisation,
    /// Stiffness of the nominal chain's base joint (clamped), N·m/rad.
    k0: f64,
    /// The whisker's own damping time constant, s.
    tau0: f64,
    /// The calibration's joint uncertainty, drawn from instead of the prior's factors.
    fitted: Option<std::sync::Arc<FittedSpread>>,
}

/// Largest log standard deviation drawn for one parameter of a [`FittedSpread`]: a standard
/// error above the value itself (a follicle's damping, say) is a factor of e either way.
pub const MAX_LOG_SD: f64 = 1.0;

/// What one coordinate of a [`FittedSpread`] scales.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Target {
    Modulus,
    Density,
    TipRadius,
    FollicleStiffness,
    FollicleDamping,
    Damping,
    /// A channel's gain, by its index in the contract's order.
    Gain(usize),
}

impl Target {
    /// A number that tells targets apart, for digests.
    fn code(&self) -> f64 {
        match self {
            Target::Modulus => 1.0,
            Target::Density => 2.0,
            Target::TipRadius => 3.0,
            Target::FollicleStiffness => 4.0,
            Target::FollicleDamping => 5.0,
            Target::Damping => 6.0,
            Target::Gain(c) => 7.0 + *c as f64,
        }
    }

    /// The target that a `[[calibration.parameters]]` key sets, if draws vary it.
    fn of(key: &str) -> Option<Target> {
        Some(match key {
            "whisker.youngs_modulus" => Target::Modulus,
            "whisker.density" => Target::Density,
            "whisker.tip_radius" => Target::TipRadius,
            "whisker.follicle.stiffness" => Target::FollicleStiffness,
            "whisker.follicle.damping" => Target::FollicleDamping,
            "whisker.damping.ratio" | "whisker.damping.q" | "whisker.damping.beta" => {
                Target::Damping
            }
            _ => {
                let channel = key.strip_prefix("sensors.")?.strip_suffix(".gain")?;
                Target::Gain(
                    vibrissa_core::sensors::CHANNELS
                        .iter()
                        .position(|c| *c == channel)?,
                )
            }
        })
    }
}

/// A calibration's joint uncertainty of the whisker and the sensor gains, to draw whiskers
/// from: the logarithms of the determined parameters jointly normal about the fitted values,
/// each with its relative standard error (at most [`MAX_LOG_SD`]) and their recorded
/// correlations. Offsets and the time offset are not drawn, nor are the parameters the fit held:
/// the recordings either barely see them or cannot tell them from others (the force channels'
/// common gain, held as the reference, trades against the whisker's stiffness, so varying it
/// alone would draw whiskers the recordings rule out).
#[derive(Debug, Clone, PartialEq)]
pub struct FittedSpread {
    /// What each coordinate scales.
    targets: Vec<Target>,
    /// Lower Cholesky factor of the logarithms' covariance, row-major.
    factor: Vec<Vec<f64>>,
}

/// The lower Cholesky factor of the correlation matrix `r`. A matrix recorded to finite
/// precision may be singular or, by rounding, slightly indefinite: a little is added to its
/// diagonal until it factors (the same for every parameter, whatever its scale), and without a
/// factor at all the parameters are drawn independently.
fn cholesky(r: &nalgebra::DMatrix<f64>) -> nalgebra::DMatrix<f64> {
    let n = r.nrows();
    [0.0, 1e-9, 1e-6, 1e-3, 1e-2, 1e-1]
        .iter()
        .find_map(|&jitter| {
            let m = r + nalgebra::DMatrix::identity(n, n) * jitter;
            nalgebra::Cholesky::new(m).map(|ch| ch.l() / (1.0 + jitter).sqrt())
        })
        .unwrap_or_else(|| nalgebra::DMatrix::identity(n, n))
}

impl FittedSpread {
    /// The spread a fitted scenario's `[calibration]` record gives, if it records the fit's
    /// correlations and any drawable parameter.
    pub fn of(record: &Calibration) -> Option<FittedSpread> {
        let correlation = record.correlation.as_ref()?;
        let mut picked = Vec::new();
        for (i, key) in correlation.keys.iter().enumerate() {
            let Some(target) = Target::of(key) else {
                continue;
            };
            let Some(p) = record.parameters.iter().find(|p| &p.key == key) else {
                continue;
            };
            // A gain may be negative (a channel wired the other way): its relative error is
            // that of its size.
            let value = p.value.abs();
            let (Some(se), true) = (p.std_error, value.is_finite() && value > 0.0) else {
                continue;
            };
            picked.push((i, target, (se / value).min(MAX_LOG_SD)));
        }
        if picked.is_empty() {
            return None;
        }
        let n = picked.len();
        let r =
            nalgebra::DMatrix::from_fn(n, n, |a, b| correlation.matrix[picked[a].0][picked[b].0]);
        // The covariance's factor: the correlation's, each row scaled by its standard deviation.
        let l = cholesky(&r);
        Some(FittedSpread {
            targets: picked.iter().map(|&(_, t, _)| t).collect(),
            factor: (0..n)
                .map(|a| (0..n).map(|b| picked[a].2 * l[(a, b)]).collect())
                .collect(),
        })
    }

    /// `s` with its whisker and gains drawn by `rng`.
    fn apply(&self, s: &mut Scenario, rng: &mut Rng) {
        let z: Vec<f64> = self.targets.iter().map(|_| rng.normal()).collect();
        let mut gains = s.sensor_response.to_array();
        for (a, &target) in self.targets.iter().enumerate() {
            let u: f64 = self.factor[a].iter().zip(&z).map(|(l, z)| l * z).sum();
            let f = u.exp();
            let w = &mut s.whisker;
            match target {
                Target::Modulus => w.youngs_modulus *= f,
                Target::Density => w.density *= f,
                Target::TipRadius => w.tip_radius = (w.tip_radius * f).min(w.base_radius),
                Target::FollicleStiffness | Target::FollicleDamping => {
                    if let Follicle::Spring { stiffness, damping } = &mut w.follicle {
                        if target == Target::FollicleStiffness {
                            *stiffness *= f;
                        } else {
                            *damping *= f;
                        }
                    }
                }
                Target::Damping => scale_damping(&mut w.damping, f),
                Target::Gain(c) => gains[c].gain *= f,
            }
        }
        s.sensor_response = SensorResponse::from_array(gains);
    }

    /// A digest, for caches of training runs.
    fn digest(&self) -> u64 {
        self.targets
            .iter()
            .map(|t| t.code())
            .chain(self.factor.iter().flatten().copied())
            .fold(0x005b_7ead_u64, |h, x| {
                (h ^ x.to_bits()).wrapping_mul(0x0000_0100_0000_01b3)
            })
    }
}

/// Scales a damping law's coefficient by `f` (a modal ratio at most 0.9).
fn scale_damping(d: &mut Damping, f: f64) {
    *d = match *d {
        Damping::ModalRatio { ratio } => Damping::ModalRatio {
            ratio: (ratio * f).min(0.9),
        },
        Damping::SegmentQ { q } => Damping::SegmentQ { q: q * f },
        Damping::StiffnessProportional { beta } => {
            Damping::StiffnessProportional { beta: beta * f }
        }
        Damping::None => Damping::None,
    };
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
        for (what, x) in [
            ("follicle", prior.follicle),
            ("taper", prior.taper),
            ("resegment", prior.resegment),
            ("seed_rule", prior.seed_rule),
        ] {
            if !(0.0..=1.0).contains(&x) {
                return Err(Error::Setting(format!(
                    "randomisation: {what} = {x}: allowed is a probability in [0, 1]"
                )));
            }
        }
        let [lo, hi] = prior.compliance;
        if !(lo > 0.0 && hi.is_finite() && hi >= lo) {
            return Err(Error::Setting(format!(
                "randomisation: compliance = [{lo}, {hi}]: allowed is a positive, increasing range"
            )));
        }
        let [lo, hi] = prior.tip;
        if !(lo > 0.0 && hi <= 1.0 && hi >= lo) {
            return Err(Error::Setting(format!(
                "randomisation: tip = [{lo}, {hi}]: allowed is an increasing range in (0, 1]"
            )));
        }
        let [lo, hi] = prior.segments;
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && hi >= lo) {
            return Err(Error::Setting(format!(
                "randomisation: segments = [{lo}, {hi}]: allowed is a positive, increasing range \
                 of factors on the scenario's segment count"
            )));
        }
        if !(1..=MAX_RUNS).contains(&prior.runs) {
            return Err(Error::Setting(format!(
                "randomisation: runs = {}: allowed is a whole number from 1 to {MAX_RUNS}",
                prior.runs
            )));
        }
        let reference = Reference::of(base)?;
        Ok(Around {
            prior,
            k0: reference.k0,
            tau0: reference.beta0,
            fitted: None,
        })
    }

    /// Draws from a calibration's `spread` instead of the prior's factors of the modulus,
    /// density, damping, follicle and gains (the prior's structural draws, of follicle, taper
    /// and chain, still apply where it makes them).
    pub fn with_fitted(self, spread: std::sync::Arc<FittedSpread>) -> Around {
        Around {
            fitted: Some(spread),
            ..self
        }
    }

    /// Whether draws come from a calibration's spread.
    pub fn is_fitted(&self) -> bool {
        self.fitted.is_some()
    }

    /// A digest of the draws, for caches of training runs.
    pub fn digest(&self) -> u64 {
        match &self.fitted {
            None => self.prior.digest(),
            Some(f) => (self.prior.digest() ^ f.digest()).wrapping_mul(0x0000_0100_0000_01b3),
        }
    }

    /// `s` with its whisker and sensor gains drawn from the prior by `seed` (the same seed gives
    /// the same draw).
    pub fn apply(&self, s: &mut Scenario, seed: u64) {
        let p = &self.prior;
        let mut rng = Rng::stream(seed, 0xD0_A1A5);
        if let Some(fitted) = &self.fitted {
            fitted.apply(s, &mut rng);
        }
        // Around a fitted spread, the prior's own factors are 1.
        let unfitted = if self.fitted.is_some() { 0.0 } else { 1.0 };
        let mut factor = |half: f64| (unfitted * half * (2.0 * rng.uniform() - 1.0)).exp();
        let (fe, fr, fd) = (factor(p.modulus), factor(p.density), factor(p.damping));
        let fs = factor(p.spring);
        let w = &mut s.whisker;
        w.youngs_modulus *= fe;
        w.density *= fr;
        scale_damping(&mut w.damping, fd);
        let (u_follicle, u_compliance, u_tau) = (rng.uniform(), rng.uniform(), rng.uniform());
        w.follicle = match w.follicle {
            Follicle::Clamped if u_follicle < p.follicle => {
                let [lo, hi] = p.compliance;
                let compliance = (lo.ln() + u_compliance * (hi / lo).ln()).exp();
                let stiffness = self.k0 / compliance;
                // The follicle's damper reaches joint 0 through the series, scaled by
                // (k/k_f)² = 1/(1 + 1/compliance)² on the nominal chain (see `Model::new`): it is
                // drawn so that joint 0 receives k_f·τ·e^u, τ the whisker's own time constant
                // and u in ±1, the damping this prior was chosen and tested with.
                let series = (1.0 + 1.0 / compliance).powi(2);
                Follicle::Spring {
                    stiffness,
                    damping: stiffness * self.tau0 * (2.0 * u_tau - 1.0).exp() * series,
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
            gain: nominal[c].gain * (1.0 + unfitted * p.gain * (2.0 * rng.uniform() - 1.0)),
            offset: nominal[c].offset,
        }));
        let (u_resegment, u_segments, u_rule) = (rng.uniform(), rng.uniform(), rng.uniform());
        if u_resegment < p.resegment {
            let [lo, hi] = p.segments;
            let factor = (lo.ln() + u_segments * (hi / lo).ln()).exp();
            s.segments = ((s.segments as f64 * factor).round() as usize).clamp(2, MAX_SEGMENTS);
        }
        if u_rule < p.seed_rule {
            s.discretisation = Discretisation::Seed;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::family::Family;

    #[test]
    fn a_drawn_follicle_gives_joint_0_a_damper_of_its_stiffness_times_the_whisker_s_time_constant()
    {
        let base = Family::builtin("e2").unwrap().base().clone();
        // Only the follicle varies, on the nominal chain.
        let prior = Randomisation {
            modulus: 0.0,
            density: 0.0,
            damping: 0.0,
            follicle: 1.0,
            spring: 0.0,
            taper: 0.0,
            gain: 0.0,
            resegment: 0.0,
            seed_rule: 0.0,
            ..Randomisation::default()
        };
        let around = Around::new(&base, prior).unwrap();
        let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
        for seed in 0..300 {
            let mut s = base.clone();
            around.apply(&mut s, seed);
            let Follicle::Spring { stiffness, damping } = s.whisker.follicle else {
                panic!("draw {seed}: the follicle stayed clamped");
            };
            let model = vibrissa_core::Model::new(
                &s.whisker.check().unwrap(),
                s.segments,
                s.discretisation,
            )
            .unwrap();
            // What joint 0 receives of the follicle's damper through the series.
            let share = model.stiffness[0] / stiffness;
            let ratio = damping * share * share / (stiffness * around.tau0);
            lo = lo.min(ratio);
            hi = hi.max(ratio);
        }
        assert!(lo >= (-1.0f64).exp() * (1.0 - 1e-9), "{lo}");
        assert!(hi <= 1.0f64.exp() * (1.0 + 1e-9), "{hi}");
        assert!(lo < (-0.8f64).exp() && hi > 0.8f64.exp(), "{lo}..{hi}");
    }

    #[test]
    fn a_calibrated_scenario_is_randomised_narrowly_and_keeps_its_chain() {
        let fitted = "experiment = \"e2\"\nwhisker.follicle = { kind = \"spring\", stiffness = 3e-4, damping = 3e-8 }\n[calibration]\nlabelled = \"calib\"\nrecordings = 9\n";
        let calibrated = Family::open_str(fitted, "fitted.toml", &[]).unwrap();
        let base = calibrated.base().clone();
        let prior = calibrated
            .clone()
            .randomised_if(true)
            .unwrap()
            .randomisation()
            .unwrap();
        assert_eq!(prior, Randomisation::calibrated());
        // Not calibrated: the wide prior.
        let e2 = Family::builtin("e2").unwrap();
        let wide = e2.randomised_if(true).unwrap().randomisation().unwrap();
        assert_eq!(wide, Randomisation::default());
        let around = Around::new(&base, prior).unwrap();
        let mut moved = 0;
        for seed in 0..100 {
            let mut s = base.clone();
            around.apply(&mut s, seed);
            let fe = s.whisker.youngs_modulus / base.whisker.youngs_modulus;
            assert!((0.904..=1.106).contains(&fe), "{fe}");
            moved += usize::from((fe - 1.0).abs() > 0.05);
            let Follicle::Spring { stiffness, .. } = s.whisker.follicle else {
                panic!("the fitted follicle spring is kept");
            };
            assert!((2.71e-4..=3.32e-4).contains(&stiffness), "{stiffness}");
            assert_eq!(s.whisker.tip_radius, base.whisker.tip_radius);
            assert_eq!(s.segments, base.segments);
            assert_eq!(s.discretisation, base.discretisation);
            for (r, b) in s
                .sensor_response
                .to_array()
                .iter()
                .zip(base.sensor_response.to_array())
            {
                assert!((r.gain / b.gain - 1.0).abs() <= 0.02, "{}", r.gain);
            }
        }
        assert!(
            moved > 30,
            "{moved} of 100 draws moved the modulus by over 5%"
        );
    }

    /// A fitted file whose record gives the modulus and density 5% errors correlated 0.9, the
    /// follicle's damping a standard error twice its value, `m0`'s gain 3%, and an offset.
    const FITTED_WITH_CORRELATION: &str = r#"
experiment = "e2"
whisker.follicle = { kind = "spring", stiffness = 3e-4, damping = 3e-8 }
[calibration]
[[calibration.parameters]]
key = "whisker.youngs_modulus"
value = 3.3e9
std_error = 1.65e8
determined = true
[[calibration.parameters]]
key = "whisker.density"
value = 1100.0
std_error = 55.0
determined = true
[[calibration.parameters]]
key = "whisker.follicle.damping"
value = 3e-8
std_error = 6e-8
determined = true
[[calibration.parameters]]
key = "sensors.m0.gain"
value = 1.0
std_error = 0.03
determined = true
[[calibration.parameters]]
key = "sensors.m0.offset"
value = 0.0
std_error = 1e-7
determined = true
[calibration.correlation]
keys = ["whisker.youngs_modulus", "whisker.density", "whisker.follicle.damping", "sensors.m0.gain", "sensors.m0.offset"]
matrix = [[1.0, 0.9, 0.0, 0.0, 0.5], [0.9, 1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0, 0.0], [0.5, 0.0, 0.0, 0.0, 1.0]]
"#;

    #[test]
    fn a_recorded_fit_is_drawn_with_its_standard_errors_and_correlations() {
        let calibrated = Family::open_str(FITTED_WITH_CORRELATION, "fitted.toml", &[]).unwrap();
        let randomised = calibrated.clone().randomised_if(true).unwrap();
        let around = randomised.around().unwrap();
        assert!(around.is_fitted());
        assert_ne!(
            randomised.digest(),
            calibrated
                .randomised(Randomisation::calibrated())
                .unwrap()
                .digest()
        );
        let base = calibrated.base().clone();
        let n = 4000;
        let (mut le, mut lr, mut ld, mut lg) = (vec![], vec![], vec![], vec![]);
        for seed in 0..n {
            let mut s = base.clone();
            around.apply(&mut s, seed);
            le.push((s.whisker.youngs_modulus / base.whisker.youngs_modulus).ln());
            lr.push((s.whisker.density / base.whisker.density).ln());
            let (Follicle::Spring { stiffness, damping }, Follicle::Spring { damping: d0, .. }) =
                (s.whisker.follicle, base.whisker.follicle)
            else {
                panic!("the fitted follicle spring is kept");
            };
            assert_eq!(stiffness, 3e-4, "not in the record: not drawn");
            ld.push((damping / d0).ln());
            let (r, r0) = (s.sensor_response.m0, base.sensor_response.m0);
            lg.push((r.gain / r0.gain).ln());
            assert_eq!(r.offset, r0.offset, "offsets are not drawn");
            assert_eq!(s.sensor_response.fx, base.sensor_response.fx);
            assert_eq!(s.whisker.tip_radius, base.whisker.tip_radius);
            assert_eq!(s.segments, base.segments);
        }
        let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
        let sd = |x: &[f64]| {
            let m = mean(x);
            (x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / x.len() as f64).sqrt()
        };
        let corr = |x: &[f64], y: &[f64]| {
            let (mx, my) = (mean(x), mean(y));
            x.iter()
                .zip(y)
                .map(|(a, b)| (a - mx) * (b - my))
                .sum::<f64>()
                / (x.len() as f64 * sd(x) * sd(y))
        };
        // Sampling error of an sd over 4000 draws is about 1.1%, of a correlation of 0.9 about 0.003.
        for (what, x, want) in [
            ("modulus", &le, 0.05),
            ("density", &lr, 0.05),
            ("follicle damping", &ld, MAX_LOG_SD),
            ("m0 gain", &lg, 0.03),
        ] {
            assert!((sd(x) / want - 1.0).abs() < 0.05, "{what}: sd {}", sd(x));
            assert!(
                mean(x).abs() < 4.0 * want / (n as f64).sqrt(),
                "{what}: mean {}",
                mean(x)
            );
        }
        assert!((corr(&le, &lr) - 0.9).abs() < 0.015, "{}", corr(&le, &lr));
        assert!(corr(&le, &lg).abs() < 0.06, "{}", corr(&le, &lg));
        // The same seed, the same draw.
        let (mut a, mut b) = (base.clone(), base.clone());
        around.apply(&mut a, 7);
        around.apply(&mut b, 7);
        assert_eq!(a, b);
    }

    #[test]
    fn a_negative_gain_is_drawn_by_its_size_and_keeps_its_sign() {
        let text = FITTED_WITH_CORRELATION
            .replace(
                "key = \"sensors.m0.gain\"\nvalue = 1.0",
                "key = \"sensors.m0.gain\"\nvalue = -1.0",
            )
            .replace(
                "[calibration]\n",
                "[sensors.m0]\ngain = -1.0\n[calibration]\n",
            );
        let f = Family::open_str(&text, "fitted.toml", &[]).unwrap();
        let f = f.randomised_if(true).unwrap();
        let around = f.around().unwrap();
        let mut logs = Vec::new();
        for seed in 0..400 {
            let mut s = f.base().clone();
            around.apply(&mut s, seed);
            let g = s.sensor_response.m0.gain;
            assert!(g < 0.0, "{g}");
            logs.push((-g).ln());
        }
        let sd = (logs.iter().map(|x| x * x).sum::<f64>() / logs.len() as f64).sqrt();
        assert!((sd / 0.03 - 1.0).abs() < 0.15, "{sd}");
    }

    #[test]
    fn draws_vary_the_whisker_within_the_prior_and_repeat_by_seed() {
        let f = Family::builtin("e2").unwrap();
        let base = f.base().clone();
        let around = Around::new(&base, Randomisation::default()).unwrap();
        let (mut springs, mut tapers, mut resegmented, mut seed_rule) = (0, 0, 0, 0);
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
            assert!((10..=60).contains(&s.segments), "{}", s.segments);
            resegmented += usize::from(s.segments != base.segments);
            seed_rule += usize::from(s.discretisation == Discretisation::Seed);
            s.check().expect("a valid scenario");
            let mut again = base.clone();
            around.apply(&mut again, seed);
            assert_eq!(again.whisker.youngs_modulus, s.whisker.youngs_modulus);
        }
        assert!((70..130).contains(&springs), "{springs}");
        assert!((70..130).contains(&tapers), "{tapers}");
        // A drawn count may round to the scenario's own.
        assert!((60..130).contains(&resegmented), "{resegmented}");
        assert!((70..130).contains(&seed_rule), "{seed_rule}");
    }

    #[test]
    fn segment_counts_stay_within_the_chain_s_limits() {
        let f = Family::builtin("e2").unwrap();
        let prior = Randomisation {
            resegment: 1.0,
            segments: [0.01, 100.0],
            ..Randomisation::default()
        };
        let around = Around::new(f.base(), prior).unwrap();
        for seed in 0..100 {
            let mut s = f.base().clone();
            around.apply(&mut s, seed);
            assert!((2..=MAX_SEGMENTS).contains(&s.segments), "{}", s.segments);
        }
        // Without resegmenting, every run keeps the scenario's chain.
        let around = Around::new(
            f.base(),
            Randomisation {
                resegment: 0.0,
                seed_rule: 0.0,
                ..Randomisation::default()
            },
        )
        .unwrap();
        for seed in 0..50 {
            let mut s = f.base().clone();
            around.apply(&mut s, seed);
            assert_eq!(s.segments, f.base().segments);
            assert_eq!(s.discretisation, f.base().discretisation);
        }
    }

    #[test]
    fn the_prior_is_part_of_the_family_s_digest() {
        let f = Family::builtin("e2").unwrap();
        let a = f.randomised(Randomisation::default()).unwrap();
        let b = f
            .randomised(Randomisation {
                resegment: 0.0,
                ..Randomisation::default()
            })
            .unwrap();
        assert_ne!(a.digest(), b.digest());
        assert_ne!(a.digest(), f.digest());
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
        for (what, prior) in [
            (
                "resegment",
                Randomisation {
                    resegment: 1.5,
                    ..Randomisation::default()
                },
            ),
            (
                "seed_rule",
                Randomisation {
                    seed_rule: -0.1,
                    ..Randomisation::default()
                },
            ),
            (
                "segments",
                Randomisation {
                    segments: [2.0, 1.0],
                    ..Randomisation::default()
                },
            ),
            (
                "segments",
                Randomisation {
                    segments: [0.0, 3.0],
                    ..Randomisation::default()
                },
            ),
            (
                "segments",
                Randomisation {
                    segments: [0.5, f64::INFINITY],
                    ..Randomisation::default()
                },
            ),
            (
                "runs",
                Randomisation {
                    runs: 0,
                    ..Randomisation::default()
                },
            ),
            (
                "taper",
                Randomisation {
                    taper: f64::NAN,
                    ..Randomisation::default()
                },
            ),
        ] {
            let e = Around::new(f.base(), prior).unwrap_err().to_string();
            assert!(e.contains(what), "{what}: {e}");
        }
    }
}
