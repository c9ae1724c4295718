//! Estimating shapes from a batch of recordings: what `vibrissa estimate --shapes` and the
//! Python package share. The recordings' timing and sensor noise are read from them, the
//! estimator is trained once on runs of the family at that timing with that noise, and every
//! recording is estimated.

use super::bank::{CleanRuns, BANK_PER_CLASS};
use super::estimator::{ShapeEstimate, ShapeKrr};
use super::family::ShapeFamily;
use super::filter::SHAPE_PF_PARTICLES;
use super::method::{check_shape_method, fit_shape_method, needs_clean_runs};
use crate::contract::EstimateRow;
use crate::error::{Error, Result};
use crate::experiment::CHANNELS;
use crate::recording::Recording;
use std::time::Instant;

/// Training runs per class by default.
pub const DEFAULT_TRAINING: usize = 800;

/// How to train.
#[derive(Debug, Clone)]
pub struct BatchOptions {
    /// The estimator (of [`super::SHAPE_METHODS`]).
    pub method: String,
    /// Training runs per class (at least 20).
    pub training: usize,
    /// Noise-free runs per class for `shape-bank` (at least the training runs).
    pub bank: usize,
    /// Seed of the training runs.
    pub seed: u64,
    /// Train on whiskers and sensors drawn around the scenario's.
    pub randomise: bool,
    /// The sensor noise stated per channel of [`CHANNELS`] (the others are measured).
    pub stated: [Option<f64>; 5],
    /// Also keep an online estimator's posterior after every sample ([`Batch::traces`]).
    pub trace: bool,
    /// Particles per class of `shape-pf` and of `shape-mix`'s filter.
    pub particles: usize,
}

impl Default for BatchOptions {
    fn default() -> Self {
        BatchOptions {
            method: ShapeKrr::NAME.to_string(),
            training: DEFAULT_TRAINING,
            bank: BANK_PER_CLASS,
            seed: 1,
            randomise: false,
            stated: [None; 5],
            trace: false,
            particles: SHAPE_PF_PARTICLES,
        }
    }
}

/// A recording whose misfit ([`ShapeEstimate::misfit`]) exceeds this gets a warning.
pub const MISFIT_WARNING: f64 = 3.0;

/// The estimates of a batch.
#[derive(Debug, Clone)]
pub struct Batch {
    /// The estimator's name.
    pub method: String,
    /// One per recording, in order, with the seconds it took.
    pub estimates: Vec<(ShapeEstimate, f64)>,
    /// With [`BatchOptions::trace`] and an online estimator, each recording's class posterior
    /// after every sample (`[recordings][samples][classes]`); empty otherwise.
    pub traces: Vec<Vec<Vec<f64>>>,
    /// The sensor noise the training runs carried, per channel of [`CHANNELS`].
    pub noise: [f64; 5],
    /// Warnings for the user (constant channels, training runs left out).
    pub warnings: Vec<String>,
    /// Seconds spent simulating and fitting.
    pub training_seconds: f64,
    /// What the fit chose ([`super::ShapeMethod::settings`]), for the user to see.
    pub settings: Vec<(String, f64)>,
}

/// Checks a batch of recordings before any training (`[recordings][whiskers]`, `names` for
/// messages): all of one timing, and no channel flat from the first sample to the last while
/// the whisker's other channels vary (a sensor that recorded nothing, which every shape
/// estimator would read as the whisker's response). Returns warnings: a whisker whose every
/// channel is flat.
pub fn check_recordings(
    family: &ShapeFamily,
    names: &[String],
    recordings: &[Vec<Recording>],
) -> Result<Vec<String>> {
    let bad = |m: String| Error::Observation(m);
    let Some(first) = recordings.first().and_then(|r| r.first()) else {
        return Err(bad("no recording to estimate".into()));
    };
    let all: Vec<usize> = (0..CHANNELS.len()).collect();
    let (rate, samples) = (first.rate, first.t.len());
    let whiskers = family.whiskers();
    // A named whisker's columns carry its name (`c1.theta01`).
    let named = |w: usize| whiskers.get(w).filter(|n| !n.is_empty());
    let column = |w: usize, c: usize| match named(w) {
        Some(whisker) => format!("{whisker}.{}", CHANNELS[c]),
        None => CHANNELS[c].to_string(),
    };
    let mut warnings = Vec::new();
    for (name, per) in names.iter().zip(recordings) {
        for (w, r) in per.iter().enumerate() {
            if (r.rate - rate).abs() > 1e-6 * rate || r.t.len() != samples {
                return Err(bad(format!(
                    "`{name}` has {} samples at {} Hz where `{}` has {samples} at {rate} Hz: \
                     estimate recordings of one timing together",
                    r.t.len(),
                    r.rate,
                    names[0]
                )));
            }
            // A channel flat beside others that vary is a sensor that recorded nothing, and
            // every shape estimator reads every channel of every whisker: it would read the
            // flat line as the whisker's response. A whisker whose every channel is flat (one
            // that nothing touched, recorded without noise) is only worth a word.
            if let Some(&(c, value)) = r.dead_channels(&all).first() {
                return Err(bad(format!(
                    "`{name}`: column `{}` holds {value} from the first sample to the last \
                     while the whisker's other channels vary: a sensor that recorded nothing? \
                     The shape estimators read every channel of every whisker and would take \
                     it for the whisker's response; record it again, or leave this recording \
                     out",
                    column(w, c)
                )));
            }
            if r.constant_channels(&all).len() == all.len() {
                let whisker = match named(w) {
                    Some(name) => format!("whisker `{name}`"),
                    None => "the whisker".to_string(),
                };
                warnings.push(format!(
                    "`{name}`: {whisker} recorded nothing (every channel holds one value from \
                     the first sample to the last): did the object ever reach it?"
                ));
            }
        }
    }
    Ok(warnings)
}

