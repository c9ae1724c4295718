//! Calibration: fitting what a real rig gets wrong about its whisker and sensors, with the
//! simulator in the loop, from labelled recordings (strikes whose object parameters are known).
//!
//! # Model
//!
//! Every labelled recording is simulated from the nominal scenario with its labels applied as
//! overrides (`d`, `v`, …; a folder that leaves an unknown of the scenario's family unlabelled
//! is refused), sampled like the recording (its own step and length; its first
//! sample is simulation time 0, up to the fitted time offset), without noise. Recorded channel
//! `c` of recording `r` at sample `k` is modelled as
//!
//! `y[r,c,k] = g_c · s_c(θ; r, k) + o_c + ε`,  `ε ~ N(0, σ_c²)` independent,
//!
//! where `s_c` is the simulated channel, `g_c` and `o_c` the sensor's gain and offset (shared by
//! all recordings) and `θ` the whisker's parameters. The fit maximises the likelihood: weighted
//! least squares in `θ`, `g`, `o`, alternated with the maximum-likelihood noise levels
//! `σ_c² = mean squared residual of channel c` (a few rounds, each starting from the previous
//! fit), so that channels in different units count by how well they can be fitted. Before the
//! first round every `σ_c` is 1% of the channel's range over the recordings; no `σ_c` goes below
//! 1e-4 of that range.
//!
//! # Parameters (`θ`)
//!
//! | key | parametrisation | start |
//! |---|---|---|
//! | `whisker.youngs_modulus` | `ln(E/E_nominal)` | nominal |
//! | `whisker.density` | `ln(ρ/ρ_nominal)` | nominal |
//! | `whisker.tip_radius` | `ln(tip/base radius)`, at most 0 | nominal |
//! | `whisker.follicle.stiffness` | `ln(k0/k_f)`, k0 the nominal chain's base joint; at most −8 is clamped | nominal |
//! | `whisker.follicle.damping` | `ln(c_f/(k_f·β0))`, β0 the whisker's own stiffness-proportional coefficient | nominal (clamped: 0) |
//! | `whisker.damping.ratio` (or `.q`, `.beta`) | `ln(value/nominal)` | nominal |
//! | `time_offset` | the recording's first sample on the simulation's clock, s | 0 |
//!
//! A clamped follicle and a uniform whisker are bounds of their parametrisations: the fit starts
//! there when the nominal is clamped or uniform, differences turn one-sided there, and steps stop
//! there. A follicle that ends at its bound (clamped) is reported as not determined and kept
//! clamped; a taper that ends uniform is determined when its standard error is small. `time_offset` is fitted only with a fixed base (it moves the objects along
//! their paths). A parameter set by the recordings' labels is not fitted.
//!
//! The simulated channels are unchanged when E, ρ, the follicle's stiffness and damping are all
//! multiplied by one factor, except that the base's moment and forces scale with it. The
//! recordings alone therefore cannot separate the force sensors' common gain from the whisker's
//! absolute stiffness: the gain of the first force channel present (m0, else fx, else fy) is held
//! at its nominal value as the reference of the force scale, and the other force gains are fitted
//! relative to it. Without any force channel, E is held instead.
//!
//! # Gains and offsets
//!
//! They enter linearly, so by default ([`GainHandling::Projected`]) they are solved in closed form
//! (a 2×2 weighted least-squares problem per channel) inside every residual evaluation, and the
//! Levenberg–Marquardt iterations see only the whisker's parameters (variable projection). With
//! [`GainHandling::Joint`] they are parameters of the iterations beside the whisker's, with
//! exact Jacobian columns. Both reach the same minimum; `docs/calibration.md` has the measured
//! comparison that made projection the default.
//!
//! # Solver
//!
//! Levenberg–Marquardt with Marquardt's scaling (damping λ times the diagonal of JᵀJ) and
//! Nielsen's update of λ, on nalgebra (`fit.rs`, about a hundred lines). It is written here rather
//! than taken from a crate because the problem needs what general drivers do not offer together:
//! a residual function that may fail (an object overlapping the whisker at t = 0, a divergence:
//! such a trial step is rejected and the damping raised), parameters with bounds (a uniform
//! whisker is the taper's bound; steps stop there and differences turn one-sided), the gains
//! and offsets re-solved inside every evaluation, and a stopping rule suited to a cost that is
//! not smooth at the finest scale (contact events fall on time steps). The Jacobian is by
//! central differences, one-sided at a bound or where a side fails to simulate; the
//! simulations of all parameters × sides × recordings run in parallel with rayon.
//!
//! Several starts (see `best_start`): the plain nominal one and the best points of a scan over
//! density × follicle compliance × taper are each taken a few iterations; the two lowest are
//! carried on to convergence, and the lower minimum wins.
//!
//! # Standard errors and determination
//!
//! At the solution the covariance is `s²·(JᵀJ)⁻¹` with `J` the Jacobian of the weighted
//! residuals with respect to every fitted quantity (whisker parameters, free gains, offsets) and
//! `s²` the residual variance per degree of freedom, times `(1 + r)/(1 − r)` with `r` the
//! residuals' lag-1 autocorrelation (correlated residuals, as a model that is slightly off
//! leaves them, carry less information than as many independent ones). The reported errors
//! add what the simulations' roughness adds: `(JᵀJ)⁻¹ M (JᵀJ)⁻¹`, with `M` measured from what
//! the linear model misses of the residuals at 32 points next to the final solution (contact
//! events fall on time steps, so a small change of the parameters redraws part of the
//! residual; see `fit::roughness`). Errors of the physical values follow by the delta method.
//! Whether the recordings determine a parameter is judged without the roughness term (it asks
//! what the recordings resolve, not how far the search may end from the best fit): a parameter
//! is not determined when a singular value of the column-normalised Jacobian below 1e-6 of the
//! largest is dominated by it, or when its relative standard error
//! exceeds [`Settings::threshold`] (for the follicle, its compliance; for the taper, the amount
//! of taper 1 − tip/base; for the time offset, a sample period). The worst such parameter is
//! held at its nominal value and the fit is repeated without it, until every fitted parameter is
//! determined. A fit that does not converge within [`Settings::max_iterations`] is an error.

