//! The filter's settings: the priors of the object's unknowns, hypothesis injection, and the
//! checks of a run's configuration.

use super::gains::AngleGains;
#[cfg(doc)]
use super::map_joints;
use super::sensors::SensorSpread;
use crate::error::{Error, Result};
use crate::experiment::CHANNELS;
use serde::Serialize;
use vibrissa_core::chain::Discretisation;
use vibrissa_core::whisker::{Follicle, WhiskerParams};

/// Names of the object's unknowns, in the order of [`Config::priors`]: near-edge distance `d`
/// (m), speed `v` (m/s), start delay of the approach `t0` (s), box side `size` (m) and friction
/// coefficient `mu`.
pub const PARAMS: [&str; 5] = ["d", "v", "t0", "size", "mu"];

/// A uniform prior on `[lo, hi]`; `lo == hi` fixes the parameter.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Prior {
    /// Lower end.
    pub lo: f64,
    /// Upper end.
    pub hi: f64,
}

impl Prior {
    /// A fixed value.
    pub fn fixed(x: f64) -> Prior {
        Prior { lo: x, hi: x }
    }
    /// Uniform on `[lo, hi]`.
    pub fn uniform(lo: f64, hi: f64) -> Prior {
        Prior { lo, hi }
    }
    /// Whether the parameter is unknown.
    pub fn is_free(&self) -> bool {
        self.hi > self.lo
    }
}

/// Proposals from a discriminative estimate mixed into the initial particles (hypothesis
/// injection): a `fraction` of the particles is drawn from a normal around `mean` with `std`
/// (per unknown `d`, `v`; truncated to the prior), and every particle is weighted by
/// prior / mixture density, so the filter's posterior is unchanged in expectation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Injection {
    /// Share of the particles drawn from the proposal, in (0, 1).
    pub fraction: f64,
    /// Proposal means of `d` (m) and `v` (m/s).
    pub mean: [f64; 2],
    /// Proposal standard deviations of `d` and `v`.
    pub std: [f64; 2],
}

/// Settings of a filter run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Config {
    /// Number of particles (≥ 1), over all islands.
    pub particles: usize,
    /// Independent filters the particles are split among, merged at the end
    /// ([`super::islands`]; at most one per particle of each whisker entertained).
    pub islands: usize,
    /// Seed of every random stream.
    pub seed: u64,
    /// The whisker.
    pub whisker: WhiskerParams,
    /// Other whiskers the filter entertains besides `whisker` (none: the whisker is known).
    /// Particle `i` carries whisker `i mod (1 + alternatives)`, `whisker` first, through its
    /// resampled descendants, so the posterior weighs the whiskers by how well they explain the
    /// recording.
    pub alternatives: Vec<WhiskerParams>,
    /// Segments of the filter's chain. It may be coarser than the observed chain: its joint
    /// angles are mapped onto the observed chain's joints (see [`map_joints`]).
    pub segments: usize,
    /// Segments of the chain that produced the observations (sets where `theta01` and `theta12`
    /// are measured).
    pub observed_segments: usize,
    /// Stiffness rule of the observed chain, and of the transition model when it has the
    /// observed chain's segments (a coarser model keeps the default, the most accurate at few
    /// segments).
    pub discretisation: Discretisation,
    /// Time step of the transition model, s (shortened to divide the sample period).
    pub dt: f64,
    /// Geometric iterations per step of the transition model.
    pub max_iterations: usize,
    /// Observed channels, indices into [`CHANNELS`].
    pub channels: Vec<usize>,
    /// Observation noise standard deviation per channel of [`CHANNELS`], SI (in the recorded
    /// units, after the sensors' gains).
    pub sigma: [f64; 5],
    /// Gain of the sensor of each channel of [`CHANNELS`]: the filter predicts the recorded value
    /// `gain · x + offset` from the model's value `x`, as the simulator records it (a scenario's
    /// `[sensors.<channel>]`).
    pub sensor_gain: [f64; 5],
    /// Offset of the sensor of each channel of [`CHANNELS`], in the channel's unit.
    pub sensor_offset: [f64; 5],
    /// How far the sensors' gains and offsets may lie from `sensor_gain` and `sensor_offset`:
    /// the filter marginalises them within each particle (see [`SensorSpread`]).
    pub sensor_spread: SensorSpread,
    /// The prior of the joint angles' gains when it is not the one `sensor_gain` and
    /// `sensor_spread` give: what the other recordings of a batch learnt of them (see
    /// [`AngleGains`]). Only where `sensor_spread` leaves the gains unknown.
    pub angle_gains: Option<AngleGains>,
    /// Process-noise intensity on every segment, N·s^½·m^-½.
    pub process_noise: f64,
    /// Liu–West shrinkage `a` in (0, 1].
    pub shrink: f64,
    /// Resample when the effective sample size falls below this fraction of the particles.
    pub ess_fraction: f64,
    /// Priors of [`PARAMS`].
    pub priors: [Prior; 5],
    /// Gap between the box's top face and the whisker when the approach starts, m.
    pub gap: f64,
    /// Hypothesis injection, if any.
    pub injection: Option<Injection>,
    /// Whether particles are stepped in lane groups, many of one whisker at once (the default:
    /// faster, and every particle reaches the bits it would reach alone); `false` steps each on
    /// its own, for checking that.
    pub lane_groups: bool,
    /// Stiffness rule of the transition chain when it has fewer segments than the observed one.
    pub coarse_rule: Discretisation,
}

