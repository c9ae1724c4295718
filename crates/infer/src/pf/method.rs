//! The particle filter as an estimator ([`crate::Method`]).

use super::config::{Config, Injection, Prior};
use super::islands::{run, ISLANDS};
use super::likelihood::{
    observation_sigma, temper_for, TransitionModel, FINE_TEMPER, MODEL_ERROR, UNKNOWN_START_TEMPER,
};
use super::posterior::{Observations, Posterior};
use super::recording::MISFIT_LIMIT;
use super::sensors::SensorSpread;
use crate::error::{Error, Result};
use crate::experiment::CHANNELS;
use std::sync::atomic::{AtomicU64, Ordering};
use vibrissa_core::dynamics::Integrator;

/// The least sensor noise the filter assumes, as a fraction of the `noisy` variant's level
/// (5% of each channel's range): 0.5% of the range. Clean recordings would otherwise give an
/// observation noise of 0 with the fine transition model, whose model error is not counted.
pub const SENSOR_FLOOR: f64 = 0.1;

/// The particle filter as an estimator of the experiments' unknowns ([`crate::Method`]): `pf`.
///
/// Fitting takes the sensor noise of each channel from the training data's noise (estimated
/// from the recordings, or stated: [`crate::Training::noise`]), floored at [`SENSOR_FLOOR`] of
/// the `noisy` variant's level; no training run enters the filter. Estimates are the posterior at
/// the last sample.
#[derive(Debug, Clone)]
pub struct Pf {
    /// Particles per run, over all islands.
    pub particles: usize,
    /// Independent filters the particles are split among ([`Config::islands`]).
    pub islands: usize,
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
    /// Segments of the coarse transition model's chain (`None`: the whisker's
    /// [`super::coarse_segments`]).
    pub segments: Option<usize>,
    /// Liu–West shrinkage ([`Config::shrink`]).
    pub shrink: f64,
    /// Resampling threshold ([`Config::ess_fraction`]).
    pub ess_fraction: f64,
    /// Hypothesis injection from another method's estimates (fraction of particles).
    pub inject: Option<(f64, std::sync::Arc<dyn crate::Method>)>,
    /// The transition model; set it with [`Pf::set_model`], which also sets `segments`, `dt`
    /// and `temper`.
    pub model: TransitionModel,
    /// Prior spread of the sensors' gains and offsets ([`Config::sensor_spread`]); `None`: known
    /// exactly, or [`SensorSpread::rough`] for a randomised family.
    pub sensor_spread: Option<SensorSpread>,
    /// Whiskers besides the scenario's that the filter entertains on a randomised family
    /// ([`Config::alternatives`], drawn from the family's randomisation).
    pub alternatives: usize,
    /// The whiskers to entertain on a randomised family instead of the scenario's and its
    /// drawn alternatives (the first in the scenario's place): those that pooling several
    /// recordings of one whisker settled on ([`super::pool`]). `None`: the family's.
    pub whiskers: Option<Vec<vibrissa_core::whisker::WhiskerParams>>,
    /// Unknowns (by name) whose posterior intervals are widened, and the factor of each (empty:
    /// none): set by [`super::recording::fitted`] from held-out runs of a randomised family, so
    /// that they hold on whiskers it has not seen.
    pub interval_scale: Vec<(String, f64)>,
    /// The largest misfit ([`Pf::misfit`]) of the held-out runs that set
    /// [`Pf::interval_scale`], if any were run: how far from the noise model a recording that the
    /// family's prior describes falls ([`Pf::misfit_limit`]).
    pub held_out_misfit: Option<f64>,
    /// Whether the family it was fitted to is randomised.
    randomised: bool,
    /// Whether the family it was fitted to was written by calibration.
    calibrated: bool,
    /// The calibrated family's fit residual beyond noise ([`crate::Family::fit_residual`]), which
    /// the likelihood adds to the model error in place of [`CALIBRATED_TEMPER`], when known.
    fit_residual: Option<[f64; 5]>,
    sigma: Option<[f64; 5]>,
    sensor: Option<[f64; 5]>,
    family: Option<crate::Family>,
    tally: Tally,
}

/// What the filter's runs since fitting have counted, summed over runs.
#[derive(Debug, Default)]
struct Tally {
    runs: AtomicU64,
    steps: AtomicU64,
    diverged: AtomicU64,
    refused_moves: AtomicU64,
}