mod fit;
mod params;
mod report;
mod search;
mod starts;

pub use crate::resolution::{contact_resolution, holds_contacts, CONTACT_STEP};

use crate::error::{Error, Result};
use fit::{Covariance, Run, Setup, Solution, CHANNELS};
use params::{Kind, Param, Reference};
use report::assemble;
use serde::Serialize;
use starts::{add_other_minima, best_start, FINALISTS, START_GAIN_PRIOR};
use std::sync::atomic::{AtomicUsize, Ordering};
use vibrissa_core::sensors::CHANNELS as NAMES;
use vibrissa_core::sim::{Response, SensorNoise, SensorResponse};
use vibrissa_core::whisker::Damping;
use vibrissa_io::labelled::{Labelled, TRUTH};
use vibrissa_io::scenario::{
    CalibratedParameter, Calibration, ChannelValues, Correlation, Document, Loaded, UnknownSpec,
};

/// Units of the observed channels, in [`NAMES`] order.
pub const UNITS: [&str; CHANNELS] = ["rad", "rad", "N·m", "N", "N"];

/// How the sensors' gains and offsets are fitted (see the [module documentation](self)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GainHandling {
    /// Solved in closed form inside every residual evaluation (variable projection).
    #[default]
    Projected,
    /// Parameters of the Levenberg–Marquardt iterations beside the whisker's.
    Joint,
}

/// Settings of a calibration.
#[derive(Debug, Clone, Copy)]
pub struct Settings {
    /// How gains and offsets are fitted.
    pub handling: GainHandling,
    /// Most Levenberg–Marquardt iterations (Jacobians) of one fit.
    pub max_iterations: usize,
    /// Most rounds of fitting and re-estimating the noise levels per fit.
    pub noise_rounds: usize,
    /// Finite-difference step of the whisker parameters in their parametrisation (logarithms).
    pub step: f64,
    /// Relative standard error above which a parameter is not determined.
    pub threshold: f64,
    /// Prior standard deviation of each fitted sensor gain about its nominal value, relative
    /// (0.1: the gains are known to about ±10%); 0 fits the gains by maximum likelihood alone.
    pub gain_prior: f64,
    /// Starts carried on to convergence after the short fits (at least 1); the lowest minimum
    /// wins, and the others' spread enters the standard errors (see [`calibrate`]).
    pub finalists: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            handling: GainHandling::Projected,
            max_iterations: 50,
            noise_rounds: 3,
            step: 0.03,
            threshold: 0.5,
            gain_prior: 0.1,
            finalists: FINALISTS,
        }
    }
}

/// Where a running calibration is (for progress displays).
#[derive(Debug, Clone)]
pub struct Progress {
    /// What is being fitted (`round 1 of 3, 7 parameters`).
    pub stage: String,
    /// Levenberg–Marquardt iteration of this fit.
    pub iteration: usize,
    /// Residual evaluations of this fit.
    pub evaluations: usize,
    /// Lowest weighted cost (sum of squared weighted residuals) so far.
    pub cost: f64,
}

/// One parameter of a calibration's result.
#[derive(Debug, Clone, Serialize)]
pub struct ParameterFit {
    /// Scenario key (`whisker.youngs_modulus`, `sensors.m0.gain`) or `time_offset`.
    pub key: String,
    /// SI unit of the values.
    pub unit: &'static str,
    /// Value in the nominal scenario (`None`: a clamped follicle).
    pub nominal: Option<f64>,
    /// Fitted value, or the nominal where not determined (infinite: a clamped follicle).
    pub value: f64,
    /// Standard error of `value` (determined parameters only).
    pub std_error: Option<f64>,
    /// Whether the recordings determined it.
    pub determined: bool,
    /// Why it was held, or how to read it.
    pub note: Option<String>,
}