/// Segments of the coarse transition model's chain for `whisker`: 5 for a uniform whisker in a
/// clamped follicle (the `w30` of the experiments, on which the coarse model and its tempering
/// were chosen), 8 for a tapered whisker or one in a compliant follicle. A 5-segment chain cannot
/// follow a bending stiffness that falls along the whisker (16 times from base to tip at half the
/// radius) or a compliance concentrated at the base: on 40 noisy strikes of our own simulator,
/// the filter's distance error was 0.33 mm (tapered to half the radius) and 0.45 mm (tapered,
/// in a compliant follicle, other material) with 5 segments and 0.16 and 0.20 mm with 8, which
/// gives 0.13 mm on the uniform, clamped whisker (0.16 with 5) at 1.5 times the cost.
pub fn coarse_segments(whisker: &WhiskerParams) -> usize {
    let uniform = whisker.tip_radius == whisker.base_radius;
    let clamped = matches!(whisker.follicle, Follicle::Clamped);
    if uniform && clamped {
        5
    } else {
        8
    }
}

/// Segment counts the coarse chain may take for a whisker known only roughly, fewest first
/// ([`rough_segments`]).
pub const ROUGH_SEGMENTS: [usize; 4] = [5, 8, 12, 16];

/// Stiffness rule of the coarse chain for a whisker known only roughly: the joints' compliances
/// matched to the beam's deflection at every node ([`Discretisation::Nodal`]), with which 5
/// segments follow a whisker tapered to half its base radius within [`CHAIN_TOLERANCE`] (the hat
/// weights need 16).
pub const ROUGH_RULE: Discretisation = Discretisation::Nodal;

/// Largest relative error of a chain's compliance where a contact meets it ([`chain_follows`]):
/// a contact is then placed within about half a per cent of its distance from the base (the
/// deflection grows about as the cube of that distance), 0.15 mm at 30 mm.
pub const CHAIN_TOLERANCE: f64 = 0.015;

/// Points along the outer two thirds of the whisker where [`chain_follows`] compares compliances.
const COMPLIANCE_POINTS: usize = 60;

/// The deflection at arc length `s` of the straight `whisker` under a unit force there, square to
/// it (m/N): the Euler–Bernoulli beam's ([`vibrissa_core::beam::point_compliance`]) plus
/// `s² / k_f` for a compliant follicle.
fn beam_compliance(whisker: &vibrissa_core::whisker::Whisker, s: f64) -> f64 {
    let follicle = match whisker.params().follicle {
        Follicle::Spring { stiffness, .. } => s * s / stiffness,
        Follicle::Clamped => 0.0,
    };
    vibrissa_core::beam::point_compliance(whisker, s) + follicle
}

/// Whether a chain of `segments` segments with the stiffness rule `rule` follows `whisker` where
/// contacts meet it: at every one of [`COMPLIANCE_POINTS`] points along its outer two thirds, the
/// deflection under a force there is within [`CHAIN_TOLERANCE`] of the Euler–Bernoulli beam's
/// ([`beam_compliance`]). A tapered whisker's bending stiffness falls as the fourth power of its
/// radius, so the hat weights of a few segments lump its flexible outer part into joints that are
/// too stiff between them and too soft at them; the nodal rule matches every node instead.
pub fn chain_follows(
    whisker: &WhiskerParams,
    segments: usize,
    rule: Discretisation,
) -> Result<bool> {
    use vibrissa_core::chain::Model;
    let checked = whisker
        .check()
        .map_err(|e| Error::Setting(format!("the filter's chain: {e}")))?;
    let model = Model::new(&checked, segments, rule)
        .map_err(|e| Error::Setting(format!("the filter's chain of {segments} segments: {e}")))?;
    let length = whisker.length;
    let step = length / segments as f64;
    Ok((0..COMPLIANCE_POINTS).all(|i| {
        let s = length * (1.0 + 2.0 * (i + 1) as f64 / COMPLIANCE_POINTS as f64) / 3.0;
        // The chain's joints sit at its nodes: joint j turns by (s − s_j) / k_j under the force.
        let chain: f64 = model
            .stiffness
            .iter()
            .enumerate()
            .map(|(j, k)| (s - j as f64 * step).max(0.0).powi(2) / k)
            .sum();
        let beam = beam_compliance(&checked, s);
        (chain / beam - 1.0).abs() <= CHAIN_TOLERANCE
    }))
}