impl Tally {
    fn add(&self, post: &Posterior) {
        self.runs.fetch_add(1, Ordering::Relaxed);
        self.steps.fetch_add(post.steps, Ordering::Relaxed);
        self.diverged
            .fetch_add(post.diverged as u64, Ordering::Relaxed);
        self.refused_moves
            .fetch_add(post.refused_moves as u64, Ordering::Relaxed);
    }
    fn get(&self) -> [u64; 4] {
        [&self.runs, &self.steps, &self.diverged, &self.refused_moves]
            .map(|a| a.load(Ordering::Relaxed))
    }
}

impl Clone for Tally {
    fn clone(&self) -> Tally {
        let [runs, steps, diverged, refused_moves] = self.get().map(AtomicU64::new);
        Tally {
            runs,
            steps,
            diverged,
            refused_moves,
        }
    }
}

impl std::fmt::Debug for dyn crate::Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.name())
    }
}

/// The filter's default particle count for `family`: 1000, or 4000 on a randomised family,
/// whose particles spread over [`ALTERNATIVES`] + 1 whiskers (on stand-in whiskers, 1000 left the
/// distance error half as large again as 4000).
pub fn default_particles(family: &crate::Family) -> usize {
    if family.randomisation().is_some() {
        4000
    } else {
        1000
    }
}

/// The default particle count of a filter fed one sample at a time (`vibrissa.Filter`) on a
/// scenario that calibration did not write ([`online_particles`]): it keeps up with the samples
/// on two cores even with [`ALTERNATIVES`] whiskers (`vibrissa bench --pf --randomise
/// --particles 1000,4000`: a real-time factor of 1.33–1.69 at 1000, 0.39–0.40 at 4000).
/// Filtered alone, single strikes of four stand-in whiskers and the other engine's read the
/// distance 1.28 mm on average at 1000 (1.25–1.31 mm at 1250–2000) against 1.10 mm at
/// [`default_particles`]' 4000, the speed 0.050 against 0.040 m/s, their intervals widened alike
/// and holding 80–98% of the distances (docs/filter.md, "Online: real time first").
pub const ONLINE_PARTICLES: usize = 1000;

/// The default particle count of a filter fed one sample at a time on `family`:
/// [`ONLINE_PARTICLES`], or on a calibrated family [`default_particles`], since there the
/// intervals need the particles: on the four stand-ins calibrated on their 9 labelled strikes
/// they held 75–88% of the distances at 1000 (mean 80%), 78–92% at 2000 and 88–92% at 4000.
pub fn online_particles(family: &crate::Family) -> usize {
    if family.is_calibrated() {
        default_particles(family)
    } else {
        ONLINE_PARTICLES
    }
}

/// Whiskers the filter entertains besides the scenario's on a randomised family.
pub const ALTERNATIVES: usize = 63;

/// Extra tempering of the likelihood on a randomised family: no alternative whisker is the
/// recording's, and what the nearest one misses is an error correlated in time that independent
/// noise does not describe. Chosen for 90% coverage on stand-ins 31–36 (foreign whiskers of our own
/// making: a 50-segment chain with the seed paper's stiffness rule, modulus, density, damping,
/// taper, follicle and sensors off; 20 noisy strikes each, 4000 particles, 63 alternatives):
/// coverage of d 50–65% untempered, 75–85% at 2, 80–95% at 2.5 (mean 87%), 80–100% at 3, with
/// the distance error unchanged (0.96–1.03 mm on average). Checked on stand-ins made apart from
/// it (docs/filter.md).
pub const RANDOMISED_TEMPER: f64 = 2.5;

/// Extra tempering of the likelihood on a scenario written by calibration (`[calibration]`) whose
/// record lacks the fit's residuals (`rms_after` and `noise`); with them, the residual beyond
/// noise is added to the model error per channel instead, which on 16 stand-in sets gave the
/// same distance error and coverage nearer 90% (docs/filter.md):
/// the fitted whisker is the best of the model's whiskers, not the recording's, and what it misses
/// (the fit's residual beyond the noise, and its false minima: docs/calibration.md) is an error
/// correlated in time. Chosen for 90% coverage on stand-ins 31–36, each calibrated on its 9
/// labelled strikes and filtered on 20 noisy off-grid strikes (1000 particles): coverage of d
/// 60–100% untempered (mean 83%), 70–95% at 1.2 (88%), 90–95% at 1.4 (93%), 85–100% at 1.6, with the
/// distance error unchanged (0.12–0.24 mm). Checked on stand-ins made apart from it
/// (docs/filter.md).
pub const CALIBRATED_TEMPER: f64 = 1.3;

