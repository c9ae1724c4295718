//! The filter run over one whole recording, as `vibrissa estimate --method pf` and the Python
//! package's `estimate(..., method="pf")` run it: fitted to the recording's sensor noise, with
//! the object's priors and channels the caller chooses, and with what the user should be warned
//! of (a collapsed effective sample size, data that no particle explains, a posterior at an end
//! of its prior, diverged steps).

use super::gains::AngleGains;
use super::{run, Config, Injection, Observations, Pf, Posterior, Prior, TransitionModel, PARAMS};
use crate::evaluate::training_for;
use crate::recording::Recording;
use crate::{Family, Method, Result};

/// A least effective sample size below this share of the particles gets a warning.
pub const COLLAPSE_SHARE: f64 = 0.01;

/// Share of the particles drawn from an injected method's estimate.
pub const INJECT_FRACTION: f64 = 0.5;

/// Share of a prior's width within which a posterior mean counts as at its end.
pub const EDGE: f64 = 0.05;

/// Mean squared standardised residual per observation, in the units of the filter's noise model
/// before tempering, above which the recording is reported as unexplained: twice the variance
/// the model allows. Recordings of the scenario give 0.7–0.8 (own simulator and a calibrated
/// stand-in, 3% noise), another whisker described by the nominal 1.5–54. On a randomised family
/// the filter's misfit is larger even on recordings its prior describes (the sensors' unknown
/// gains cost evidence that the tempering magnifies), so there the limit is the largest misfit
/// of the held-out runs that calibrate its intervals, when that is larger
/// ([`Pf::misfit_limit`](super::Pf::misfit_limit)).
pub const MISFIT_LIMIT: f64 = 2.0;

/// Share of the particles whose steps may diverge before [`Estimate::warnings`] says so: a
/// diverged step drops its particle, as resampling drops many at every sample, and a few of
/// thousands do not move the posterior (the count is in the estimate object either way,
/// `filter.diverged_steps`).
pub const DIVERGED_SHARE: f64 = 0.01;

/// Held-out runs of a randomised family on which the filter's intervals are calibrated
/// ([`fitted`]).
pub const INTERVAL_RUNS: usize = 24;

/// Share of the held-out runs' errors that the widened 90% intervals hold.
pub const INTERVAL_QUANTILE: f64 = 0.9;

/// How the filter is run on a recording.
#[derive(Debug, Clone)]
pub struct Options {
    /// Particles, over all islands.
    pub particles: usize,
    /// Independent filters the particles are split among ([`super::islands`]).
    pub islands: usize,
    /// Islands for filtering again the recordings of a pooled batch on which its favourite
    /// whisker lost every particle ([`super::pool::refine`]; `None`: not filtered again).
    pub lost_islands: Option<usize>,
    /// Seed of the filter's random streams.
    pub seed: u64,
    /// The recording may start up to this many seconds before the approach.
    pub max_delay: f64,
    /// The transition model.
    pub model: TransitionModel,
    /// Observed channels (indices into [`crate::CHANNELS`]).
    pub channels: Vec<usize>,
    /// Priors replacing the defaults, by index into [`PARAMS`].
    pub priors: Vec<(usize, Prior)>,
    /// A discriminative method's estimates of d (and v) for this recording, whose proposals are
    /// mixed into the initial particles (hypothesis injection, [`INJECT_FRACTION`] of them).
    pub inject: Option<Vec<crate::Estimate>>,
    /// Whiskers entertained besides the scenario's on a randomised family
    /// ([`Pf::alternatives`]).
    pub alternatives: usize,
    /// Held-out runs that calibrate the intervals on a randomised family ([`fitted`]; 0: none).
    pub interval_runs: usize,
    /// The whiskers to entertain instead of the family's ([`super::Pf::whiskers`]).
    pub whiskers: Option<Vec<vibrissa_core::whisker::WhiskerParams>>,
    /// The prior of the joint angles' gains ([`Config::angle_gains`]; `None`: the scenario's
    /// gains with the filter's spread).
    pub angle_gains: Option<AngleGains>,
    /// Per recording of a batch, the prior of its joint angles' gains that pooling learnt from
    /// the others ([`super::pool::refine`]); empty when none. [`Options::for_recording`] takes
    /// it.
    pub batch_gains: Vec<AngleGains>,
    /// Whether pooling a batch also pools the joint angles' gains ([`super::gains`]; the
    /// default), or each recording learns them alone.
    pub pool_gains: bool,
}

impl Options {
    /// The defaults of `vibrissa estimate --method pf` with `particles` particles.
    pub fn new(particles: usize) -> Options {
        Options {
            particles,
            islands: super::ISLANDS,
            lost_islands: None,
            seed: 1,
            max_delay: 0.0,
            model: TransitionModel::Coarse,
            channels: (0..crate::CHANNELS.len()).collect(),
            priors: Vec::new(),
            inject: None,
            alternatives: super::ALTERNATIVES,
            interval_runs: INTERVAL_RUNS,
            whiskers: None,
            angle_gains: None,
            batch_gains: Vec::new(),
            pool_gains: true,
        }
    }