/// Segments of the coarse chain with the stiffness rule `rule` for a family whose whisker is known
/// only roughly, around `base`: the fewest of [`ROUGH_SEGMENTS`] whose chain follows `base`
/// ([`chain_follows`]), else the most. With [`ROUGH_RULE`], 5 for the uniform `e2` whisker and for
/// one whose tip has half the base's radius (with the hat weights 8 and 16). The whiskers the
/// filter entertains around it taper further, where the chain follows them less closely (with 5
/// nodal segments, within 2.6% of the compliance at a quarter of the base's radius).
pub fn rough_segments(base: &WhiskerParams, rule: Discretisation) -> Result<usize> {
    for &n in &ROUGH_SEGMENTS {
        if chain_follows(base, n, rule)? {
            return Ok(n);
        }
    }
    Ok(ROUGH_SEGMENTS[ROUGH_SEGMENTS.len() - 1])
}

/// Where each unknown's prior range may lie, `(lowest, highest)` per [`PARAMS`] entry: distances,
/// start delays and sizes not negative (sizes and speeds above zero), speeds up to 50 m/s
/// (whiskers meet objects at centimetres to metres per second), friction coefficients up to 10.
pub const PRIOR_BOUNDS: [(f64, f64); 5] = [
    (0.0, f64::INFINITY),
    (1e-6, 50.0),
    (0.0, f64::INFINITY),
    (1e-6, f64::INFINITY),
    (0.0, 10.0),
];

impl Config {
    /// Per unknown named in `unknowns`, the `[lo, hi]` of its prior (`None` for a name that is
    /// not one of [`PARAMS`]): where the filter's posterior can lie.
    pub fn support(&self, unknowns: &[&str]) -> Vec<Option<[f64; 2]>> {
        unknowns
            .iter()
            .map(|u| {
                PARAMS
                    .iter()
                    .position(|p| p == u)
                    .map(|k| [self.priors[k].lo, self.priors[k].hi])
            })
            .collect()
    }

    /// The `e2` family: d ∈ [14, 31] mm, v ∈ [0.2, 1.6] m/s (the experiment's ranges, widened by
    /// 1 mm and 0.1 m/s), known start, 10 mm frictionless box,
    /// the `w30` whisker observed on a chain of 20 segments and modelled with 5, all five channels
    /// with noise `sigma`.
    pub fn e2(sigma: [f64; 5], particles: usize, seed: u64) -> Config {
        Config {
            particles,
            islands: 1,
            seed,
            whisker: WhiskerParams::w30(),
            alternatives: Vec::new(),
            segments: 5,
            observed_segments: 20,
            discretisation: Discretisation::default(),
            dt: 1e-3 / 3.0,
            max_iterations: 1,
            channels: (0..CHANNELS.len()).collect(),
            sigma,
            sensor_gain: [1.0; 5],
            sensor_offset: [0.0; 5],
            sensor_spread: SensorSpread::default(),
            angle_gains: None,
            process_noise: crate::experiment::PROCESS_NOISE,
            shrink: 0.98,
            ess_fraction: 0.5,
            // A little wider than the family's range, so that a value at its edge lies inside
            // the prior's support (a central interval can never hold an edge of the support).
            priors: [
                Prior::uniform(0.014, 0.031),
                Prior::uniform(0.2, 1.6),
                Prior::fixed(0.0),
                Prior::fixed(0.010),
                Prior::fixed(0.0),
            ],
            gap: 1e-3,
            injection: None,
            lane_groups: true,
            coarse_rule: Discretisation::default(),
        }
    }

