//! Generative inference: a particle filter whose transition model is the whisker physics (the
//! seed paper's dynamic Bayesian network, its Fig. 5).
//!
//! Hidden state of a particle: the whisker's joint angles, rates and accelerations (a core
//! [`State`]) and the object's state: the box's near edge `d` (m), its speed `v` (m/s), the
//! height of its top face at t = 0 (its path is `y0 + v·t`; the start delay `t0` of the approach
//! follows from it) and, when asked for, its size (m) and friction coefficient. Transition:
//! physics steps of the core with seeded process noise on every segment; once a particle's box
//! has gone for good, its whisker rings on a copy of the model stepped once per sample (see
//! `FreeModel`). Observation: any set of the contract's channels `theta01`, `theta12`, `m0`,
//! `fx`, `fy` with independent Gaussian noise of a stated standard deviation per channel.
//!
//! Static unknowns get a Liu–West kernel move at every resampling: each resampled particle's
//! object parameters are shrunk toward the weighted mean by `a` and jittered with covariance
//! `(1 − a²)` times the weighted covariance, so the cloud's mean and spread are kept while its
//! points become distinct again. While a box may still touch its whisker, its height stays where
//! it is (the whisker state stays consistent with it): its speed moves, and its start delay
//! follows instead of moving on its own. Boxes that have not come
//! within reach yet are instead redrawn at every sample from the prior given that they have not
//! arrived ([`run`] calls it the waiting group), with early arrivals favoured and weighted back.
//! Resampling is systematic, when the effective sample size falls below a fraction of the
//! particle count. Every random number comes from a stream indexed by particle and generation,
//! so a run gives the same bits whatever the number of threads.

use crate::error::{Error, Result};
use crate::experiment::CHANNELS;
use crate::method::Estimate;
use rayon::prelude::*;
use serde::Serialize;
use vibrissa_core::batch;
use vibrissa_core::chain::{Discretisation, Model};
use vibrissa_core::dynamics::{initialize, step, Inputs, Integrator, State, Workspace};
use vibrissa_core::objects::{Motion, Object, Shape};
use vibrissa_core::rng::Rng;
use vibrissa_core::sensors::Sensors;
use vibrissa_core::whisker::WhiskerParams;

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
    /// Number of particles (≥ 1).
    pub particles: usize,
    /// Seed of every random stream.
    pub seed: u64,
    /// The whisker.
    pub whisker: WhiskerParams,
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
    /// Observation noise standard deviation per channel of [`CHANNELS`], SI.
    pub sigma: [f64; 5],
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
}

impl Config {
    /// The `e2` family: d ∈ [14, 31] mm, v ∈ [0.2, 1.6] m/s (the experiment's ranges, widened by
    /// 1 mm and 0.1 m/s), known start, 10 mm frictionless box,
    /// the `w30` whisker observed on a chain of 20 segments and modelled with 5, all five channels
    /// with noise `sigma`.
    pub fn e2(sigma: [f64; 5], particles: usize, seed: u64) -> Config {
        Config {
            particles,
            seed,
            whisker: WhiskerParams::w30(),
            segments: 5,
            observed_segments: 20,
            discretisation: Discretisation::default(),
            dt: 1e-3 / 3.0,
            max_iterations: 1,
            channels: (0..CHANNELS.len()).collect(),
            sigma,
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
        }
    }