    /// These options for recording `r` of the batch: its gains' prior from
    /// [`Options::batch_gains`], where there is one.
    pub fn for_recording(&self, r: usize) -> Options {
        Options {
            angle_gains: self.batch_gains.get(r).copied().or(self.angle_gains),
            batch_gains: Vec::new(),
            ..self.clone()
        }
    }
}

/// The filter's result on one recording.
#[derive(Debug, Clone)]
pub struct Estimate {
    /// The posterior at every sample.
    pub posterior: Posterior,
    /// The settings it ran with.
    pub config: Config,
    /// The sensor noise per channel it assumed (before its model error), SI.
    pub sensor: [f64; 5],
    /// Its observation noise per channel (sensor noise and model error), SI.
    pub sigma: [f64; 5],
    /// Mean squared standardised residual per observation (see [`MISFIT_LIMIT`]).
    pub misfit: f64,
    /// The misfit above which [`Estimate::warnings`] reports the recording as unexplained
    /// ([`super::Pf::misfit_limit`]); `None` where the recording is not judged alone (a pooled
    /// batch is judged as a whole: [`super::pool::warnings`]).
    pub misfit_limit: Option<f64>,
    /// Wall time of the filtering, s.
    pub seconds: f64,
}

impl Estimate {
    /// The filter's own counts for the estimate object (`"filter"` in the contract's JSON).
    pub fn counts(&self) -> Vec<(&'static str, f64)> {
        let p = &self.posterior;
        let mut counts = vec![
            ("particles", self.config.particles as f64),
            ("islands", super::islands::island_count(&self.config) as f64),
            ("resamples", p.resamples as f64),
            ("particle_steps", p.steps as f64),
            ("diverged_steps", p.diverged as f64),
            ("refused_moves", p.refused_moves as f64),
            ("misfit", self.misfit),
        ];
        if let Some(limit) = self.misfit_limit {
            counts.push(("misfit_limit", limit));
        }
        counts
    }

    /// The posterior after the last sample, named by unknown (the object's `d`, `v`, and any
    /// further unknown the filter carried; the sensors' gains and offsets by their scenario keys,
    /// `sensors.<channel>.gain` and `.offset`, when the filter was not told them exactly; the
    /// whisker's parameters that differ between the whiskers it entertained, `whisker.<key>`).
    pub fn named(&self) -> Vec<(String, crate::Estimate)> {
        let post = &self.posterior;
        let mut named: Vec<(String, crate::Estimate)> = post
            .unknowns
            .iter()
            .map(|n| n.to_string())
            .zip(post.last().iter().copied())
            .collect();
        if let Some(s) = &post.sensors {
            for &c in &self.config.channels {
                let ch = crate::CHANNELS[c];
                named.push((format!("sensors.{ch}.gain"), s.gain[c]));
                named.push((format!("sensors.{ch}.offset"), s.offset[c]));
            }
        }
        named.extend(post.whisker.iter().map(|(k, e)| (k.to_string(), *e)));
        named
    }