    /// The settings for a run of `family` (the experiment box with unknowns `d` or `d, v`):
    /// its whisker (modelled with [`coarse_segments`]), observed chain, sensors and box, priors on its ranges widened on both sides by the
    /// larger of each unknown's margins (so that a value at a range's edge lies inside the
    /// prior's support), and its fixed speed where `v` is not an unknown.
    pub fn for_family(
        family: &crate::Family,
        sigma: [f64; 5],
        particles: usize,
        seed: u64,
    ) -> Result<Config> {
        if !family.is_box_family() {
            return Err(Error::Setting(format!(
                "the particle filter models the experiment box: it needs a family with \
                 experiment = \"e1\" or \"e2\" and unknowns d or d, v (not {})",
                family.unknowns().join(", ")
            )));
        }
        let mut c = Config::e2(sigma, particles, seed);
        let base = family.base();
        c.whisker = base.whisker.clone();
        c.segments = coarse_segments(&c.whisker);
        c.observed_segments = base.segments;
        c.discretisation = base.discretisation;
        let sensors = base.sensor_response.to_array();
        c.sensor_gain = sensors.map(|r| r.gain);
        c.sensor_offset = sensors.map(|r| r.offset);
        c.priors[3] = Prior::fixed(vibrissa_io::scenario::BOX_SIDE);
        c.gap = vibrissa_io::scenario::BOX_GAP;
        let mut ranges = family.ranges().into_iter().zip(family.margins());
        if let Some(([lo, hi], [below, above])) = ranges.next() {
            let m = below.max(above);
            c.priors[0] = Prior::uniform(lo - m, hi + m);
        }
        c.priors[1] = match ranges.next() {
            Some(([lo, hi], [below, above])) => {
                let m = below.max(above);
                Prior::uniform((lo - m).max(1e-6), hi + m)
            }
            None => Prior::fixed(family.speed_of(&[]).unwrap_or(0.6)),
        };
        Ok(c)
    }

    /// The stiffness rule of the transition model: the observed chain's at its segment count,
    /// else the default.
    pub fn model_discretisation(&self) -> Discretisation {
        if self.segments == self.observed_segments {
            self.discretisation
        } else {
            self.coarse_rule
        }
    }

    /// Checks every setting, naming the first bad one.
    pub fn check(&self) -> Result<()> {
        let bad = |field: &str, allowed: &str| {
            Err(Error::Setting(format!(
                "filter setting `{field}`: expected {allowed}"
            )))
        };
        if !(1..=crate::limits::MAX_PARTICLES).contains(&self.particles) {
            return bad(
                "particles",
                &format!("1 to {} particles", crate::limits::MAX_PARTICLES),
            );
        }
        if self.islands == 0 {
            return bad("islands", "at least 1 island");
        }
        if self.alternatives.len() >= self.particles.min(u16::MAX as usize) {
            return bad(
                "alternatives",
                "fewer alternative whiskers than particles (and than 65535)",
            );
        }
        if !(self.dt > 0.0 && self.dt <= 1e-3) {
            return bad("dt", "a model time step in (0, 1 ms]");
        }
        if self.max_iterations == 0 {
            return bad("max_iterations", "at least 1");
        }
        let chains = 2..=vibrissa_core::chain::MAX_SEGMENTS;
        if !chains.contains(&self.segments) {
            return bad("segments", "a segment count from 2 to 200");
        }
        if !chains.contains(&self.observed_segments) {
            return bad("observed_segments", "a segment count from 2 to 200");
        }
        if self.channels.is_empty() || self.channels.iter().any(|&c| c >= CHANNELS.len()) {
            return bad("channels", "one or more of theta01, theta12, m0, fx, fy");
        }
        for &c in &self.channels {
            let s = self.sigma[c];
            if !(s.is_finite() && s > 0.0) {
                return bad(
                    CHANNELS[c],
                    "a finite observation noise > 0 for every observed channel",
                );
            }
        }
        for (name, (g, o)) in CHANNELS
            .iter()
            .zip(self.sensor_gain.iter().zip(&self.sensor_offset))
        {
            if !(g.is_finite() && *g != 0.0 && o.is_finite()) {
                return bad(
                    name,
                    "a finite sensor gain other than 0 and a finite sensor offset",
                );
            }
        }
        if !self.sensor_spread.is_valid() {
            return bad(
                "sensor_spread",
                "finite spreads of the sensors' gains and offsets, 0 or more",
            );
        }
        if let Some(g) = &self.angle_gains {
            if !g.is_valid() {
                return bad(
                    "angle_gains",
                    "finite gains other than 0 with finite variances, 0 or more",
                );
            }
            if self.sensor_spread.is_fixed() {
                return bad(
                    "angle_gains",
                    "none where the sensors' gains and offsets are known (sensor_spread zero)",
                );
            }
        }
        if !(self.shrink > 0.0 && self.shrink <= 1.0) {
            return bad("shrink", "a Liu–West shrinkage in (0, 1]");
        }
        if !(0.0..=1.0).contains(&self.ess_fraction) {
            return bad("ess_fraction", "a fraction in [0, 1]");
        }
        for (k, p) in self.priors.iter().enumerate() {
            let (lo, hi) = PRIOR_BOUNDS[k];
            if !(p.lo.is_finite() && p.hi.is_finite() && p.lo <= p.hi && p.lo >= lo && p.hi <= hi) {
                let within = if hi.is_finite() {
                    format!("[{lo}, {hi}]")
                } else {
                    format!("[{lo}, ∞)")
                };
                return bad(
                    PARAMS[k],
                    &format!(
                        "a prior range lo <= hi, finite, within {within} (got [{}, {}])",
                        p.lo, p.hi
                    ),
                );
            }
        }
        if let Some(inj) = &self.injection {
            if !(inj.fraction > 0.0 && inj.fraction < 1.0)
                || inj.std.iter().any(|s| !(s.is_finite() && *s > 0.0))
                || inj.mean.iter().any(|m| !m.is_finite())
            {
                return bad(
                    "injection",
                    "a fraction in (0, 1), finite means and stds > 0",
                );
            }
        }
        Ok(())
    }