/// One channel of a calibration's result.
#[derive(Debug, Clone, Serialize)]
pub struct ChannelFit {
    /// Channel name.
    pub name: &'static str,
    /// SI unit.
    pub unit: &'static str,
    /// Residual RMS with the nominal scenario and sensors.
    pub rms_before: f64,
    /// Residual RMS with the fitted scenario and sensors.
    pub rms_after: f64,
    /// Noise standard deviation the fit estimated (its residual RMS, floored).
    pub noise: f64,
}

/// One recording with the nominal and fitted simulations, as the sensors would record them.
#[derive(Debug, Clone)]
pub struct RunFit {
    /// Name in `truth.csv`.
    pub file: String,
    /// The labels.
    pub labels: Vec<(String, f64)>,
    /// Sample times of the recording, s.
    pub t: Vec<f64>,
    /// Recorded channels (`None`: not in the recording): `[channel][sample]`.
    pub recorded: [Option<Vec<f64>>; CHANNELS],
    /// The nominal scenario's channels.
    pub nominal: [Vec<f64>; CHANNELS],
    /// The fitted scenario's channels.
    pub fitted: [Vec<f64>; CHANNELS],
}

/// A calibration's result.
#[derive(Debug, Clone)]
pub struct Fit {
    /// Whisker parameters, then each channel's gain and offset.
    pub parameters: Vec<ParameterFit>,
    /// Channels present in the recordings.
    pub channels: Vec<ChannelFit>,
    /// The recordings with their simulations.
    pub runs: Vec<RunFit>,
    /// Levenberg–Marquardt iterations over all fits.
    pub iterations: usize,
    /// Simulations run.
    pub simulations: usize,
    /// Fits run (noise rounds and refits without undetermined parameters).
    pub fits: usize,
    /// Other minima of the cost, of the search's finalists, whose spread is in the standard
    /// errors (those within twice the best cost).
    pub other_minima: usize,
    /// `key=value` overrides that turn the nominal scenario into the fitted one.
    pub overrides: Vec<String>,
    /// Correlations of the determined parameters' errors, from the same covariance as their
    /// standard errors.
    pub correlation: Correlation,
    /// Channels left out of the fit because they hold one value (given) in every strike: a
    /// sensor that recorded nothing.
    pub left_out: Vec<(&'static str, f64)>,
    /// Channels left out of single strikes because they hold one value (given) from the first
    /// sample to the last there while they vary in other strikes (strike's file, channel,
    /// value): a sensor that recorded nothing in that strike.
    pub flat_in: Vec<(String, &'static str, f64)>,
    /// Substeps near contact that the fit simulated with and [`Fit::overrides`] writes into the
    /// fitted scenario ([`contact_resolution`]; `None`: the nominal's own setting).
    pub contact_substeps: Option<usize>,
    /// Whether the fit held contacts where the nominal left `hold_contacts` to its default, and
    /// [`Fit::overrides`] writes `hold_contacts = true` into the fitted scenario
    /// ([`holds_contacts`]).
    pub hold_contacts: bool,
}

impl Fit {
    /// The record for a fitted scenario's `[calibration]` table; `labelled` names the folder.
    pub fn record(&self, labelled: &str) -> Calibration {
        let by_channel = |f: fn(&ChannelFit) -> f64| {
            ChannelValues::from_array(std::array::from_fn(|c| {
                self.channels.iter().find(|ch| ch.name == NAMES[c]).map(f)
            }))
        };
        Calibration {
            labelled: Some(labelled.to_string()),
            recordings: Some(self.runs.len()),
            rms_before: by_channel(|c| c.rms_before),
            rms_after: by_channel(|c| c.rms_after),
            noise: by_channel(|c| c.noise),
            parameters: self
                .parameters
                .iter()
                .map(|p| CalibratedParameter {
                    key: p.key.clone(),
                    nominal: p.nominal,
                    value: p.value,
                    std_error: p.std_error,
                    determined: p.determined,
                    note: p.note.clone(),
                })
                .collect(),
            correlation: Some(self.correlation.clone()),
        }
    }

    /// The fitted scenario: `nominal` with the fitted values and the `[calibration]` record.
    pub fn document(&self, nominal: &Document, labelled: &str) -> Result<Document> {
        let mut doc = nominal.clone();
        for set in &self.overrides {
            doc.set(set)?;
        }
        doc.set_calibration(&self.record(labelled))?;
        // The result must load as a scenario.
        doc.loaded()?;
        Ok(doc)
    }
}

/// Calibrates `nominal` on the labelled recordings `set`; `progress` hears of every residual
/// evaluation. The simulations step contact as [`contact_resolution`] says, and the fit's
/// overrides carry that setting into the fitted scenario; the starting scan, which only ranks
/// points of a coarse grid, simulates at the nominal's own step (on two sets the same fit in
/// about 40% less processor time).
pub fn calibrate(
    nominal: &Document,
    set: &Labelled,
    settings: &Settings,
    progress: &mut dyn FnMut(&Progress),
) -> Result<Fit> {
    check_settings(settings)?;
    let hold = holds_contacts(nominal)?;
    let mut resolved = nominal.clone();
    if hold {
        resolved.set(HOLD_SETTING)?;
    }
    let mut fit = match contact_resolution(nominal)? {
        None => fit_resolved(&resolved, set, settings, None, progress)?,
        Some(substeps) => {
            let setting = format!("contact_substeps={substeps}");
            resolved.set(&setting)?;
            // The starting scan only ranks points far apart: it simulates at the nominal's own
            // step.
            let own = nominal.loaded()?.scenario.integrator.contact_substeps;
            let mut fit = fit_resolved(&resolved, set, settings, Some(own), progress)?;
            fit.overrides.insert(0, setting);
            fit.contact_substeps = Some(substeps);
            fit
        }
    };
    if hold {
        fit.overrides.insert(0, HOLD_SETTING.to_string());
    }
    fit.hold_contacts = hold;
    Ok(fit)
}

/// The override with which calibration holds contacts ([`holds_contacts`]).
const HOLD_SETTING: &str = "hold_contacts=true";

/// [`calibrate`] on `nominal` as it will be simulated.
fn fit_resolved(
    nominal: &Document,
    set: &Labelled,
    settings: &Settings,
    scan_substeps: Option<usize>,
    progress: &mut dyn FnMut(&Progress),
) -> Result<Fit> {
    let loaded = nominal.loaded()?;
    check_labels(&loaded, set)?;
    let base = loaded.scenario;
    let reference = Reference::of(&base)?;
    let mut runs = prepare(nominal, set)?;
    let flat_in = leave_out_flat(&mut runs);
    // The time offset is stepped by a quarter of the longest sample period.
    let period = set.recordings.iter().map(|r| r.step).fold(0.0, f64::max);
    let params = params::parameters(&base, &reference, &set.keys, settings.step, 0.25 * period);
    let count = AtomicUsize::new(0);

    // Channels with data, and the reference of the force scale. A channel that holds one value
    // in every strike (a sensor that recorded nothing) says nothing of the whisker, and fitted
    // it would pull the whisker towards a flat signal: it is left out.
    let with_data: Vec<usize> = (0..CHANNELS)
        .filter(|&c| {
            runs.iter().any(|r| {
                r.y[c]
                    .as_ref()
                    .is_some_and(|y| y.iter().any(|v| v.is_finite()))
            })
        })
        .collect();
    let (channels, constant): (Vec<usize>, Vec<usize>) = with_data
        .into_iter()
        .partition(|&c| constant_value(&runs, c).is_none());
    if channels.is_empty() {
        return Err(Error::Observation(format!(
            "{}: every channel holds one value in every strike ({}): nothing to fit",
            set.dir.display(),
            constant
                .iter()
                .map(|&c| NAMES[c])
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    let reference_channel = [2, 3, 4].into_iter().find(|c| channels.contains(c));
    let nominal_resp = base.sensor_response.to_array();
    let mut gain_free = [false; CHANNELS];
    for &c in &channels {
        gain_free[c] = Some(c) != reference_channel;
    }
    let mut notes: Vec<Option<String>> = vec![None; params.len()];
    let mut gain_notes: [Option<String>; CHANNELS] = Default::default();
    let mut free: Vec<bool> = vec![true; params.len()];
    #[allow(unused_mut)]
    if reference_channel.is_none() {
        if let Some(i) = params.iter().position(|p| p.kind == Kind::Modulus) {
            free[i] = false;
            notes[i] = Some(
                "held as the reference of the stiffness scale: without force channels, \
                 the angles cannot tell it from the density and the follicle"
                    .into(),
            );
        }
    }
    let held: Vec<Option<f64>> = params.iter().map(|p| p.x_nominal).collect();
    // Noise levels start at 1% of each channel's range.
    let ranges = ranges(&runs);
    let mut sigma = [1.0; CHANNELS];
    for &c in &channels {
        sigma[c] = 0.01 * ranges[c];
    }
    let mut setup = Setup {
        runs: &runs,
        params: &params,
        reference: &reference,
        free,
        held,
        channels: channels.clone(),
        sigma,
        gain_free,
        nominal: nominal_resp,
        handling: settings.handling,
        gain_prior: settings.gain_prior,
        smooth: 1,
        ys: Vec::new(),
        weights: Vec::new(),
        scan_substeps,
    };
    setup.set_smoothing(1);

    // The nominal scenario as it is, for the residuals before.
    let x_nominal: Vec<Option<f64>> = params.iter().map(|p| p.x_nominal).collect();
    let before = setup.simulate(&x_nominal, &count).ok_or_else(|| {
        Error::Calibration("a labelled recording's nominal scenario does not simulate".into())
    })?;
    let rms_before = setup.rms(&before, &nominal_resp);

    // Fit; hold the worst undetermined parameter and fit again, until all are determined.
    let z: Vec<f64> = (0..params.len())
        .filter(|&i| setup.free[i])
        .map(|i| params[i].x_start)
        .collect();
    let (mut iterations, mut fits) = (0, 0);
    // The search for a start holds the gains near their nominal values (a tight prior): gains
    // far off let the angle channels trade against the taper and the follicle into false
    // minima. The final fits then use the prior asked for.
    if settings.gain_prior > 0.0 {
        setup.gain_prior = settings.gain_prior.min(START_GAIN_PRIOR);
    } else {
        setup.gain_prior = START_GAIN_PRIOR;
    }
    let (best, others) = best_start(
        &setup,
        &z,
        settings,
        &count,
        &mut iterations,
        &mut fits,
        progress,
    )?;
    let (mut z, mut resp) = (best.z.clone(), best.resp);
    setup.gain_prior = settings.gain_prior;
    let (solution, cov, other_minima) = loop {
        let sol = fit_with_noise(
            &mut setup,
            &z,
            &resp,
            settings,
            &ranges,
            &count,
            &mut fits,
            &mut iterations,
            progress,
        )?;
        let mut cov = fit::covariance(&setup, &sol, &count)?;
        match worst_undetermined(&setup, &sol, &cov, settings, &reference) {
            None => {
                fit::add_roughness(&setup, &sol, &mut cov, &count)?;
                let counted = add_other_minima(&setup, &sol, &mut cov, &best, &others);
                break (sol, cov, counted);
            }
            Some((Held::Param(i), note)) => {
                let x = setup.full_x(&sol.z);
                setup.free[i] = false;
                notes[i] = Some(note);
                // Without a follicle spring its damping means nothing.
                if params[i].kind == Kind::FollicleCompliance {
                    if let Some(d) = params.iter().position(|p| p.kind == Kind::FollicleDamping) {
                        if setup.free[d] {
                            setup.free[d] = false;
                            notes[d] = Some("no follicle spring to damp".into());
                        }
                    }
                }
                z = (0..params.len())
                    .filter(|&k| setup.free[k])
                    .map(|k| x[k].unwrap_or(params[k].x_start))
                    .collect();
                resp = sol.resp;
            }
            Some((Held::Gain(c), note)) => {
                setup.gain_free[c] = false;
                gain_notes[c] = Some(note);
                z = sol.z.clone();
                resp = sol.resp;
            }
        }
    };

    let mut fit = assemble(
        &setup,
        &solution,
        &cov,
        &before,
        &rms_before,
        &notes,
        &gain_notes,
        set,
        reference_channel,
        iterations,
        fits,
        count.load(Ordering::Relaxed),
    );
    fit.other_minima = other_minima;
    fit.flat_in = flat_in;
    fit.left_out = constant
        .iter()
        .map(|&c| {
            let v = constant_value(&runs, c).unwrap_or(f64::NAN);
            (NAMES[c], v)
        })
        .collect();
    Ok(fit)
}

/// The one value channel `c` holds in every run, where it holds one (every finite sample alike).
fn constant_value(runs: &[Run], c: usize) -> Option<f64> {
    let mut values = runs
        .iter()
        .filter_map(|r| r.y[c].as_ref())
        .flatten()
        .filter(|v| v.is_finite());
    let first = *values.next()?;
    values.all(|&v| v == first).then_some(first)
}

/// Refuses settings out of range.
fn check_settings(s: &Settings) -> Result<()> {
    if s.max_iterations == 0 || s.noise_rounds == 0 || s.finalists == 0 {
        return Err(Error::Setting(
            "calibration: max_iterations, noise_rounds and finalists must be at least 1".into(),
        ));
    }
    if !(s.gain_prior >= 0.0 && s.gain_prior.is_finite()) {
        return Err(Error::Setting(format!(
            "calibration: gain_prior must be a finite number ≥ 0 (got {})",
            s.gain_prior
        )));
    }
    if !(s.step > 0.0 && s.step <= 0.3 && s.threshold > 0.0 && s.threshold.is_finite()) {
        return Err(Error::Setting(format!(
            "calibration: step must be in (0, 0.3] and threshold positive (got {} and {})",
            s.step, s.threshold
        )));
    }
    Ok(())
}

/// Every unknown of the nominal scenario's family must have a label column: a recording
/// simulated at the scenario's own value of an unknown, rather than at the value it was made
/// at, would bend the whisker's fit to make up the difference.
fn check_labels(loaded: &Loaded, set: &Labelled) -> Result<()> {
    let Some(family) = &loaded.family else {
        return Ok(());
    };
    let named = |u: &UnknownSpec| {
        if u.name == u.key {
            format!("`{}`", u.key)
        } else {
            format!("`{}` (named {})", u.key, u.name)
        }
    };
    let missing: Vec<String> = family
        .unknowns
        .iter()
        .filter(|u| !set.keys.contains(&u.key))
        .map(named)
        .collect();
    if missing.is_empty() {
        return Ok(());
    }
    let all: Vec<&str> = family.keys();
    Err(Error::Calibration(format!(
        "{}: no column for the unknown{} {} (the scenario's unknowns are {}; label every one, \
         one column per key, with the same value on every row where it did not vary)",
        set.dir.join(TRUTH).display(),
        if missing.len() == 1 { "" } else { "s" },
        missing.join(", "),
        all.join(", ")
    )))
}

/// The recordings as runs: the nominal scenario with each one's labels, timed like it.
fn prepare(nominal: &Document, set: &Labelled) -> Result<Vec<Run>> {
    set.recordings
        .iter()
        .map(|rec| {
            let mut scenario = nominal.loaded_with(&rec.overrides())?.scenario;
            if let Some(why) = crate::family::too_slow(rec.rate(), scenario.duration) {
                return Err(Error::Observation(format!("`{}`: {why}", rec.file)));
            }
            let n = rec.t().len();
            scenario.sample_rate = rec.rate();
            scenario.duration = (n - 1) as f64 / scenario.sample_rate;
            scenario.process_noise = 0.0;
            scenario.sensor_noise = SensorNoise::default();
            scenario.sensor_response = SensorResponse::default();
            let y = std::array::from_fn(|c| rec.channel(NAMES[c]).map(<[f64]>::to_vec));
            Ok(Run {
                file: rec.file.clone(),
                scenario,
                y,
                n,
            })
        })
        .collect()
}

/// Leaves out of each strike the channels that hold one value there from the first sample to
/// the last while they vary in another strike (a sensor that recorded nothing in that strike),
/// as a column the recording lacks is: fitted, such a channel would pull the whisker towards a
/// flat signal. Returns (strike, channel, value) for each. A channel flat in every strike is
/// [`Fit::left_out`]'s.
fn leave_out_flat(runs: &mut [Run]) -> Vec<(String, &'static str, f64)> {
    let flat = |y: &[f64]| -> Option<f64> {
        let mut values = y.iter().filter(|v| v.is_finite());
        let first = *values.next()?;
        values.all(|&v| v == first).then_some(first)
    };
    let mut out = Vec::new();
    for (c, &name) in NAMES.iter().enumerate().take(CHANNELS) {
        let varies = runs
            .iter()
            .any(|r| r.y[c].as_deref().is_some_and(|y| flat(y).is_none()));
        if !varies {
            continue;
        }
        for run in runs.iter_mut() {
            if let Some(value) = run.y[c].as_deref().and_then(flat) {
                run.y[c] = None;
                out.push((run.file.clone(), name, value));
            }
        }
    }
    out
}

/// Range (max − min) of each channel over all recordings (1 where it has no spread).
fn ranges(runs: &[Run]) -> [f64; CHANNELS] {
    std::array::from_fn(|c| {
        let (lo, hi) = runs
            .iter()
            .filter_map(|r| r.y[c].as_ref())
            .flatten()
            .filter(|v| v.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            });
        if hi > lo {
            hi - lo
        } else {
            1.0
        }
    })
}

/// One fit in rounds: fit, set every channel's noise level to its residual RMS, fit again,
/// until the levels settle (within 10%) or the rounds run out.
#[allow(clippy::too_many_arguments)]
fn fit_with_noise(
    setup: &mut Setup,
    z0: &[f64],
    resp0: &[Response; CHANNELS],
    settings: &Settings,
    ranges: &[f64; CHANNELS],
    count: &AtomicUsize,
    fits: &mut usize,
    iterations: &mut usize,
    progress: &mut dyn FnMut(&Progress),
) -> Result<Solution> {
    let (mut z, mut resp) = (z0.to_vec(), *resp0);
    let free = setup.free.iter().filter(|&&f| f).count();
    let mut round = 0;
    loop {
        round += 1;
        let stage = format!(
            "fit {}, noise round {round}, {free} whisker parameters",
            *fits + 1
        );
        let sol = search::fit(
            setup,
            &z,
            &resp,
            settings.max_iterations,
            count,
            &stage,
            progress,
        )?;
        *fits += 1;
        *iterations += sol.iterations;
        let floor: [f64; CHANNELS] = std::array::from_fn(|c| 1e-4 * ranges[c]);
        let settled = setup.reweight(&sol.sims, &sol.resp, &floor) <= 0.1;
        if settled || round >= settings.noise_rounds {
            return Ok(sol);
        }
        z = sol.z;
        resp = sol.resp;
    }
}

/// What the determination check holds next.
enum Held {
    /// A whisker parameter (its index).
    Param(usize),
    /// A channel's gain.
    Gain(usize),
}

/// The fitted quantity that is worst determined, if any is not determined, with the reason.
fn worst_undetermined(
    setup: &Setup,
    sol: &Solution,
    cov: &Covariance,
    settings: &Settings,
    reference: &Reference,
) -> Option<(Held, String)> {
    let free = setup.free_indices();
    let gains = setup.gains();
    let step = setup
        .runs
        .iter()
        .map(|r| 1.0 / r.scenario.sample_rate)
        .fold(0.0, f64::max);
    let mut worst: Option<(f64, Held, String)> = None;
    let mut consider = |badness: f64, held: Held, note: String| {
        if badness > 1.0 && worst.as_ref().is_none_or(|w| badness > w.0) {
            worst = Some((badness, held, note));
        }
    };
    // Degenerate directions: the parameter that dominates each tiny singular value.
    for &(rel, col) in &cov.weak {
        if rel < 1e-6 {
            if col < free.len() {
                consider(
                    f64::INFINITY,
                    Held::Param(free[col]),
                    "degenerate: the recordings cannot tell it from the other parameters".into(),
                );
            } else if col < free.len() + gains.len() {
                consider(
                    f64::INFINITY,
                    Held::Gain(gains[col - free.len()]),
                    "degenerate: the recordings cannot tell it from the other parameters".into(),
                );
            }
        }
    }
    // Relative standard errors.
    let sd = |j: usize| cov.cov[(j, j)].max(0.0).sqrt();
    let x = setup.full_x(&sol.z);
    for (j, &i) in free.iter().enumerate() {
        let p = &setup.params[i];
        let xi = x[i].unwrap_or(0.0);
        let (badness, note) = match p.kind {
            Kind::TimeOffset => (
                sd(j) / step,
                format!(
                    "standard error {:.3e} s is more than a sample period",
                    sd(j)
                ),
            ),
            Kind::Taper => {
                // The amount of taper, 1 − q, against its standard error (a uniform whisker
                // is the bound: determined as uniform when the error is small).
                let q = xi.exp();
                let rel = if q < 1.0 {
                    q * sd(j) / (1.0 - q)
                } else {
                    q * sd(j) / 0.05
                };
                (
                    rel / settings.threshold,
                    "the recordings do not resolve the taper: the nominal is kept".into(),
                )
            }
            Kind::FollicleCompliance if params::at_bound(p, xi) => (
                f64::INFINITY,
                "stiffer than the recordings resolve: the nominal follicle is kept".into(),
            ),
            Kind::FollicleCompliance => (
                sd(j) / settings.threshold,
                "the recordings do not resolve its compliance: the nominal follicle is kept".into(),
            ),
            _ if params::at_bound(p, xi) => (
                f64::INFINITY,
                "ran to the bound of its range: held at the nominal".into(),
            ),
            _ => (
                sd(j) / settings.threshold,
                format!(
                    "relative standard error {:.0}% above {:.0}%: held at the nominal",
                    100.0 * sd(j),
                    100.0 * settings.threshold
                ),
            ),
        };
        consider(badness, Held::Param(i), note);
    }
    for (k, &c) in gains.iter().enumerate() {
        let g = sol.resp[c].gain;
        let rel = sd(free.len() + k) / g.abs();
        consider(
            rel / settings.threshold,
            Held::Gain(c),
            format!(
                "relative standard error {:.0}%: held at the nominal",
                100.0 * rel
            ),
        );
    }
    let _ = reference;
    worst.map(|(_, h, n)| (h, n))
}

#[cfg(test)]
mod tests {
    use super::report::correlation;
    use super::starts::spread;
    use super::*;
    use nalgebra::{DMatrix, DVector};

    #[test]
    fn a_channel_flat_in_one_strike_is_left_out_of_that_strike_alone() {
        let scenario = Document::load("e2", &[])
            .unwrap()
            .loaded()
            .unwrap()
            .scenario;
        let run = |file: &str, m0: Vec<f64>, fx: Vec<f64>| Run {
            file: file.into(),
            scenario: scenario.clone(),
            y: [
                Some(vec![0.0, 1.0, 2.0]),
                Some(vec![0.0, -1.0, 0.5]),
                Some(m0),
                Some(fx),
                None,
            ],
            n: 3,
        };
        let mut runs = vec![
            run("a.csv", vec![0.0, 2.0, 1.0], vec![3.0, 3.0, 3.0]),
            run("b.csv", vec![1e30, 1e30, f64::NAN], vec![3.0, 3.0, 3.0]),
        ];
        let flat = leave_out_flat(&mut runs);
        // m0 varies in a.csv: b.csv's flat m0 goes. fx is flat in both: Fit::left_out's.
        assert_eq!(flat, vec![("b.csv".to_string(), "m0", 1e30)]);
        assert!(runs[1].y[2].is_none() && runs[0].y[2].is_some());
        assert!(runs.iter().all(|r| r.y[3].is_some()));
        assert_eq!(constant_value(&runs, 3), Some(3.0));
    }

    #[test]
    fn the_spread_of_other_minima_is_the_mean_outer_product_of_their_deviations() {
        let d = [
            DVector::from_vec(vec![1.0, 0.0]),
            DVector::from_vec(vec![-1.0, 2.0]),
        ];
        let s = spread(&d, 2);
        assert_eq!(s, DMatrix::from_row_slice(2, 2, &[1.0, -1.0, -1.0, 2.0]));
        // One other minimum a distance δ away: a standard error of δ, so two of them reach it.
        let one = spread(&[DVector::from_vec(vec![0.3])], 1);
        assert!((one[(0, 0)].sqrt() - 0.3).abs() < 1e-15);
        assert_eq!(spread(&[], 3), DMatrix::zeros(3, 3));
    }

    #[test]
    fn correlations_are_those_of_the_quantities_the_rows_derive() {
        // Coordinates with variances 4 and 1 and covariance 1: correlation 1/2.
        let cov = DMatrix::from_row_slice(2, 2, &[4.0, 1.0, 1.0, 1.0]);
        let rows = vec![
            ("a".to_string(), vec![1.0, 0.0]),
            ("b".to_string(), vec![0.0, 1.0]),
            // a − 4b: variance 4 − 8 + 16 = 12; covariance with a 4 − 4 = 0, with b 1 − 4 = −3.
            ("c".to_string(), vec![1.0, -4.0]),
            // No variance: uncorrelated.
            ("d".to_string(), vec![0.0, 0.0]),
        ];
        let c = correlation(&rows, &cov);
        assert_eq!(c.keys, ["a", "b", "c", "d"]);
        let m = &c.matrix;
        assert_eq!(m[0][1], 0.5);
        assert_eq!(m[0][2], 0.0);
        // −3/√12 = −0.8660254…
        assert_eq!(m[1][2], -0.866025);
        for (i, row) in m.iter().enumerate() {
            assert_eq!(row[i], 1.0);
            assert_eq!(row[3], if i == 3 { 1.0 } else { 0.0 });
            for (j, &r) in row.iter().enumerate() {
                assert_eq!(r, m[j][i]);
            }
        }
    }

    #[test]
    fn a_coordinate_of_infinite_variance_leaves_the_others_correlated() {
        let cov = DMatrix::from_row_slice(
            3,
            3,
            &[4.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, f64::INFINITY],
        );
        let rows = vec![
            ("a".to_string(), vec![1.0, 0.0, 0.0]),
            ("b".to_string(), vec![0.0, 1.0, 0.0]),
            ("unseen".to_string(), vec![0.0, 0.0, 1.0]),
        ];
        let c = correlation(&rows, &cov);
        assert_eq!(c.matrix[0][1], 0.5);
        assert_eq!(c.matrix[2], [0.0, 0.0, 1.0]);
        assert!(c.matrix.iter().flatten().all(|r| r.is_finite()));
    }

    #[test]
    fn no_finalist_is_refused() {
        let settings = Settings {
            finalists: 0,
            ..Settings::default()
        };
        let err = check_settings(&settings).unwrap_err().to_string();
        assert!(err.contains("finalists"), "{err}");
    }

    /// A folder of two flat recordings labelled by `truth` (its header and rows).
    fn labelled(name: &str, truth: &str, nominal: &Document) -> Labelled {
        let dir = std::env::temp_dir().join(format!(
            "vibrissa-calibrate-labels-{name}-{}",
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let rows: String = (0..20)
            .map(|k| format!("{},0,0\n", k as f64 / 1000.0))
            .collect();
        for file in ["a.csv", "b.csv"] {
            std::fs::write(dir.join(file), format!("t,theta01,theta12\n{rows}")).unwrap();
        }
        std::fs::write(dir.join(TRUTH), truth).unwrap();
        let set = vibrissa_io::labelled::read_labelled(&dir, nominal, &Default::default());
        let _ = std::fs::remove_dir_all(&dir);
        set.unwrap()
    }

    #[test]
    fn every_unknown_of_the_family_must_be_labelled() {
        let e2 = Document::load("e2", &[]).unwrap();
        let set = labelled("missing", "file,d\na.csv,0.02\nb.csv,0.025\n", &e2);
        let err = calibrate(&e2, &set, &Settings::default(), &mut |_| {})
            .expect_err("a folder without `v` is refused")
            .to_string();
        assert!(
            err.contains("truth.csv: no column for the unknown `v` (the scenario's unknowns are d, v; label every one"),
            "{err}"
        );
        let set = labelled("none", "file,whisker.length\na.csv,0.03\nb.csv,0.03\n", &e2);
        let err = check_labels(&e2.loaded().unwrap(), &set)
            .unwrap_err()
            .to_string();
        assert!(err.contains("no column for the unknowns `d`, `v`"), "{err}");
        // Every unknown labelled; and e1, whose only unknown is d.
        let set = labelled("both", "file,d,v\na.csv,0.02,0.5\nb.csv,0.025,0.8\n", &e2);
        check_labels(&e2.loaded().unwrap(), &set).unwrap();
        let e1 = Document::load("e1", &[]).unwrap();
        let set = labelled("e1", "file,d\na.csv,0.02\nb.csv,0.025\n", &e1);
        check_labels(&e1.loaded().unwrap(), &set).unwrap();
    }
}