/// Estimates every recording of `recordings` (`[recordings][whiskers]`, each recording's
/// whiskers in the family's order, all of one timing; `names` for messages).
pub fn estimate_batch(
    family: &ShapeFamily,
    names: &[String],
    recordings: &[Vec<Recording>],
    options: &BatchOptions,
) -> Result<Batch> {
    let started = Instant::now();
    let bad = |m: String| Error::Observation(m);
    let Some(first) = recordings.first().and_then(|r| r.first()) else {
        return Err(bad("no recording to estimate".into()));
    };
    check_shape_method(&options.method)?;
    if options.training < 20 {
        return Err(Error::Setting(format!(
            "training must be at least 20 runs per class (got {})",
            options.training
        )));
    }
    let all: Vec<usize> = (0..CHANNELS.len()).collect();
    let (rate, samples) = (first.rate, first.t.len());
    let mut warnings = check_recordings(family, names, recordings)?;
    let timed = family.with_timing(rate, samples)?;
    // The sensor noise: stated, or measured on every whisker of every recording.
    let series: Vec<&[Vec<f64>]> = recordings.iter().flatten().map(|r| &r.values[..]).collect();
    let measured = crate::noise::estimate_pooled(&series, &all)?;
    let sensor: [f64; 5] = std::array::from_fn(|c| options.stated[c].unwrap_or(measured[c]));
    // Training runs carry the scenario's random forces (its `process_noise`, 0 unless stated)
    // and the sensor noise that the measured level leaves beyond their response.
    let process = timed.classes()[0].family.base().process_noise;
    let noise = timed.training_noise(sensor, process)?;
    let train = timed.randomised_if(options.randomise)?;
    let draws = timed.draws(options.training, true, options.seed);
    let (runs, failed) = train.simulate_completed(&draws, &noise, options.seed ^ 0x5ea9, &|| {})?;
    warnings.extend(
        failed
            .iter()
            .map(|f| format!("a training run could not be simulated and is left out: {f}")),
    );
    let clean = if needs_clean_runs(&options.method) {
        let (clean, failed) = CleanRuns::simulate(
            &train,
            &draws,
            options.bank.max(options.training),
            options.seed,
            options.seed ^ 0x5ea9,
            &|| {},
        )?;
        warnings.extend(
            failed
                .iter()
                .map(|f| format!("a noise-free run could not be simulated and is left out: {f}")),
        );
        Some(clean)
    } else {
        None
    };
    let model = fit_shape_method(
        &options.method,
        &timed,
        &runs,
        clean.as_ref(),
        options.particles,
    )?;
    let training_seconds = started.elapsed().as_secs_f64();
    let mut traces = Vec::new();
    let estimates = recordings
        .iter()
        .map(|per| {
            let t0 = Instant::now();
            let values: Vec<Vec<Vec<f64>>> = per.iter().map(|r| r.values.clone()).collect();
            let estimate = model.predict(&values)?;
            let seconds = t0.elapsed().as_secs_f64();
            if options.trace {
                if let Some(trace) = model.trace(&values) {
                    traces.push(trace?);
                }
            }
            Ok((estimate, seconds))
        })
        .collect::<Result<Vec<_>>>()?;
    for (name, (e, _)) in names.iter().zip(&estimates) {
        if let Some(m) = e.misfit.filter(|&m| m > MISFIT_WARNING) {
            warnings.push(format!(
                "`{name}` lies {m:.1} times farther from every simulated run than simulated \
                 recordings do: the scenario does not explain it (another whisker or sensors, \
                 say); its probabilities and intervals are widened accordingly, and calibrating \
                 the whisker first (`--whisker-from`) would serve better"
            ));
        }
    }
    Ok(Batch {
        method: model.name().to_string(),
        estimates,
        traces,
        noise: sensor,
        warnings,
        training_seconds,
        settings: model.settings(),
    })
}

impl Batch {
    /// The contract's estimate object of every recording, in order (`file` named when there are
    /// several): `class`, the most probable class's unknowns, `method`, `seconds` and `noise`.
    pub fn rows(&self, names: &[String]) -> Vec<EstimateRow> {
        names
            .iter()
            .zip(&self.estimates)
            .map(|(name, (e, seconds))| EstimateRow {
                file: (names.len() > 1).then(|| name.clone()),
                class: e.class.clone(),
                estimates: e.pose.clone(),
                method: self.method.clone(),
                seconds: *seconds,
                noise: CHANNELS
                    .iter()
                    .zip(self.noise)
                    .map(|(c, x)| (c.to_string(), x))
                    .collect(),
                filter: Vec::new(),
                check: None,
                misfit: e.misfit,
            })
            .collect()
    }
}