    /// Names of the free unknowns.
    pub fn unknowns(&self) -> Vec<&'static str> {
        (0..PARAMS.len())
            .filter(|&k| self.priors[k].is_free())
            .map(|k| PARAMS[k])
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_beam_compliance_is_the_cantilever_formula_on_a_uniform_whisker() {
        let w = WhiskerParams::w30().check().unwrap();
        use vibrissa_core::beam::BeamProfile;
        let ei = w.ei(0.0);
        for s in [0.01, 0.02, 0.03] {
            let exact = s * s * s / (3.0 * ei);
            assert!((beam_compliance(&w, s) / exact - 1.0).abs() < 1e-12);
        }
        let mut sprung = WhiskerParams::w30();
        sprung.follicle = Follicle::Spring {
            stiffness: 1e-4,
            damping: 0.0,
        };
        let sprung = sprung.check().unwrap();
        let s = 0.02;
        let exact = s * s * s / (3.0 * ei) + s * s / 1e-4;
        assert!((beam_compliance(&sprung, s) / exact - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_few_hat_weighted_segments_follow_a_uniform_whisker_but_not_a_tapered_one() {
        let hat = Discretisation::Gregory;
        let mut w = WhiskerParams::w30();
        assert_eq!(w.tip_radius, w.base_radius);
        assert!(chain_follows(&w, 8, hat).unwrap());
        assert!(!chain_follows(&w, 5, hat).unwrap());
        // A tip of half the base's radius: the outer segments are up to 16 times more flexible.
        w.tip_radius = 0.5 * w.base_radius;
        assert!(!chain_follows(&w, 8, hat).unwrap());
        assert!(chain_follows(&w, 16, hat).unwrap());
        assert!(chain_follows(&w, 64, hat).unwrap());
    }

    #[test]
    fn five_nodal_segments_follow_a_uniform_and_a_tapered_whisker() {
        let mut w = WhiskerParams::w30();
        assert!(chain_follows(&w, 5, ROUGH_RULE).unwrap());
        w.tip_radius = 0.5 * w.base_radius;
        assert!(chain_follows(&w, 5, ROUGH_RULE).unwrap());
        // A quarter of the base's radius is beyond 5 segments, within 8.
        w.tip_radius = 0.25 * w.base_radius;
        assert!(!chain_follows(&w, 5, ROUGH_RULE).unwrap());
        assert!(chain_follows(&w, 8, ROUGH_RULE).unwrap());
    }

    #[test]
    fn the_rough_chain_grows_with_the_taper() {
        let mut w = WhiskerParams::w30();
        let hat = Discretisation::Gregory;
        assert_eq!(rough_segments(&w, hat).unwrap(), 8);
        assert_eq!(rough_segments(&w, ROUGH_RULE).unwrap(), ROUGH_SEGMENTS[0]);
        w.tip_radius = 0.5 * w.base_radius;
        assert_eq!(rough_segments(&w, hat).unwrap(), 16);
        assert_eq!(rough_segments(&w, ROUGH_RULE).unwrap(), 5);
        w.tip_radius = 0.25 * w.base_radius;
        assert_eq!(rough_segments(&w, ROUGH_RULE).unwrap(), 8);
        let bad = WhiskerParams {
            length: -1.0,
            ..w.clone()
        };
        let e = rough_segments(&bad, ROUGH_RULE).unwrap_err().to_string();
        assert!(e.contains("length"), "{e}");
    }
}