    /// The settings for a run of `family` (the experiment box with unknowns `d` or `d, v`):
    /// its whisker, observed chain and box, priors on its ranges widened on both sides by the
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
        c.observed_segments = base.segments;
        c.discretisation = base.discretisation;
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
            Discretisation::default()
        }
    }

    /// Checks every setting, naming the first bad one.
    pub fn check(&self) -> Result<()> {
        let bad = |field: &str, allowed: &str| {
            Err(Error::Setting(format!(
                "filter setting `{field}`: expected {allowed}"
            )))
        };
        if self.particles == 0 {
            return bad("particles", "at least 1 particle");
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
        if !(self.shrink > 0.0 && self.shrink <= 1.0) {
            return bad("shrink", "a Liu–West shrinkage in (0, 1]");
        }
        if !(0.0..=1.0).contains(&self.ess_fraction) {
            return bad("ess_fraction", "a fraction in [0, 1]");
        }
        let ranges = [
            (0.0, f64::INFINITY),
            (1e-6, f64::INFINITY),
            (0.0, f64::INFINITY),
            (1e-6, f64::INFINITY),
            (0.0, 10.0),
        ];
        for (k, p) in self.priors.iter().enumerate() {
            let (lo, hi) = ranges[k];
            if !(p.lo.is_finite() && p.hi.is_finite() && p.lo <= p.hi && p.lo >= lo && p.hi <= hi) {
                return bad(
                    PARAMS[k],
                    "a prior range lo <= hi, finite, within the parameter's physical range",
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

/// Observations: sample times and channel values (`NaN` where a sample is missing).
#[derive(Debug, Clone, PartialEq)]
pub struct Observations {
    /// Sample times, s, increasing, starting at 0.
    pub t: Vec<f64>,
    /// `[CHANNELS][samples]`; channels that are not observed may be empty.
    pub values: Vec<Vec<f64>>,
}

impl Observations {
    /// Observations sampled at `rate` (Hz) from t = 0, from channel-major series.
    pub fn at_rate(values: Vec<Vec<f64>>, rate: f64) -> Observations {
        let n = values.iter().map(Vec::len).max().unwrap_or(0);
        Observations {
            t: (0..n).map(|k| k as f64 / rate).collect(),
            values,
        }
    }
}

/// The posterior of one sample.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TraceRow {
    /// Sample time, s.
    pub t: f64,
    /// Effective sample size before any resampling at this sample.
    pub ess: f64,
    /// Per free unknown: the posterior summary.
    pub estimates: Vec<Estimate>,
}

/// What a filter run returns.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Posterior {
    /// Names of the free unknowns, in the order of every [`TraceRow::estimates`].
    pub unknowns: Vec<&'static str>,
    /// One row per sample.
    pub trace: Vec<TraceRow>,
    /// Samples whose channel values were missing (`NaN`) and skipped, counted per value.
    pub skipped: usize,
    /// Resampling events.
    pub resamples: usize,
    /// Particle steps that diverged (those particles got weight zero).
    pub diverged: usize,
    /// Physics steps taken over all particles.
    pub steps: u64,
    /// Share of particle-samples advanced on the free-ringing model (the box gone for good).
    pub ringing_share: f64,
    /// Logarithm of the (tempered) marginal likelihood of the observations, up to a constant
    /// that depends only on the noise levels: the sum over samples of the log mean weight
    /// update. Compares priors or models on the same series.
    pub log_evidence: f64,
}

impl Posterior {
    /// A posterior over `unknowns` with no sample yet.
    pub fn empty(unknowns: Vec<&'static str>) -> Posterior {
        Posterior {
            unknowns,
            trace: Vec::new(),
            skipped: 0,
            resamples: 0,
            diverged: 0,
            steps: 0,
            ringing_share: 0.0,
            log_evidence: 0.0,
        }
    }

    /// The posterior at the last sample.
    pub fn last(&self) -> &[Estimate] {
        self.trace.last().map(|r| &r.estimates[..]).unwrap_or(&[])
    }

    /// The sample time and effective sample size where the effective sample size was least (the
    /// first such sample), if there is any sample. A value near 1 means that one particle carried
    /// almost all the weight there: the cloud had lost the data, and the posterior after it
    /// rests on the descendants of very few particles and is likely too narrow.
    pub fn least_ess(&self) -> Option<(f64, f64)> {
        self.trace
            .iter()
            .map(|r| (r.t, r.ess))
            .reduce(|a, b| if b.1 < a.1 { b } else { a })
    }
}

/// The object's state of one particle: `[d, v, y0, size, mu]` with `y0` the height of the top
/// face at t = 0 (its trajectory is `y0 + v·t`).
type ObjState = [f64; 5];

const Y: usize = 2;

/// The particle's box.
fn object_of(o: &ObjState) -> Object {
    let [d, v, y0, size, mu] = *o;
    Object {
        shape: Shape::Box {
            width: size,
            height: size,
        },
        position: [d + 0.5 * size, y0 - 0.5 * size],
        angle: 0.0,
        motion: Motion::Constant {
            velocity: [0.0, v],
            angular_velocity: 0.0,
        },
        friction: mu,
    }
}

/// Start delay of the approach: the top face is `gap` below the whisker at `t0`.
fn start_delay(o: &ObjState, gap: f64) -> f64 {
    -(o[Y] + gap) / o[1]
}

/// The filter's reported value of unknown `k` for a particle.
fn param(o: &ObjState, k: usize, gap: f64) -> f64 {
    match k {
        2 => start_delay(o, gap),
        _ => o[k],
    }
}

/// The whisker's model once a particle's box has gone for good: the same chain stepped once per
/// sample period, its stiffness raised so that the first mode keeps its frequency at that step
/// (the implicit method's period elongation, `Ω_num = 2·atan(Ω/2)` with `Ω = ω·h`, is undone by
/// `ω_model = (2/h)·tan(ω·h/2)`). Higher modes, whose frequencies it gets wrong, are damped away
/// within a few milliseconds of the slip-off.
struct FreeModel {
    model: Model,
    stepper: vibrissa_core::dynamics::Stepper,
    /// Tip deflection per √energy, m/√J: √(2L³/(3·EI_min)), the cantilever's least stiffness.
    reach_per_root_energy: f64,
    /// Highest rest point of the whisker plus its thickest radius and a margin, m.
    clearance: f64,
}

impl FreeModel {
    fn new(config: &Config, model: &Model, period: f64) -> Result<FreeModel> {
        let f1 = model
            .modes()
            .map_err(|e| Error::Observation(format!("filter free model: {e}")))?
            .frequencies[0];
        let omega_h = 2.0 * std::f64::consts::PI * f1 * period;
        let warp = ((0.5 * omega_h).tan() / (0.5 * omega_h)).powi(2);
        let mut params = config.whisker.clone();
        params.youngs_modulus *= warp;
        let stiffer = params
            .check()
            .map_err(|e| Error::Observation(format!("filter free model: {e}")))?;
        let free = Model::new(&stiffer, config.segments, config.model_discretisation())
            .map_err(|e| Error::Observation(format!("filter free model: {e}")))?;
        let stepper = Integrator {
            dt: period,
            max_iterations: config.max_iterations,
            ..Integrator::default()
        }
        .check()
        .map_err(|e| Error::Observation(format!("filter integrator: {e}")))?;
        let p = &config.whisker;
        let r_min = p.base_radius.min(p.tip_radius);
        let ei_min = p.youngs_modulus * std::f64::consts::PI * r_min.powi(4) / 4.0;
        let mut y_rest = 0.0f64;
        let (mut y, mut ang) = (0.0f64, 0.0f64);
        for i in 0..model.n {
            ang += model.rest[i];
            y += model.arc * ang.sin();
            y_rest = y_rest.max(y.abs());
        }
        let rmax = model.radius.iter().cloned().fold(0.0, f64::max);
        Ok(FreeModel {
            model: free,
            stepper,
            reach_per_root_energy: (2.0 * p.length.powi(3) / (3.0 * ei_min)).sqrt(),
            clearance: y_rest + rmax + 2e-4,
        })
    }

    /// Whether the box has left the whisker for good at time `t`: it moves away (upward) and its
    /// bottom is beyond anything the whisker can reach with its energy (by 10%).
    fn cleared(&self, s: &State, o: &ObjState, t: f64, ws: &mut Workspace) -> bool {
        let [_, v, y0, size, _] = *o;
        let bottom = y0 + v * t - size;
        if v <= 0.0 || bottom <= self.clearance {
            return false;
        }
        let energy = vibrissa_core::dynamics::kinetic_energy(&self.model, s, ws)
            + vibrissa_core::dynamics::potential_energy(&self.model, s);
        bottom > self.clearance + 1.1 * self.reach_per_root_energy * energy.max(0.0).sqrt()
    }
}

/// The joint angles `theta01`, `theta12` that a chain `observed` would show, from the joint angles
/// `q` of the model chain `model` (which may be cut into fewer, longer segments). A joint spring
/// holds its angle at its rest angle plus the elastic bending moment there times its compliance,
/// so the model's moments `k_i·(q_i − rest_i)` at its nodes are interpolated linearly in arc length
/// (the bending moment is linear near the base, where no load acts) to the observed chain's first
/// two joints. Identical chains map exactly. `q` needs the model's joints up to the one beyond the
/// observed chain's second joint.
pub fn map_joints(model: &Model, observed: &Model, q: &[f64]) -> [f64; 2] {
    if model.n == observed.n && model.stiffness == observed.stiffness {
        return [q[0], q[1]];
    }
    let moment = |i: usize| model.stiffness[i] * (q[i] - model.rest[i]);
    std::array::from_fn(|j| {
        let s = j as f64 * observed.arc / model.arc;
        let i = (s.floor() as usize).min(q.len().saturating_sub(2));
        let u = s - i as f64;
        let m = (1.0 - u) * moment(i) + u * moment(i + 1);
        observed.rest[j] + m / observed.stiffness[j]
    })
}

/// The filter's transition model: the chain, its stepper, and the free-ringing model.
struct Chain<'a> {
    model: &'a Model,
    stepper: &'a vibrissa_core::dynamics::Stepper,
    ringing: &'a FreeModel,
}

/// Advances one particle by `steps` steps of the contact model (or `periods` steps of the
/// free-ringing model once its box has gone for good), with process noise of intensity `noise`
/// drawn once per sample period; marks the box gone when it has left for good by time `t`.
#[allow(clippy::too_many_arguments)]
fn advance(
    chain: &Chain,
    s: &mut State,
    o: &ObjState,
    gone: &mut bool,
    steps: usize,
    periods: usize,
    noise: f64,
    t: f64,
    ws: &mut Workspace,
) -> std::result::Result<(), ()> {
    let ringing = chain.ringing;
    if *gone {
        // Free ringing: one step per period of the free model.
        let inputs = Inputs {
            base: Default::default(),
            loads: &[],
            noise,
            objects: &[],
        };
        for _ in 0..periods {
            step(&ringing.model, &ringing.stepper, s, &inputs, ws).map_err(|_| ())?;
        }
        return Ok(());
    }
    let object = [object_of(o)];
    // Process noise drawn once per period (on its first step, with the intensity that gives the
    // period's impulse its full variance).
    let per_period = (steps / periods.max(1)).max(1);
    let lumped = noise * (per_period as f64).sqrt();
    for j in 0..steps {
        let inputs = Inputs {
            base: Default::default(),
            loads: &[],
            noise: if j % per_period == 0 { lumped } else { 0.0 },
            objects: &object,
        };
        step(chain.model, chain.stepper, s, &inputs, ws).map_err(|_| ())?;
    }
    if s.contact.is_none() && ringing.cleared(s, o, t, ws) {
        let none = Inputs {
            base: Default::default(),
            loads: &[],
            noise: 0.0,
            objects: &[],
        };
        initialize(&ringing.model, s, &none, ws).map_err(|_| ())?;
        *gone = true;
    }
    Ok(())
}

/// Stream indices: particles' process noise, their moves, the resampling draws, the prior.
const STREAM_NOISE: u64 = 1 << 40;
const STREAM_MOVE: u64 = 2 << 40;
const STREAM_RESAMPLE: u64 = 3 << 40;
const STREAM_PRIOR: u64 = 4 << 40;
const STREAM_REDRAW: u64 = 5 << 40;

/// Runs the filter over `obs`, one sample at a time, calling `progress` with the fraction done.
pub fn run(
    config: &Config,
    obs: &Observations,
    progress: &mut dyn FnMut(f64),
) -> Result<Posterior> {
    config.check()?;
    check_observations(config, obs)?;
    let whisker = config
        .whisker
        .check()
        .map_err(|e| Error::Observation(format!("filter whisker: {e}")))?;
    let model = Model::new(&whisker, config.segments, config.model_discretisation())
        .map_err(|e| Error::Observation(format!("filter model: {e}")))?;
    let observed = Model::new(&whisker, config.observed_segments, config.discretisation)
        .map_err(|e| Error::Observation(format!("observed chain: {e}")))?;
    let np = config.particles;
    let period = obs.t.get(1).map_or(1e-3, |t1| t1 - obs.t[0]);
    let per_sample = ((period / config.dt) * (1.0 - 1e-9)).ceil().max(1.0) as usize;
    let stepper = Integrator {
        dt: period / per_sample as f64,
        max_iterations: config.max_iterations,
        ..Integrator::default()
    }
    .check()
    .map_err(|e| Error::Observation(format!("filter integrator: {e}")))?;

    // Initial particles: the whisker at rest, the object drawn from the prior (or the mixture
    // with the injected proposal).
    let mut template = State::at_rest(&model, config.seed);
    let mut ws = Workspace::new(&model);
    initialize(
        &model,
        &mut template,
        &Inputs {
            base: Default::default(),
            loads: &[],
            noise: 0.0,
            objects: &[],
        },
        &mut ws,
    )
    .map_err(|e| Error::Observation(format!("filter initial state: {e}")))?;
    let mut states: Vec<State> = (0..np)
        .map(|i| {
            let mut s = template.clone();
            s.rng = Rng::stream(config.seed, STREAM_NOISE + i as u64);
            s
        })
        .collect();
    let mut objs: Vec<ObjState> = Vec::with_capacity(np);
    let mut logw: Vec<f64> = Vec::with_capacity(np);
    for i in 0..np {
        let mut rng = Rng::stream(config.seed, STREAM_PRIOR + i as u64);
        let (o, lw) = draw_initial(config, &mut rng);
        objs.push(o);
        logw.push(lw);
    }

    let free: Vec<usize> = (0..PARAMS.len())
        .filter(|&k| config.priors[k].is_free())
        .collect();
    let mut post = Posterior::empty(config.unknowns());
    post.trace.reserve(obs.t.len());
    let mut ringing_samples = 0usize;
    let ringing = FreeModel::new(config, &model, period)?;
    let chain = Chain {
        model: &model,
        stepper: &stepper,
        ringing: &ringing,
    };
    // Whether each particle's box has left for good (its whisker then rings free).
    let mut cleared = vec![false; np];
    let mut spare_cleared = cleared.clone();
    // Whether each particle's box has come within reach of its whisker (before that, the whisker
    // moves by process noise alone and the box's parameters are redrawn at every sample).
    let mut arrived = vec![false; np];
    let mut spare_arrived = arrived.clone();
    let reach_zone = ringing.clearance + 1e-4;
    let mut spare = states.clone();
    let mut generation = 0u64;
    let samples = obs.t.len();
    for k in 0..samples {
        let t = obs.t[k];
        let y: [f64; 5] = std::array::from_fn(|c| {
            obs.values
                .get(c)
                .and_then(|v| v.get(k))
                .copied()
                .unwrap_or(f64::NAN)
        });
        let mut seen = [false; 5];
        for &c in &config.channels {
            if y[c].is_finite() {
                seen[c] = true;
            } else {
                post.skipped += 1;
            }
        }
        // Predict (k > 0) and weight every particle, in parallel.
        let steps = if k == 0 {
            0
        } else {
            let dt_obs = t - obs.t[k - 1];
            ((dt_obs / stepper.dt) + 0.5).floor() as usize
        };
        let periods = if k == 0 {
            0
        } else {
            (((t - obs.t[k - 1]) / period) + 0.5).floor() as usize
        };
        // Weight mass the particles carry into this sample (for the evidence).
        let prior_mass: f64 = logw.iter().map(|l| l.exp()).sum();
        let ringing_before = cleared.iter().filter(|c| **c).count();
        let diverged = batch::sum_with_workspace(
            &model,
            states
                .par_iter_mut()
                .zip(objs.par_iter())
                .zip(logw.par_iter_mut())
                .zip(cleared.par_iter_mut()),
            |ws, (((s, o), lw), gone)| {
                if *lw == f64::NEG_INFINITY {
                    return 0;
                }
                let noise = config.process_noise;
                if advance(&chain, s, o, gone, steps, periods, noise, t, ws).is_err() {
                    *lw = f64::NEG_INFINITY;
                    return 1;
                }
                let mut pred = Sensors::read(s).to_array();
                [pred[0], pred[1]] = map_joints(&model, &observed, s.q());
                let mut ll = 0.0;
                for c in 0..5 {
                    if seen[c] {
                        let z = (y[c] - pred[c]) / config.sigma[c];
                        ll -= 0.5 * z * z;
                    }
                }
                *lw += ll;
                0
            },
        );
        post.diverged += diverged;
        post.steps += ((np - ringing_before) * steps + ringing_before * periods) as u64;
        ringing_samples += ringing_before;

        // Normalise.
        let max = logw.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        if max == f64::NEG_INFINITY {
            return Err(Error::Observation(format!(
                "every particle diverged or has zero likelihood by t = {t} s"
            )));
        }
        let mut w: Vec<f64> = logw.iter().map(|l| (l - max).exp()).collect();
        let total: f64 = w.iter().sum();
        // The weights entered this sample normalised (or equal after resampling), so their new
        // sum is the sample's likelihood averaged over the particles.
        post.log_evidence += max + (total / prior_mass).ln();
        w.iter_mut().for_each(|x| *x /= total);
        let ess = 1.0 / w.iter().map(|x| x * x).sum::<f64>();

        // Posterior summary.
        let estimates = free
            .iter()
            .map(|&p| {
                let vals: Vec<f64> = objs.iter().map(|o| param(o, p, config.gap)).collect();
                summarise(&vals, &w)
            })
            .collect();
        post.trace.push(TraceRow { t, ess, estimates });

        // Resample and move.
        if ess < config.ess_fraction * np as f64 && k + 1 < samples {
            generation += 1;
            post.resamples += 1;
            let mut rng = Rng::stream(config.seed, STREAM_RESAMPLE + generation);
            let parents = systematic(&w, rng.uniform());
            let moved = liu_west(
                config, &objs, &w, &parents, &free, &cleared, &arrived, generation, t,
            );
            for (i, &p) in parents.iter().enumerate() {
                spare[i].clone_from(&states[p]);
                spare_cleared[i] = cleared[p];
                spare_arrived[i] = arrived[p];
                spare[i].rng =
                    Rng::stream(config.seed, STREAM_NOISE + (generation << 20) + i as u64);
            }
            std::mem::swap(&mut states, &mut spare);
            std::mem::swap(&mut cleared, &mut spare_cleared);
            std::mem::swap(&mut arrived, &mut spare_arrived);
            objs = moved;
            logw.iter_mut().for_each(|l| *l = 0.0);
        } else {
            logw.iter_mut()
                .zip(&w)
                .for_each(|(l, x)| *l = if *x > 0.0 { x.ln() } else { f64::NEG_INFINITY });
        }
        // Boxes that have not come within reach yet: the whisker has not felt them, so their
        // parameters are redrawn from the prior given "not arrived by now", with arrivals in the
        // next few milliseconds favoured (and weighted back), so that whenever contact begins
        // many particles meet it with a spread of distances and speeds.
        if k + 1 < samples {
            redraw_waiting(
                config,
                &mut objs,
                &mut logw,
                &mut arrived,
                t,
                reach_zone,
                Rng::stream(config.seed, STREAM_REDRAW + k as u64),
            );
        }
        if k % 16 == 0 {
            progress(k as f64 / samples as f64);
        }
    }
    progress(1.0);
    post.ringing_share = ringing_samples as f64 / (np * samples) as f64;
    Ok(post)
}

/// Share of the redrawn boxes that arrive within [`ARRIVAL_WINDOW`] of now.
const ARRIVAL_SHARE: f64 = 0.5;
/// How soon a favoured arrival comes, s.
const ARRIVAL_WINDOW: f64 = 3e-3;

/// Redraws the box of every particle whose box has not come within `zone` (m) of the whisker by
/// time `t` (marking the others as arrived), from the prior restricted to boxes that have not
/// arrived yet. Half of the draws arrive within [`ARRIVAL_WINDOW`]; each draw is weighted by
/// prior / proposal density, and the redrawn group keeps its total weight.
fn redraw_waiting(
    config: &Config,
    objs: &mut [ObjState],
    logw: &mut [f64],
    arrived: &mut [bool],
    t: f64,
    zone: f64,
    mut rng: Rng,
) {
    let pr = &config.priors;
    let travel = config.gap - zone;
    let uni = |rng: &mut Rng, lo: f64, hi: f64| lo + (hi - lo) * rng.uniform();
    let (mut old_mass, mut new_mass) = (0.0f64, 0.0f64);
    let mut group = Vec::new();
    for i in 0..objs.len() {
        if arrived[i] {
            continue;
        }
        let o = &objs[i];
        if o[Y] + o[1] * t >= -zone {
            arrived[i] = true;
            continue;
        }
        if logw[i] == f64::NEG_INFINITY {
            continue;
        }
        // Importance ratio π/q of the draw (π uniform on the allowed region).
        // With hypothesis injection, a share of the speeds and distances comes from the injected
        // estimate (weighted back like the initial draws).
        let inj = config.injection;
        let (v, t0, ratio) = if pr[2].is_free() {
            // Speed from the prior (or the injection), then the arrival time a = t0 + travel/v
            // after t.
            let (v, ratio_v) = match &inj {
                _ if !pr[1].is_free() => (pr[1].lo, 1.0),
                Some(j) => {
                    let v = if rng.uniform() < j.fraction {
                        truncated_normal(&mut rng, j.mean[1], j.std[1], &pr[1])
                    } else {
                        uni(&mut rng, pr[1].lo, pr[1].hi)
                    };
                    let prior = 1.0 / (pr[1].hi - pr[1].lo);
                    let mix = j.fraction * truncated_density(v, j.mean[1], j.std[1], &pr[1])
                        + (1.0 - j.fraction) * prior;
                    (v, prior / mix)
                }
                None => (uni(&mut rng, pr[1].lo, pr[1].hi), 1.0),
            };
            let (lo, hi) = ((pr[2].lo + travel / v).max(t), pr[2].hi + travel / v);
            if hi <= lo {
                (v, pr[2].lo, 0.0)
            } else {
                let soon = ARRIVAL_WINDOW.min(hi - lo);
                let a = if rng.uniform() < ARRIVAL_SHARE {
                    uni(&mut rng, lo, lo + soon)
                } else {
                    uni(&mut rng, lo, hi)
                };
                let q = ARRIVAL_SHARE * f64::from(u8::from(a <= lo + soon)) / soon
                    + (1.0 - ARRIVAL_SHARE) / (hi - lo);
                (v, a - travel / v, ratio_v / q)
            }
        } else if !pr[1].is_free() {
            // Known start and speed: the box arrives when it arrives.
            let (t0, v) = (pr[2].lo, pr[1].lo);
            (v, t0, if t0 + travel / v > t { 1.0 } else { 0.0 })
        } else {
            // Known start: the speeds whose box arrives after t.
            let t0 = pr[2].lo;
            let cap = if t > t0 && travel > 0.0 {
                pr[1].hi.min(travel / (t - t0))
            } else if t > t0 {
                pr[1].lo
            } else {
                pr[1].hi
            };
            if cap <= pr[1].lo {
                (pr[1].lo, t0, 0.0)
            } else {
                // Speeds arriving within the window: v >= travel / (t + window - t0).
                let fast = if travel > 0.0 {
                    (travel / (t + ARRIVAL_WINDOW - t0)).clamp(pr[1].lo, cap)
                } else {
                    pr[1].lo
                };
                let soon = cap - fast;
                let range = Prior::uniform(pr[1].lo, cap);
                let injected = inj.filter(|j| rng.uniform() < j.fraction);
                let v = if let Some(j) = injected {
                    truncated_normal(&mut rng, j.mean[1], j.std[1], &range)
                } else if soon > 0.0 && rng.uniform() < ARRIVAL_SHARE {
                    uni(&mut rng, fast, cap)
                } else {
                    uni(&mut rng, pr[1].lo, cap)
                };
                let share = if soon > 0.0 { ARRIVAL_SHARE } else { 0.0 };
                let q = share * f64::from(u8::from(v >= fast)) / soon.max(f64::MIN_POSITIVE)
                    + (1.0 - share) / (cap - pr[1].lo);
                let q = match &inj {
                    Some(j) => {
                        j.fraction * truncated_density(v, j.mean[1], j.std[1], &range)
                            + (1.0 - j.fraction) * q
                    }
                    None => q,
                };
                (v, t0, 1.0 / q)
            }
        };
        let mut o = [0.0; 5];
        let ratio = match &inj {
            Some(j) if pr[0].is_free() => {
                o[0] = if rng.uniform() < j.fraction {
                    truncated_normal(&mut rng, j.mean[0], j.std[0], &pr[0])
                } else {
                    uni(&mut rng, pr[0].lo, pr[0].hi)
                };
                let prior = 1.0 / (pr[0].hi - pr[0].lo);
                let mix = j.fraction * truncated_density(o[0], j.mean[0], j.std[0], &pr[0])
                    + (1.0 - j.fraction) * prior;
                ratio * prior / mix
            }
            _ => {
                o[0] = uni(&mut rng, pr[0].lo, pr[0].hi);
                ratio
            }
        };
        o[1] = v;
        o[Y] = -config.gap - v * t0;
        o[3] = uni(&mut rng, pr[3].lo, pr[3].hi);
        o[4] = uni(&mut rng, pr[4].lo, pr[4].hi);
        objs[i] = o;
        old_mass += logw[i].exp();
        let lw = logw[i] + ratio.ln();
        new_mass += lw.exp();
        logw[i] = lw;
        group.push(i);
    }
    if new_mass > 0.0 && old_mass > 0.0 {
        let shift = (old_mass / new_mass).ln();
        for i in group {
            logw[i] += shift;
        }
    }
}

/// Refuses observations the filter cannot use.
fn check_observations(config: &Config, obs: &Observations) -> Result<()> {
    let n = obs.t.len();
    if n < 2 {
        return Err(Error::Observation(format!(
            "the filter needs at least 2 samples, got {n}"
        )));
    }
    for &c in &config.channels {
        match obs.values.get(c) {
            Some(v) if v.len() == n => {}
            _ => {
                return Err(Error::Observation(format!(
                    "channel `{}` is observed by the filter but missing or of the wrong length (expected {n} samples)",
                    CHANNELS[c]
                )))
            }
        }
    }
    if obs.t.iter().any(|t| !t.is_finite()) {
        return Err(Error::Observation("a sample time `t` is not finite".into()));
    }
    let period = obs.t[1] - obs.t[0];
    if period.is_nan() || period <= 0.0 {
        return Err(Error::Observation("sample times `t` must increase".into()));
    }
    for k in 1..n {
        let dt = obs.t[k] - obs.t[k - 1];
        let m = dt / period;
        // Gaps of whole sample periods are predicted across; anything else is refused.
        if m.is_nan() || m < 0.5 || (m - m.round()).abs() > 1e-3 {
            return Err(Error::Observation(format!(
                "irregular sample times: t = {} s follows {} s, expected a whole number of periods of {period} s",
                obs.t[k],
                obs.t[k - 1]
            )));
        }
    }
    Ok(())
}

/// One particle's initial object state and log importance weight (0 without injection).
fn draw_initial(config: &Config, rng: &mut Rng) -> (ObjState, f64) {
    let pr = &config.priors;
    let uni = |rng: &mut Rng, p: &Prior| p.lo + (p.hi - p.lo) * rng.uniform();
    let mut o: ObjState = [0.0; 5];
    let mut lw = 0.0;
    let injected = config.injection;
    let from_proposal = match &injected {
        Some(inj) => rng.uniform() < inj.fraction,
        None => false,
    };
    for k in [0usize, 1] {
        o[k] = if from_proposal {
            let inj = injected.as_ref().expect("checked above");
            truncated_normal(rng, inj.mean[k], inj.std[k], &pr[k])
        } else {
            uni(rng, &pr[k])
        };
    }
    let t0 = uni(rng, &pr[2]);
    o[3] = uni(rng, &pr[3]);
    o[4] = uni(rng, &pr[4]);
    o[Y] = -config.gap - o[1] * t0;
    if let Some(inj) = &injected {
        // prior / mixture density on (d, v).
        let mut prior = 1.0;
        let mut prop = 1.0;
        for k in [0usize, 1] {
            if pr[k].is_free() {
                prior /= pr[k].hi - pr[k].lo;
                prop *= truncated_density(o[k], inj.mean[k], inj.std[k], &pr[k]);
            }
        }
        let mix = (1.0 - inj.fraction) * prior + inj.fraction * prop;
        lw = (prior / mix).ln();
    }
    (o, lw)
}

fn normal_cdf(z: f64) -> f64 {
    0.5 * erfc(-z / std::f64::consts::SQRT_2)
}

/// Complementary error function (Numerical Recipes' Chebyshev fit, relative error < 1.2e-7).
fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let r = t
        * (-z * z - 1.265_512_23
            + t * (1.000_023_68
                + t * (0.374_091_96
                    + t * (0.096_784_18
                        + t * (-0.186_288_06
                            + t * (0.278_868_07
                                + t * (-1.135_203_98
                                    + t * (1.488_515_87
                                        + t * (-0.822_152_23 + t * 0.170_872_77)))))))))
            .exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

/// Density at `x` of a normal truncated to the prior's range.
fn truncated_density(x: f64, mean: f64, std: f64, p: &Prior) -> f64 {
    if !p.is_free() {
        return 1.0;
    }
    let mass = normal_cdf((p.hi - mean) / std) - normal_cdf((p.lo - mean) / std);
    let z = (x - mean) / std;
    (-0.5 * z * z).exp() / (std * (2.0 * std::f64::consts::PI).sqrt()) / mass.max(1e-300)
}

/// A draw from a normal truncated to the prior's range (rejection, then uniform as a fallback).
fn truncated_normal(rng: &mut Rng, mean: f64, std: f64, p: &Prior) -> f64 {
    if !p.is_free() {
        return p.lo;
    }
    for _ in 0..1000 {
        let x = mean + std * rng.normal();
        if x >= p.lo && x <= p.hi {
            return x;
        }
    }
    p.lo + (p.hi - p.lo) * rng.uniform()
}

/// Systematic resampling: parent index of every new particle.
fn systematic(w: &[f64], u0: f64) -> Vec<usize> {
    let n = w.len();
    let mut parents = Vec::with_capacity(n);
    let mut cum = w[0];
    let mut i = 0;
    for j in 0..n {
        let u = (j as f64 + u0) / n as f64;
        while u > cum && i + 1 < n {
            i += 1;
            cum += w[i];
        }
        parents.push(i);
    }
    parents
}

/// Smallest standard deviation of the cloud that a Liu–West move assumes, as a fraction of each
/// unknown's prior range: a cloud that has collapsed onto one value (all weight on one particle)
/// still moves, so the filter can leave a wrong mode.
const COV_FLOOR: f64 = 2e-3;

#[allow(clippy::needless_range_loop, clippy::too_many_arguments)]
/// The Liu–West move of the resampled object states (see the module's documentation).
fn liu_west(
    config: &Config,
    objs: &[ObjState],
    w: &[f64],
    parents: &[usize],
    free: &[usize],
    cleared: &[bool],
    arrived: &[bool],
    generation: u64,
    t: f64,
) -> Vec<ObjState> {
    // Moved coordinates: the free unknowns (d, v, t0, size, mu), summarised over the weighted
    // cloud. A particle whose box has gone takes the move as it is. One whose box may still touch
    // its whisker keeps the box's height where it is (the whisker state stays consistent with
    // it): its speed and distance move, its start delay follows from the height and the speed.
    let m = free.len();
    let a = config.shrink;
    let mut out: Vec<ObjState> = parents.iter().map(|&p| objs[p]).collect();
    if m == 0 || a >= 1.0 {
        return out;
    }
    let gap = config.gap;
    // The cloud of the particles whose box has arrived (the others are redrawn anyway).
    let mass: f64 = w
        .iter()
        .zip(arrived)
        .filter(|(_, a)| **a)
        .map(|(w, _)| w)
        .sum();
    if mass <= 0.0 {
        return out;
    }
    let w: Vec<f64> = w
        .iter()
        .zip(arrived)
        .map(|(w, a)| if *a { w / mass } else { 0.0 })
        .collect();
    let w = &w[..];
    let mut mean = [0.0f64; 5];
    for (o, &wi) in objs.iter().zip(w) {
        for (j, &c) in free.iter().enumerate() {
            mean[j] += wi * param(o, c, gap);
        }
    }
    let mut cov = [[0.0f64; 5]; 5];
    for (o, &wi) in objs.iter().zip(w) {
        for j in 0..m {
            for l in 0..m {
                cov[j][l] +=
                    wi * (param(o, free[j], gap) - mean[j]) * (param(o, free[l], gap) - mean[l]);
            }
        }
    }
    // Cholesky with a small floor on the diagonal (a collapsed cloud still moves a little).
    let mut chol = [[0.0f64; 5]; 5];
    for j in 0..m {
        let span = config.priors[free[j]].hi - config.priors[free[j]].lo;
        cov[j][j] = cov[j][j].max(COV_FLOOR * COV_FLOOR * span * span);
    }
    for j in 0..m {
        for l in 0..=j {
            let mut s = cov[j][l];
            for r in 0..l {
                s -= chol[j][r] * chol[l][r];
            }
            chol[j][l] = if j == l {
                s.max(0.0).sqrt()
            } else if chol[l][l] > 0.0 {
                s / chol[l][l]
            } else {
                0.0
            };
        }
    }
    let h = (1.0 - a * a).sqrt();
    for (i, o) in out.iter_mut().enumerate() {
        if !arrived[parents[i]] {
            continue;
        }
        let mut rng = Rng::stream(config.seed, STREAM_MOVE + (generation << 20) + i as u64);
        let z: Vec<f64> = (0..m).map(|_| rng.normal()).collect();
        let (t0_old, y_now) = (start_delay(o, gap), o[Y] + o[1] * t);
        // Every unknown's value before the move (t0 depends on the speed, which moves first).
        let before: Vec<f64> = free.iter().map(|&c| param(o, c, gap)).collect();
        let mut t0_new = t0_old;
        for j in 0..m {
            let c = free[j];
            let noise: f64 = (0..=j).map(|l| chol[j][l] * z[l]).sum();
            let x = reflect(
                a * before[j] + (1.0 - a) * mean[j] + h * noise,
                &config.priors[c],
            );
            if c == Y {
                // While the box may still touch its whisker, its height is part of the contact
                // state: it stays where it is, and t0 follows from it and the speed.
                if cleared[parents[i]] {
                    t0_new = x;
                }
            } else {
                o[c] = x;
            }
        }
        o[Y] = if cleared[parents[i]] {
            -gap - o[1] * t0_new
        } else {
            y_now - o[1] * (t0_new - t0_old) - o[1] * t
        };
    }
    out
}

/// `x` reflected into the prior's range.
fn reflect(x: f64, p: &Prior) -> f64 {
    let (lo, hi) = (p.lo, p.hi);
    if hi <= lo {
        return lo;
    }
    let span = hi - lo;
    let mut y = (x - lo).rem_euclid(2.0 * span);
    if y > span {
        y = 2.0 * span - y;
    }
    lo + y
}

/// Weighted mean, std and central 90% interval.
fn summarise(vals: &[f64], w: &[f64]) -> Estimate {
    let mean: f64 = vals.iter().zip(w).map(|(x, w)| x * w).sum();
    let var: f64 = vals
        .iter()
        .zip(w)
        .map(|(x, w)| w * (x - mean) * (x - mean))
        .sum();
    let mut idx: Vec<usize> = (0..vals.len()).collect();
    idx.sort_by(|&a, &b| vals[a].total_cmp(&vals[b]));
    let quantile = |q: f64| {
        let mut cum = 0.0;
        for &i in &idx {
            cum += w[i];
            if cum >= q {
                return vals[i];
            }
        }
        vals[*idx.last().expect("at least one particle")]
    };
    Estimate {
        mean,
        std: var.max(0.0).sqrt(),
        ci90: [quantile(0.05), quantile(0.95)],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transition_models_set_their_chain_step_and_tempering() {
        assert_eq!(
            TransitionModel::from_name("fine").unwrap(),
            TransitionModel::Fine
        );
        let e = TransitionModel::from_name("exact").unwrap_err().to_string();
        assert!(e.contains("exact") && e.contains("coarse, fine"), "{e}");
        let mut pf = Pf::new(4000);
        pf.set_model(TransitionModel::Fine);
        let e2 = crate::Family::builtin("e2").unwrap();
        let c = pf.config(&e2, [1.0; 5]).unwrap();
        assert_eq!(c.segments, c.observed_segments);
        // The family's settings are the e2 filter's.
        for (a, b) in c.priors.iter().zip(Config::e2([1.0; 5], 4000, 1).priors) {
            assert!((a.lo - b.lo).abs() < 1e-15 && (a.hi - b.hi).abs() < 1e-15);
        }
        assert_eq!(c.whisker, Config::e2([1.0; 5], 4000, 1).whisker);
        let e1 = pf
            .config(&crate::Family::builtin("e1").unwrap(), [1.0; 5])
            .unwrap();
        assert_eq!(e1.priors[1], Prior::fixed(0.6));
        assert_eq!(c.dt, Integrator::default().dt);
        assert_eq!(pf.temper, FINE_TEMPER);
        pf.set_model(TransitionModel::Coarse);
        let c = pf.config(&e2, [1.0; 5]).unwrap();
        assert_eq!((c.segments, c.dt), (5, 1e-3 / 3.0));
        assert_eq!(pf.temper, temper_for(4000));
    }

    #[test]
    fn least_ess_finds_the_first_smallest_sample() {
        let row = |t: f64, ess: f64| TraceRow {
            t,
            ess,
            estimates: vec![],
        };
        let mut post = Posterior::empty(vec![]);
        assert_eq!(post.least_ess(), None);
        post.trace = vec![
            row(0.0, 100.0),
            row(0.001, 3.0),
            row(0.002, 3.0),
            row(0.003, 50.0),
        ];
        assert_eq!(post.least_ess(), Some((0.001, 3.0)));
    }

    #[test]
    fn tempering_follows_the_calibrated_points() {
        assert!((temper_for(250) - 2.2).abs() < 1e-12);
        assert!((temper_for(1000) - 1.3).abs() < 1e-12);
        assert!((temper_for(500) - 1.75).abs() < 1e-12);
        assert_eq!(temper_for(10), 2.2);
        assert_eq!(temper_for(100_000), 1.3);
    }

    #[test]
    fn systematic_resampling_keeps_proportions() {
        let w = [0.5, 0.25, 0.0, 0.25];
        let p = systematic(&w, 0.5);
        assert_eq!(p.len(), 4);
        assert_eq!(p.iter().filter(|&&i| i == 0).count(), 2);
        assert_eq!(p.iter().filter(|&&i| i == 2).count(), 0);
    }

    #[test]
    fn reflection_stays_in_range() {
        let p = Prior::uniform(1.0, 2.0);
        for x in [-3.3, 0.5, 1.5, 2.5, 7.1] {
            let y = reflect(x, &p);
            assert!((1.0..=2.0).contains(&y), "{x} -> {y}");
        }
        assert!((reflect(2.25, &p) - 1.75).abs() < 1e-12);
    }

    #[test]
    fn weighted_summary_matches_hand_values() {
        let e = summarise(&[1.0, 2.0, 3.0], &[0.25, 0.5, 0.25]);
        assert!((e.mean - 2.0).abs() < 1e-12);
        assert!((e.std - 0.5f64.sqrt()).abs() < 1e-12);
        assert_eq!(e.ci90, [1.0, 3.0]);
    }

    #[test]
    fn injected_particles_are_weighted_back_to_the_prior() {
        // With importance weights prior / mixture, the weighted cloud has the prior's mean even
        // though half of it sits near the injected estimate.
        let mut c = Config::e2([1.0; 5], 1, 3);
        c.injection = Some(Injection {
            fraction: 0.5,
            mean: [0.016, 1.4],
            std: [0.001, 0.05],
        });
        let mut rng = Rng::stream(11, 0);
        let (mut sw, mut sd, mut sv, mut near) = (0.0, 0.0, 0.0, 0usize);
        let n = 40000;
        for _ in 0..n {
            let (o, lw) = draw_initial(&c, &mut rng);
            let w = lw.exp();
            sw += w;
            sd += w * o[0];
            sv += w * o[1];
            near += usize::from((o[0] - 0.016).abs() < 0.002);
        }
        assert!(near > n / 2, "{near}");
        assert!((sd / sw - 0.0225).abs() < 2e-4, "{}", sd / sw);
        assert!((sv / sw - 0.9).abs() < 0.015, "{}", sv / sw);
    }

    #[test]
    fn waiting_boxes_are_redrawn_from_the_prior_given_no_arrival() {
        // Weighted redraws against plain rejection sampling of the prior: same mean start delay
        // and speed among boxes that have not arrived by t, and the group keeps its weight.
        let mut c = Config::e2([1.0; 5], 1, 3);
        c.priors[2] = Prior::uniform(0.0, 0.05);
        let (t, zone, n) = (0.01, 3e-4, 40_000);
        // n waiting boxes of equal weight, redrawn once: their states and new weights.
        let redraw = |c: &Config, seed: u64| {
            let mut objs = vec![[0.02, 1.0, -1.0, 0.01, 0.0]; n];
            let mut logw = vec![(1.0 / n as f64).ln(); n];
            let mut arrived = vec![false; n];
            let rng = Rng::stream(seed, 0);
            redraw_waiting(c, &mut objs, &mut logw, &mut arrived, t, zone, rng);
            let w: Vec<f64> = logw.iter().map(|l| l.exp()).collect();
            (objs, w)
        };
        let (objs, w) = redraw(&c, 5);
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        let travel = c.gap - zone;
        let mut soon = 0usize;
        for o in &objs {
            let a = start_delay(o, c.gap) + travel / o[1];
            assert!(a > t, "{o:?}");
            soon += usize::from(a < t + ARRIVAL_WINDOW);
        }
        assert!(soon > n / 3, "{soon}");
        let mean = |f: &dyn Fn(&ObjState) -> f64| -> f64 {
            objs.iter().zip(&w).map(|(o, w)| w * f(o)).sum()
        };
        let (t0_w, v_w) = (mean(&|o| start_delay(o, c.gap)), mean(&|o| o[1]));
        let mut rng = Rng::stream(6, 0);
        let (mut t0_r, mut v_r, mut k) = (0.0, 0.0, 0usize);
        while k < 200_000 {
            let (v, t0) = (0.2 + 1.4 * rng.uniform(), 0.05 * rng.uniform());
            if t0 + travel / v > t {
                t0_r += t0;
                v_r += v;
                k += 1;
            }
        }
        let (t0_r, v_r) = (t0_r / k as f64, v_r / k as f64);
        assert!((t0_w - t0_r).abs() < 6e-4, "{t0_w} vs {t0_r}");
        assert!((v_w - v_r).abs() < 0.02, "{v_w} vs {v_r}");

        // With half the draws injected near d = 16 mm, v = 1.4 m/s, the weights still give the
        // prior's conditional means.
        c.injection = Some(Injection {
            fraction: 0.5,
            mean: [0.016, 1.4],
            std: [0.001, 0.05],
        });
        let (objs, w) = redraw(&c, 7);
        let near = objs.iter().filter(|o| (o[0] - 0.016).abs() < 0.002).count();
        assert!(near > n / 2, "{near}");
        let d_w: f64 = objs.iter().zip(&w).map(|(o, w)| w * o[0]).sum();
        let v_w: f64 = objs.iter().zip(&w).map(|(o, w)| w * o[1]).sum();
        assert!((d_w - 0.0225).abs() < 3e-4, "{d_w}");
        assert!((v_w - v_r).abs() < 0.03, "{v_w} vs {v_r}");
    }

    #[test]
    fn a_known_speed_and_start_is_kept_while_waiting() {
        // e1: v fixed; the waiting boxes keep it and their weights.
        let mut c = Config::e2([1.0; 5], 1, 3);
        c.priors[1] = Prior::fixed(0.6);
        let mut objs = vec![[0.02, 0.6, -1e-3, 0.01, 0.0]; 8];
        let mut logw = vec![(1.0f64 / 8.0).ln(); 8];
        let mut arrived = vec![false; 8];
        redraw_waiting(
            &c,
            &mut objs,
            &mut logw,
            &mut arrived,
            0.0,
            3e-4,
            Rng::stream(1, 0),
        );
        for (o, l) in objs.iter().zip(&logw) {
            assert_eq!(o[1], 0.6);
            assert!((l.exp() - 0.125).abs() < 1e-12);
        }
    }

    #[test]
    fn joint_angles_map_exactly_under_a_linear_bending_moment() {
        // A straight and a curved whisker (whose joints rest at non-zero angles).
        let mut curved = WhiskerParams::w30();
        curved.rest_curvature = 20.0;
        for params in [WhiskerParams::w30(), curved] {
            let w = params.check().unwrap();
            let fine = Model::new(&w, 20, Discretisation::default()).unwrap();
            // A tip load: the bending moment falls linearly to zero at the tip, and every joint
            // of a chain in equilibrium holds its rest angle plus the moment at its node over its
            // stiffness.
            let moment = |s: f64| 3e-6 * (0.03 - s) + 1e-7;
            let angle = |m: &Model, i: usize| m.rest[i] + moment(i as f64 * m.arc) / m.stiffness[i];
            for n in [3, 5, 8, 20, 40] {
                let coarse = Model::new(&w, n, Discretisation::default()).unwrap();
                let q: Vec<f64> = (0..n).map(|i| angle(&coarse, i)).collect();
                let mapped = map_joints(&coarse, &fine, &q);
                for (j, m) in mapped.iter().enumerate() {
                    let want = angle(&fine, j);
                    assert!(
                        (m - want).abs() < 1e-12 * want.abs().max(1e-3),
                        "N = {n}, joint {j}: {m} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn truncated_density_integrates_to_one() {
        let p = Prior::uniform(0.0, 1.0);
        let n = 20000;
        let s: f64 = (0..n)
            .map(|i| truncated_density((i as f64 + 0.5) / n as f64, 0.9, 0.2, &p) / n as f64)
            .sum();
        assert!((s - 1.0).abs() < 1e-4, "{s}");
    }
}

/// Model error of the transition model per channel of [`CHANNELS`], as a fraction of the
/// `noisy` variant's sensor noise: what the filter's model cannot reproduce of the runs it
/// observes, measured on 15 clean and 15 process-noise-only `e2` runs (`pf_fidelity`). Two parts,
/// added in quadrature:
/// - the coarse model itself (5 segments, dt = 1/3 ms, one geometric iteration) against the
///   simulator that records the experiments (20 segments, dt = 0.1 ms): root-mean-square
///   differences 0.24, 0.23, 0.25, 0.72, 0.56;
/// - the process noise's response that the coarse chain lacks: the same random forces move the
///   channels by 0.81, 0.79, 0.82, 2.46, 1.49 on the 20-segment chain and by 0.76, 0.73, 0.76,
///   1.35, 1.20 on the 5-segment one; the difference of the squares is the part the filter's
///   particles cannot follow (mostly the higher modes in the base forces).
pub const MODEL_ERROR: [f64; 5] = [0.38, 0.37, 0.39, 2.18, 1.05];

/// Default tempering of the likelihood for `particles` particles: every observation noise is
/// multiplied by it, which widens the posterior for the model error that a Gaussian, independent
/// noise does not capture (its bias is correlated in time) and for the filter's own collapse with
/// few particles. Chosen for 90% coverage on 48 simulated runs that are never the evaluated grid
/// (`pf_evaluate cal` and `train`): 2.2 at 250 particles, 1.3 at 1000, log-linear between,
/// constant outside.
pub fn temper_for(particles: usize) -> f64 {
    let x = ((particles.max(1) as f64 / 250.0).log2() / 2.0).clamp(0.0, 1.0);
    2.2 + (1.3 - 2.2) * x
}

/// Extra tempering when the start of the approach is unknown (t0 free): arrival time, speed
/// and distance then trade against each other, and the filter's cloud is thinner in three
/// dimensions. Chosen on the same kind of runs, started 0–50 ms early, at 1000 particles.
pub const UNKNOWN_START_TEMPER: f64 = 1.3;

/// Tempering of the fine transition model ([`TransitionModel::Fine`]), whatever the particle
/// count: chosen for 90% coverage with an unknown start on 48 simulated runs that are not the
/// evaluated grid (`pf_evaluate cal` and `train`, 4000 particles, two filter seeds: coverage
/// 92% for d and 93% for v).
pub const FINE_TEMPER: f64 = 1.1;

/// The filter's transition model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TransitionModel {
    /// 5 segments at 1/3 ms, its measured model error ([`MODEL_ERROR`]) in the likelihood and
    /// the tempering of [`temper_for`]: real time with 1000 particles on 2 cores.
    #[default]
    Coarse,
    /// The chain that recorded the observations (its segment count) at the simulator's default
    /// time step (0.1 ms), no model error and the tempering [`FINE_TEMPER`]: about 20 times the
    /// cost of the coarse model per particle, and in need of thousands of particles (with 1000
    /// its posteriors are too narrow).
    Fine,
}

/// Names accepted by [`TransitionModel::from_name`].
pub const TRANSITION_MODELS: [&str; 2] = ["coarse", "fine"];

impl TransitionModel {
    /// Parses `coarse` or `fine`.
    pub fn from_name(name: &str) -> Result<TransitionModel> {
        match name {
            "coarse" => Ok(TransitionModel::Coarse),
            "fine" => Ok(TransitionModel::Fine),
            _ => Err(Error::Setting(format!(
                "transition model: unknown `{name}`; expected one of {}",
                TRANSITION_MODELS.join(", ")
            ))),
        }
    }

    /// The name used in reports.
    pub fn name(self) -> &'static str {
        match self {
            TransitionModel::Coarse => "coarse",
            TransitionModel::Fine => "fine",
        }
    }
}

/// Observation noise from the sensor noise `sensor`, the model error `model` and tempering.
pub fn observation_sigma(sensor: [f64; 5], model: [f64; 5], temper: f64) -> [f64; 5] {
    std::array::from_fn(|c| temper * sensor[c].hypot(model[c]))
}

/// Sensor noise of each channel estimated from series alone: the median absolute second
/// difference, scaled to a standard deviation (1.4826 / √6). Robust to contact events; for clean
/// series it measures only the signal's own curvature.
pub fn noise_from_series(samples: &[&[Vec<f64>]]) -> [f64; 5] {
    std::array::from_fn(|c| {
        let mut d2: Vec<f64> = samples
            .iter()
            .filter_map(|s| s.get(c))
            .flat_map(|x| x.windows(3).map(|w| (w[2] - 2.0 * w[1] + w[0]).abs()))
            .filter(|x| x.is_finite())
            .collect();
        if d2.is_empty() {
            return 0.0;
        }
        let mid = d2.len() / 2;
        let (_, m, _) = d2.select_nth_unstable_by(mid, f64::total_cmp);
        1.482_6 * *m / 6f64.sqrt()
    })
}

/// The particle filter as an estimator of the experiments' unknowns ([`crate::Method`]): `pf`.
///
/// Fitting estimates the sensor noise of each channel from the training runs
/// ([`noise_from_series`]); no training run enters the filter otherwise. Estimates are the
/// posterior at the last sample.
#[derive(Debug, Clone)]
pub struct Pf {
    /// Particles per run.
    pub particles: usize,
    /// Seed of the filter's streams.
    pub seed: u64,
    /// Likelihood tempering ([`temper_for`], or [`FINE_TEMPER`] for the fine model); times
    /// [`UNKNOWN_START_TEMPER`] when `max_delay > 0` with the coarse model.
    pub temper: f64,
    /// Largest start delay of the approach (0: the start is known).
    pub max_delay: f64,
    /// Time step of the transition model, s.
    pub dt: f64,
    /// Geometric iterations per step of the transition model.
    pub max_iterations: usize,
    /// Segments of the transition model's chain.
    pub segments: usize,
    /// Liu–West shrinkage ([`Config::shrink`]).
    pub shrink: f64,
    /// Resampling threshold ([`Config::ess_fraction`]).
    pub ess_fraction: f64,
    /// Hypothesis injection from another method's estimates (fraction of particles).
    pub inject: Option<(f64, std::sync::Arc<dyn crate::Method>)>,
    /// The transition model; set it with [`Pf::set_model`], which also sets `segments`, `dt`
    /// and `temper`.
    pub model: TransitionModel,
    sigma: Option<[f64; 5]>,
    family: Option<crate::Family>,
}

impl std::fmt::Debug for dyn crate::Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.name())
    }
}

impl Default for Pf {
    fn default() -> Self {
        Pf::new(1000)
    }
}

impl Pf {
    /// A filter with `particles` particles and the default settings.
    pub fn new(particles: usize) -> Pf {
        Pf {
            particles,
            seed: 1,
            temper: temper_for(particles),
            max_delay: 0.0,
            dt: 1e-3 / 3.0,
            max_iterations: 1,
            segments: 5,
            shrink: 0.98,
            ess_fraction: 0.5,
            inject: None,
            model: TransitionModel::Coarse,
            sigma: None,
            family: None,
        }
    }

    /// Switches the transition model, with its segment count (the coarse model's 5; the fine
    /// one takes the observed chain's), time step and tempering.
    pub fn set_model(&mut self, model: TransitionModel) {
        self.model = model;
        match model {
            TransitionModel::Coarse => {
                self.segments = 5;
                self.dt = 1e-3 / 3.0;
                self.temper = temper_for(self.particles);
            }
            TransitionModel::Fine => {
                self.dt = Integrator::default().dt;
                self.temper = FINE_TEMPER;
            }
        }
    }

    /// The observation noise found by [`crate::Method::fit`], if fitted.
    pub fn sigma(&self) -> Option<[f64; 5]> {
        self.sigma
    }

    /// The filter's settings for one run of `family` with observation noise `sigma`.
    pub fn config(&self, family: &crate::Family, sigma: [f64; 5]) -> Result<Config> {
        let mut c = Config::for_family(family, sigma, self.particles, self.seed)?;
        c.dt = self.dt;
        c.max_iterations = self.max_iterations;
        c.segments = match self.model {
            TransitionModel::Coarse => self.segments,
            TransitionModel::Fine => c.observed_segments,
        };
        c.shrink = self.shrink;
        c.ess_fraction = self.ess_fraction;
        if self.max_delay > 0.0 {
            c.priors[2] = Prior::uniform(0.0, self.max_delay);
        }
        Ok(c)
    }

    /// Runs the filter on one run's channel-major series, sampled as the family's runs.
    pub fn posterior(&self, obs: &[Vec<f64>]) -> Result<Posterior> {
        let (Some(sigma), Some(family)) = (self.sigma, &self.family) else {
            return Err(Error::Fit {
                method: "pf".into(),
                detail: "used before fit".into(),
            });
        };
        let mut config = self.config(family, sigma)?;
        if let Some((fraction, method)) = &self.inject {
            let e = method.predict(obs)?;
            let v = e
                .get(1)
                .copied()
                .unwrap_or(crate::Estimate::normal(config.priors[1].lo, 1.0));
            config.injection = Some(Injection {
                fraction: *fraction,
                mean: [e[0].mean, v.mean],
                std: [e[0].std.max(1e-5), v.std.max(1e-3)],
            });
        }
        run(
            &config,
            &Observations::at_rate(obs.to_vec(), family.sample_rate()),
            &mut |_| {},
        )
    }
}

impl crate::Method for Pf {
    fn name(&self) -> &'static str {
        "pf"
    }
    fn budget(&self) -> crate::Budget {
        crate::Budget::Free
    }
    fn channels(&self) -> Vec<usize> {
        (0..CHANNELS.len()).collect()
    }
    fn fit(&mut self, training: &crate::Training) -> Result<()> {
        let series: Vec<&[Vec<f64>]> = training
            .samples
            .iter()
            .chain(&training.calibration)
            .map(|s| &s.series[..])
            .collect();
        if series.is_empty() {
            return Err(Error::Fit {
                method: "pf".into(),
                detail: "no training runs to estimate the sensor noise from".into(),
            });
        }
        let sensor = noise_from_series(&series);
        let noisy = training.family.noise(crate::Variant::Noisy)?.sensor;
        let model: [f64; 5] = match self.model {
            TransitionModel::Coarse => std::array::from_fn(|c| MODEL_ERROR[c] * noisy[c]),
            TransitionModel::Fine => [0.0; 5],
        };
        let temper = if self.max_delay > 0.0 && self.model == TransitionModel::Coarse {
            self.temper * UNKNOWN_START_TEMPER
        } else {
            self.temper
        };
        self.sigma = Some(observation_sigma(sensor, model, temper));
        self.family = Some(training.family.clone());
        if let Some((_, m)) = &mut self.inject {
            let m = std::sync::Arc::get_mut(m).ok_or_else(|| Error::Fit {
                method: "pf".into(),
                detail: "the injected method is shared and cannot be fitted".into(),
            })?;
            m.fit(training)?;
        }
        Ok(())
    }
    fn predict(&self, obs: &[Vec<f64>]) -> Result<Vec<crate::Estimate>> {
        let post = self.posterior(obs)?;
        let last = post.last();
        // Unknowns of the experiment only (d, or d and v).
        let n = self.family.as_ref().map_or(2, |f| f.unknowns().len());
        Ok(last.iter().take(n).copied().collect())
    }
    fn settings(&self) -> Vec<(String, f64)> {
        let mut s = vec![
            ("particles".to_string(), self.particles as f64),
            ("temper".to_string(), self.temper),
        ];
        if let Some(sig) = self.sigma {
            for (c, x) in sig.iter().enumerate() {
                s.push((format!("sigma_{}", CHANNELS[c]), *x));
            }
        }
        s
    }
}