/// `count` whiskers drawn from the randomisation `prior` around `family`'s, for the filter's
/// alternatives: the draws of its whisker alone (modulus, density, damping, follicle, taper).
/// The recording's chain and the sensors' gains, which the prior also draws for training runs,
/// are the filter's sensor unknowns instead ([`SensorSpread`]). The same family gives the same
/// whiskers.
///
/// On a calibrated family the draws come from the narrow prior
/// ([`crate::randomise::Randomisation::calibrated`]), not from the fit's own spread that its
/// training runs use: the filter holds the fitted gains, and the fit's spread given those gains
/// is under 1% in every whisker parameter but the follicle's damping, which left the filter
/// 0.25 mm biased on another engine's recordings (docs/calibration.md).
pub fn alternative_whiskers(
    family: &crate::Family,
    prior: crate::randomise::Randomisation,
    count: usize,
) -> Result<Vec<vibrissa_core::whisker::WhiskerParams>> {
    let around = crate::randomise::Around::new(family.base(), prior)?;
    Ok((0..count as u64)
        .map(|i| {
            let mut s = family.base().clone();
            around.apply(&mut s, ALTERNATIVE_SEED + i);
            s.whisker
        })
        .collect())
}

/// Seed of the first alternative whisker's draw.
const ALTERNATIVE_SEED: u64 = 0x5eed_0000;

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
            islands: ISLANDS,
            seed: 1,
            temper: temper_for(particles),
            max_delay: 0.0,
            dt: 1e-3 / 3.0,
            max_iterations: 1,
            segments: None,
            shrink: 0.98,
            ess_fraction: 0.5,
            inject: None,
            model: TransitionModel::Coarse,
            sensor_spread: None,
            alternatives: ALTERNATIVES,
            whiskers: None,
            interval_scale: Vec::new(),
            held_out_misfit: None,
            randomised: false,
            calibrated: false,
            fit_residual: None,
            sigma: None,
            sensor: None,
            family: None,
            tally: Tally::default(),
        }
    }

    /// Switches the transition model, with its segment count (the coarse model's
    /// [`super::coarse_segments`]; the fine one takes the observed chain's), time step and tempering.
    pub fn set_model(&mut self, model: TransitionModel) {
        self.model = model;
        match model {
            TransitionModel::Coarse => {
                self.segments = None;
                self.dt = 1e-3 / 3.0;
                self.temper = temper_for(self.particles);
            }
            TransitionModel::Fine => {
                self.dt = Integrator::default().dt;
                self.temper = FINE_TEMPER;
            }
        }
    }

    /// The sensor noise per channel that [`crate::Method::fit`] took (the training data's,
    /// floored at [`SENSOR_FLOOR`]), SI, if fitted.
    pub fn sensor_noise(&self) -> Option<[f64; 5]> {
        self.sensor
    }

    /// The tempering the likelihood applies: [`Pf::temper`], times [`UNKNOWN_START_TEMPER`] for
    /// the coarse model with an unknown start, and [`RANDOMISED_TEMPER`] on a randomised family
    /// or, on a calibrated scenario whose record lacks its residuals, [`CALIBRATED_TEMPER`] (with
    /// them, the fit's residual joins the model error instead: [`crate::Family::fit_residual`]).
    pub fn effective_temper(&self) -> f64 {
        let start = if self.max_delay > 0.0 && self.model == TransitionModel::Coarse {
            UNKNOWN_START_TEMPER
        } else {
            1.0
        };
        let whisker = if self.fit_residual.is_some() {
            1.0
        } else if self.calibrated {
            CALIBRATED_TEMPER
        } else if self.randomised {
            RANDOMISED_TEMPER
        } else {
            1.0
        };
        self.temper * start * whisker
    }

    /// How far no particle explained a recording: the likelihood's mean squared standardised
    /// residual per observation of `post` (on `channels` channels), in units of the noise model
    /// before tempering. About 1 or less when the model explains the recording.
    pub fn misfit(&self, post: &Posterior, channels: usize) -> f64 {
        let n = (post.trace.len() * channels).max(1) as f64;
        -2.0 * post.log_evidence / n * (self.effective_temper() * post.rate_widening).powi(2)
    }

    /// The misfit above which a recording is reported as unexplained: [`MISFIT_LIMIT`], or the
    /// largest misfit of the held-out runs ([`Pf::held_out_misfit`]) where that is larger. Of a
    /// randomised family's recordings a rank test: a recording that its prior describes exceeds
    /// all of n held-out runs with probability 1/(n + 1) (1/25 for the default
    /// [`super::recording::INTERVAL_RUNS`]).
    pub fn misfit_limit(&self) -> f64 {
        self.held_out_misfit
            .map_or(MISFIT_LIMIT, |m| m.max(MISFIT_LIMIT))
    }

    /// Per name of `unknowns`, the factor its intervals are widened by
    /// ([`Pf::interval_scale`]; 1 where none is set).
    pub fn widening(&self, unknowns: &[&str]) -> Vec<f64> {
        unknowns
            .iter()
            .map(|n| {
                self.interval_scale
                    .iter()
                    .find(|(k, _)| k == n)
                    .map_or(1.0, |(_, f)| *f)
            })
            .collect()
    }

    /// The calibrated family's fit residual beyond noise that the likelihood holds
    /// ([`crate::Family::fit_residual`]), SI per channel, if fitted to such a family.
    pub fn fit_residual(&self) -> Option<[f64; 5]> {
        self.fit_residual
    }

    /// The observation noise found by [`crate::Method::fit`], if fitted.
    pub fn sigma(&self) -> Option<[f64; 5]> {
        self.sigma
    }

    /// The filter's settings for one run of `family` with observation noise `sigma`.
    pub fn config(&self, family: &crate::Family, sigma: [f64; 5]) -> Result<Config> {
        let mut c = Config::for_family(family, sigma, self.particles, self.seed)?;
        c.islands = self.islands;
        c.dt = self.dt;
        c.max_iterations = self.max_iterations;
        c.segments = match self.model {
            TransitionModel::Coarse => self.segments.unwrap_or(c.segments),
            TransitionModel::Fine => c.observed_segments,
        };
        c.shrink = self.shrink;
        c.sensor_spread = self.sensor_spread.unwrap_or_default();
        if let Some(prior) = family.randomisation() {
            match &self.whiskers {
                Some(w) if !w.is_empty() => {
                    c.whisker = w[0].clone();
                    c.alternatives = w[1..].to_vec();
                }
                _ => c.alternatives = alternative_whiskers(family, prior, self.alternatives)?,
            }
            // A calibrated scenario's sensors and chain are fitted: only its whisker varies.
            if !family.is_calibrated() {
                c.sensor_spread = self.sensor_spread.unwrap_or_else(SensorSpread::rough);
                if self.model == TransitionModel::Coarse && self.segments.is_none() {
                    c.coarse_rule = super::config::ROUGH_RULE;
                    c.segments =
                        super::config::rough_segments(&family.base().whisker, c.coarse_rule)?;
                }
            }
        }
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
        let post = run(
            &config,
            &Observations::at_rate(obs.to_vec(), family.sample_rate()),
            &mut |_| {},
        )?;
        self.tally.add(&post);
        Ok(post)
    }

    /// Counts over the runs since the filter was fitted: `[runs, particle steps, diverged
    /// particle steps, moves undone]` (see [`Posterior`]).
    pub fn tally(&self) -> [u64; 4] {
        self.tally.get()
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
        // The `noisy` variant's levels serve as each channel's scale: the model error is
        // measured in them, and the sensor noise is floored at a fraction of them.
        let noisy = training.family.noise(crate::Variant::Noisy)?.sensor;
        let sensor: [f64; 5] = std::array::from_fn(|c| {
            let s = training.noise.sensor[c];
            if s.is_finite() {
                s.max(SENSOR_FLOOR * noisy[c])
            } else {
                noisy[c]
            }
        });
        let mut model: [f64; 5] = match self.model {
            TransitionModel::Coarse => std::array::from_fn(|c| MODEL_ERROR[c] * noisy[c]),
            TransitionModel::Fine => [0.0; 5],
        };
        self.randomised = training.family.randomisation().is_some();
        self.calibrated = training.family.is_calibrated();
        // Only a file calibration wrote has a fit residual.
        self.fit_residual = training.family.fit_residual();
        if let Some(r) = self.fit_residual {
            for (m, r) in model.iter_mut().zip(r) {
                *m = m.hypot(r);
            }
        }
        self.sigma = Some(observation_sigma(sensor, model, self.effective_temper()));
        self.sensor = Some(sensor);
        self.family = Some(training.family.clone());
        self.tally = Tally::default();
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
        if let Some(r) = self.fit_residual {
            for (c, x) in r.iter().enumerate() {
                s.push((format!("fit_residual_{}", CHANNELS[c]), *x));
            }
        }
        let [runs, steps, diverged, refused] = self.tally();
        if runs > 0 {
            s.push(("particle_steps".to_string(), steps as f64));
            s.push(("diverged_steps".to_string(), diverged as f64));
            s.push(("refused_moves".to_string(), refused as f64));
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_filter_fed_sample_by_sample_defaults_to_a_real_time_count() {
        let e2 = crate::Family::builtin("e2").unwrap();
        assert_eq!(online_particles(&e2), ONLINE_PARTICLES);
        let randomised = e2.randomised_if(true).unwrap();
        assert_eq!(default_particles(&randomised), 4000);
        assert_eq!(online_particles(&randomised), ONLINE_PARTICLES);
    }

    #[test]
    fn the_misfit_limit_is_the_held_out_runs_largest_where_that_is_larger() {
        let mut pf = Pf::new(100);
        assert_eq!(pf.misfit_limit(), MISFIT_LIMIT);
        pf.held_out_misfit = Some(1.4);
        assert_eq!(pf.misfit_limit(), MISFIT_LIMIT);
        pf.held_out_misfit = Some(2.7);
        assert_eq!(pf.misfit_limit(), 2.7);
        pf.held_out_misfit = Some(f64::NAN);
        assert_eq!(pf.misfit_limit(), MISFIT_LIMIT);
    }

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
    fn calibrated_and_randomised_families_temper_the_likelihood() {
        use crate::Method;
        let fit = |family: &crate::Family| {
            let mut pf = Pf::new(1000);
            pf.fit(&crate::Training {
                family: family.clone(),
                samples: Vec::new(),
                calibration: Vec::new(),
                noise: crate::experiment::Noise::NONE,
            })
            .unwrap();
            pf.effective_temper()
        };
        let e2 = crate::Family::builtin("e2").unwrap();
        assert!(!e2.is_calibrated());
        assert_eq!(fit(&e2), temper_for(1000));
        let fitted = "experiment = \"e2\"\n[calibration]\nlabelled = \"calib\"\nrecordings = 9\n";
        let calibrated = crate::Family::open_str(fitted, "fitted.toml", &[]).unwrap();
        assert!(calibrated.is_calibrated());
        assert_eq!(fit(&calibrated), temper_for(1000) * CALIBRATED_TEMPER);
        let rough = e2
            .randomised(crate::randomise::Randomisation::default())
            .unwrap();
        assert_eq!(fit(&rough), temper_for(1000) * RANDOMISED_TEMPER);
        let c = Pf::new(1000).config(&rough, [1.0; 5]).unwrap();
        assert_eq!(c.alternatives.len(), ALTERNATIVES);
        assert_eq!(c.segments, super::super::ROUGH_SEGMENTS[0]);
        assert_eq!(c.sensor_spread, SensorSpread::rough());
        assert!(c.alternatives.iter().all(|w| w.check().is_ok()));
        assert_ne!(c.alternatives[0], c.alternatives[1]);
        assert_eq!(default_particles(&rough), 4000);
        assert_eq!(default_particles(&e2), 1000);
        // A calibrated file randomised: whiskers from the narrow prior, its fitted sensors and
        // chain kept, the calibrated tempering.
        let narrow = calibrated.clone().randomised_if(true).unwrap();
        assert_eq!(fit(&narrow), temper_for(1000) * CALIBRATED_TEMPER);
        let c = Pf::new(1000).config(&narrow, [1.0; 5]).unwrap();
        let plain = Pf::new(1000).config(&calibrated, [1.0; 5]).unwrap();
        assert_eq!(c.alternatives.len(), ALTERNATIVES);
        assert_eq!(
            (c.segments, c.sensor_spread),
            (plain.segments, SensorSpread::default())
        );
        let e = calibrated.base().whisker.youngs_modulus;
        assert!(c
            .alternatives
            .iter()
            .all(|w| (w.youngs_modulus / e - 1.0).abs() < 0.11
                && w.follicle == vibrissa_core::whisker::Follicle::Clamped));
    }

    #[test]
    fn a_calibrated_fit_s_residual_replaces_its_tempering() {
        use crate::Method;
        let record = "experiment = \"e2\"\n[calibration]\nlabelled = \"calib\"\n\
                      recordings = 9\n[calibration.rms_after]\ntheta01 = 5e-3\nfx = 2e-5\n\
                      [calibration.noise]\ntheta01 = 3e-3\nfx = 3e-5\n";
        let fitted = crate::Family::open_str(record, "fitted.toml", &[]).unwrap();
        // √(5² − 3²) = 4 (mrad); a residual below the noise leaves nothing.
        let r = fitted.fit_residual().unwrap();
        assert!(
            (r[0] - 4e-3).abs() < 1e-15 && r[3] == 0.0 && r[1] == 0.0,
            "{r:?}"
        );
        let fit = |family: &crate::Family| {
            let mut pf = Pf::new(1000);
            let noise = crate::experiment::Noise {
                sensor: [1e-3, 1e-4, 1e-7, 1e-5, 1e-5],
                process: 0.0,
            };
            pf.fit(&crate::Training {
                family: family.clone(),
                samples: Vec::new(),
                calibration: Vec::new(),
                noise,
            })
            .unwrap();
            pf
        };
        let with = fit(&fitted);
        assert_eq!(with.effective_temper(), temper_for(1000));
        // The same file without its residuals: the fixed tempering instead.
        let bare = "experiment = \"e2\"\n[calibration]\nlabelled = \"calib\"\nrecordings = 9\n";
        let without = fit(&crate::Family::open_str(bare, "fitted.toml", &[]).unwrap());
        assert_eq!(
            without.effective_temper(),
            temper_for(1000) * CALIBRATED_TEMPER
        );
        let (a, b) = (with.sigma().unwrap(), without.sigma().unwrap());
        // Per channel: temper × √(sensor² + model² + residual²).
        let model0 = MODEL_ERROR[0] * fitted.noise(crate::Variant::Noisy).unwrap().sensor[0];
        let expect = temper_for(1000) * 1e-3f64.hypot(model0).hypot(4e-3);
        assert!((a[0] - expect).abs() < 1e-12 * expect, "{} {expect}", a[0]);
        assert!((a[1] * CALIBRATED_TEMPER - b[1]).abs() < 1e-12 * b[1]);
        // A record that names a residual without its noise is not read.
        let half = "experiment = \"e2\"\n[calibration]\n[calibration.rms_after]\ntheta01 = 5e-3\n";
        assert!(crate::Family::open_str(half, "fitted.toml", &[])
            .unwrap()
            .fit_residual()
            .is_none());
    }

    #[test]
    fn the_family_s_sensors_and_whisker_set_the_filter() {
        let pf = Pf::new(100);
        let e2 = crate::Family::builtin("e2").unwrap();
        let c = pf.config(&e2, [1.0; 5]).unwrap();
        assert_eq!(
            (c.segments, c.sensor_gain, c.sensor_offset),
            (5, [1.0; 5], [0.0; 5])
        );
        let sets = [
            "whisker.tip_radius=5e-5",
            "sensors.fx.gain=1.1",
            "sensors.m0.offset=2e-8",
        ]
        .map(String::from);
        let tapered = crate::Family::open("e2", &sets).unwrap();
        let mut c = pf.config(&tapered, [1.0; 5]).unwrap();
        assert_eq!(c.segments, 8);
        assert_eq!((c.sensor_gain[3], c.sensor_offset[2]), (1.1, 2e-8));
        c.sensor_gain[0] = 0.0;
        let e = c.check().unwrap_err().to_string();
        assert!(e.contains("theta01") && e.contains("gain"), "{e}");
        let mut fixed = Pf::new(100);
        fixed.segments = Some(6);
        assert_eq!(fixed.config(&tapered, [1.0; 5]).unwrap().segments, 6);
    }
}