    /// What the user should be warned of, each naming the recording `name`.
    pub fn warnings(&self, name: &str) -> Vec<String> {
        let (post, config) = (&self.posterior, &self.config);
        let mut out = Vec::new();
        if post.skipped > 0 {
            out.push(format!(
                "`{name}`: {} missing (NaN) values skipped",
                post.skipped
            ));
        }
        if let Some((t, ess)) = post.least_ess() {
            if ess < COLLAPSE_SHARE * config.particles as f64 {
                out.push(format!(
                    "`{name}`: the effective sample size fell to {ess:.1} of {} particles at t = \
                     {t} s; the posterior after it rests on very few particles and may be too \
                     narrow: compare with more particles or another seed",
                    config.particles
                ));
            }
        }
        if let Some(limit) = self.misfit_limit.filter(|l| self.misfit > *l) {
            out.push(format!(
                "`{name}`: no particle explains the recording: its residuals are {:.1} times the \
                 variance the filter's noise model allows (at most {limit:.1} is expected of \
                 recordings the scenario describes); the whisker, the sensors or the prior do \
                 not describe it, and the intervals may be too narrow: check the scenario \
                 (--check), calibrate it, or widen the prior; recordings made by another \
                 simulator need its chain (`segments`, `discretisation`) in the scenario or the \
                 recording's sidecar",
                self.misfit
            ));
        }
        // A posterior that piles up at an end of its prior: the truth may lie beyond it.
        for (unknown, e) in post.unknowns.iter().zip(post.last()) {
            let Some(k) = PARAMS.iter().position(|p| p == unknown) else {
                continue;
            };
            let prior = config.priors[k];
            let width = prior.hi - prior.lo;
            if width > 0.0 && (e.mean - prior.lo < EDGE * width || prior.hi - e.mean < EDGE * width)
            {
                out.push(format!(
                    "`{name}`: the posterior of {unknown} ({}) lies at an end of its prior [{}, \
                     {}]: the recording may come from outside it; widen it (--prior \
                     {unknown}=LO:HI) or check the scenario (--check)",
                    e.mean, prior.lo, prior.hi
                ));
            }
        }
        // A gain read below zero: the channel runs against the scenario's sign relative to the
        // others. Only the angles' gains are loose enough a priori to turn negative, so a wrench
        // recorded the other way shows as angles read negative too.
        if let Some(s) = &post.sensors {
            for &c in &config.channels {
                let (g, ch) = (s.gain[c], crate::CHANNELS[c]);
                if g.ci90[1] < 0.0 {
                    out.push(format!(
                        "`{name}`: the filter reads the gain of {ch} as negative ({:.2}, its 90% \
                         interval {:.2} to {:.2}): {ch} runs against the other channels as the \
                         scenario has them; is it, or the base wrench, recorded with the \
                         opposite sign? (angles are counter-clockwise positive; m0, fx and fy \
                         are what the base applies to the whisker)",
                        g.mean, g.ci90[0], g.ci90[1]
                    ));
                }
            }
        }
        if post.diverged as f64 > DIVERGED_SHARE * config.particles as f64 {
            out.push(format!(
                "`{name}`: {} particle steps diverged (those particles were dropped, of {})",
                post.diverged, config.particles
            ));
        }
        out
    }

    /// The posterior means of `family`'s own unknowns, for a model check; `None` when the
    /// posterior holds unknowns the scenario does not simulate (a start delay, a size).
    pub fn scenario_point(&self, family: &Family) -> Option<Vec<f64>> {
        let post = &self.posterior;
        if post.unknowns.len() > family.unknowns().len() {
            return None;
        }
        family
            .unknowns()
            .iter()
            .map(|k| {
                post.unknowns
                    .iter()
                    .position(|n| n == k)
                    .map(|i| post.last()[i].mean)
            })
            .collect()
    }
}

/// The filter fitted to the sensor noise `level` (per channel, SI) for `family`: its settings
/// follow `options` (particles, seed, model; priors and channels are applied per recording).
///
/// On a randomised family that calibration did not write (a whisker known only roughly), the
/// filter is then run on [`INTERVAL_RUNS`] held-out runs of the family, each with its own whisker
/// and sensors drawn from the prior and the noise `level`, and each unknown's intervals are
/// widened by the factor that makes them hold [`INTERVAL_QUANTILE`] of those runs' errors (never
/// narrowed): entertaining a few dozen whiskers, the filter alone is too sure of itself.
pub fn fitted(family: &Family, level: &[f64; 5], options: &Options) -> Result<Pf> {
    let mut filter = Pf::new(options.particles);
    filter.islands = options.islands;
    filter.set_model(options.model);
    filter.seed = options.seed;
    filter.max_delay = options.max_delay;
    filter.alternatives = options.alternatives;
    filter.whiskers = options.whiskers.clone();
    let noise = family.training_noise(*level);
    let training = training_for(family, &noise, &filter, options.seed)?;
    filter.fit(&training)?;
    if family.randomisation().is_some() && !family.is_calibrated() && options.interval_runs > 0 {
        let held_out = held_out_runs(&filter, family, &noise, options)?;
        filter.interval_scale = held_out.scale;
        filter.held_out_misfit = held_out.misfits.into_iter().reduce(f64::max);
    }
    Ok(filter)
}

/// What the held-out runs of a randomised family tell of the filter ([`held_out_runs`]).
struct HeldOut {
    /// Per unknown (by name), the factor (at least 1) that widens the 90% intervals to hold
    /// [`INTERVAL_QUANTILE`] of the runs' errors.
    scale: Vec<(String, f64)>,
    /// The filter's misfit on each run.
    misfits: Vec<f64>,
}

/// Of one held-out run: per unknown, the estimate's error and std (`None` for an unknown the
/// filter does not estimate); and the filter's misfit.
type RunErrors = (Vec<Option<(f64, f64)>>, f64);

/// The filter on `options.interval_runs` held-out runs of `family` with `noise`: each unknown's
/// widening factor and each run's misfit ([`HeldOut`]).
fn held_out_runs(
    filter: &Pf,
    family: &Family,
    noise: &crate::experiment::Noise,
    options: &Options,
) -> Result<HeldOut> {
    use rayon::prelude::*;
    let seed = options.seed ^ 0x1a7e_2f11;
    // The runs' truths lie within the filter's own priors where they narrow the family's ranges
    // (each draw placed at the same share of the prior as of the range).
    let ranges = family.ranges();
    let mut params = family.random_params(options.interval_runs, seed);
    for (u, name) in family.unknowns().iter().enumerate() {
        let Some(&(_, prior)) = options.priors.iter().find(|(k, _)| PARAMS[*k] == *name) else {
            continue;
        };
        let [lo, hi] = ranges[u];
        for p in &mut params {
            let share = if hi > lo {
                (p[u] - lo) / (hi - lo)
            } else {
                0.5
            };
            p[u] = prior.lo + share * (prior.hi - prior.lo);
        }
    }
    let runs = family.simulate_all(&params, noise, seed, &|| {})?;
    let rate = family.sample_rate();
    let names: Vec<String> = family.unknowns().iter().map(|k| k.to_string()).collect();
    // Per run and unknown, the error and std of the filter's estimate; `None` for an unknown
    // that the filter does not estimate (one a zero-width prior fixes), which is not widened.
    let per_run: Vec<RunErrors> = runs
        .par_iter()
        .map(|run| -> Result<RunErrors> {
            let t: Vec<f64> = (0..run.series[0].len()).map(|k| k as f64 / rate).collect();
            let columns = run.series.iter().cloned().map(Some).collect();
            let rec = Recording::from_columns(
                "a held-out run",
                t,
                columns,
                None,
                &options.channels,
                crate::Reader::Filter,
            )?;
            let est = estimate(filter, family, &rec, options)?;
            let post = &est.posterior;
            let pairs = names
                .iter()
                .zip(&run.params)
                .map(|(name, truth)| {
                    let i = post.unknowns.iter().position(|n| n == name)?;
                    Some((post.last()[i].mean - truth, post.last()[i].std))
                })
                .collect();
            Ok((pairs, est.misfit))
        })
        .collect::<Result<_>>()?;
    let (pairs, misfits): (Vec<_>, Vec<f64>) = per_run.into_iter().unzip();
    let scale = names
        .into_iter()
        .enumerate()
        .filter_map(|(u, name)| {
            let p: Vec<(f64, f64)> = pairs.iter().filter_map(|r| r[u]).collect();
            (!p.is_empty()).then(|| {
                (
                    name,
                    crate::features::coverage_factor_at(&p, INTERVAL_QUANTILE).max(1.0),
                )
            })
        })
        .collect();
    Ok(HeldOut { scale, misfits })
}

/// Runs the fitted `filter` (see [`fitted`]) over the recording `rec` of `family`.
pub fn estimate(
    filter: &Pf,
    family: &Family,
    rec: &Recording,
    options: &Options,
) -> Result<Estimate> {
    let unfitted = || crate::Error::Fit {
        method: "pf".into(),
        detail: "not fitted".into(),
    };
    let sigma = filter.sigma().ok_or_else(unfitted)?;
    let sensor = filter.sensor_noise().ok_or_else(unfitted)?;
    let start = std::time::Instant::now();
    let mut config = filter.config(family, sigma)?;
    config.channels = options.channels.clone();
    if let Some(n) = rec.segments {
        config.observed_segments = n;
        if filter.model == TransitionModel::Fine {
            config.segments = n;
        }
    }
    for &(k, p) in &options.priors {
        config.priors[k] = p;
    }
    if !config.sensor_spread.is_fixed() {
        config.angle_gains = options.angle_gains;
    }
    config.check()?;
    if let Some(e) = &options.inject {
        let d = e.first().copied().ok_or_else(|| crate::Error::Fit {
            method: "pf".into(),
            detail: "an injected method gave no estimate of d".into(),
        })?;
        let v = e
            .get(1)
            .copied()
            .unwrap_or(crate::Estimate::normal(config.priors[1].lo, 1.0));
        config.injection = Some(Injection {
            fraction: INJECT_FRACTION,
            mean: [d.mean, v.mean],
            std: [d.std.max(1e-5), v.std.max(1e-3)],
        });
    }
    // The filter's clock starts at the recording's first sample.
    let obs = Observations {
        t: rec.t.iter().map(|t| t - rec.t[0]).collect(),
        values: rec.values.clone(),
    };
    let mut posterior = run(&config, &obs, &mut |_| {})?;
    let misfit = filter.misfit(&posterior, config.channels.len());
    if !filter.interval_scale.is_empty() {
        posterior.widen(&filter.widening(&posterior.unknowns));
        // Widened, an interval still says nothing outside the prior the filter was given.
        posterior.within(&config.support(&posterior.unknowns));
    }
    Ok(Estimate {
        posterior,
        config,
        sensor,
        sigma,
        misfit,
        misfit_limit: Some(filter.misfit_limit()),
        seconds: start.elapsed().as_secs_f64(),
    })
}
