//! Scoring shape estimation: held-out runs of every class, estimated with one, three or five
//! whiskers; class accuracy, confusion, calibration of the class probabilities, and each class's
//! pose errors and interval coverage.

use super::bank::CleanRuns;
use super::family::{ShapeFamily, ShapeSample};
use super::method::{check_shape_method, fit_shape_method, needs_clean_runs};
use crate::error::{Error, Result};
use crate::experiment::Variant;
use crate::family::Family;
use rayon::prelude::*;
use serde::Serialize;
use std::time::Instant;

/// Bins of the reliability diagram (by the top class's probability).
pub const RELIABILITY_BINS: usize = 10;

/// What to run.
#[derive(Debug, Clone)]
pub struct ShapeSettings {
    /// Training runs per class (drawn over each range and its margin).
    pub train_per_class: usize,
    /// Evaluated runs per class (drawn over each range, never the training runs).
    pub eval_per_class: usize,
    /// Noise-free runs per class for estimators that weigh a bank of them (`shape-bank`; at
    /// least the training runs, whose twins it includes).
    pub bank_per_class: usize,
    /// The recordings' noise (the estimator is not told it: it measures it).
    pub variant: Variant,
    /// Seed of everything.
    pub seed: u64,
    /// Train on randomised whiskers and sensors (see [`crate::randomise`]).
    pub randomise: bool,
    /// The whisker sets to score, each by names.
    pub subsets: Vec<Vec<String>>,
    /// The estimators to score on each set (of [`super::SHAPE_METHODS`]).
    pub methods: Vec<String>,
    /// Particles per class of `shape-pf` and of `shape-mix`'s filter
    /// ([`super::SHAPE_PF_PARTICLES`] by default).
    pub particles: usize,
}

/// One unknown's scores over the correctly classified runs of a class.
#[derive(Debug, Clone, Serialize)]
pub struct PoseScore {
    /// The unknown's name.
    pub name: String,
    /// Mean absolute error, SI.
    pub mae: f64,
    /// Share of 90% intervals that hold the truth.
    pub coverage: f64,
}

/// A class's pose scores.
#[derive(Debug, Clone, Serialize)]
pub struct ClassPose {
    /// The class.
    pub class: String,
    /// Its evaluated runs.
    pub runs: usize,
    /// How many of them were classified right (the pose is scored on those).
    pub right: usize,
    /// Per unknown.
    pub unknowns: Vec<PoseScore>,
}

/// One reliability bin: runs whose top probability fell in it, their mean top probability and
/// the share of them classified right.
#[derive(Debug, Clone, Serialize)]
pub struct ReliabilityBin {
    /// Runs in the bin.
    pub runs: usize,
    /// Their mean top probability.
    pub confidence: f64,
    /// The share of them classified right.
    pub accuracy: f64,
}

/// An online estimator's class posterior after every sample of one evaluated run.
#[derive(Debug, Clone, Serialize)]
pub struct Trace {
    /// The run's index among the evaluated runs.
    pub run: usize,
    /// Its true class.
    pub class: usize,
    /// The posterior after each sample, `[samples][classes]`.
    pub probabilities: Vec<Vec<f64>>,
}

/// The scores of one estimator with one set of whiskers.
#[derive(Debug, Clone, Serialize)]
pub struct SubsetResult {
    /// The estimator.
    pub method: String,
    /// The whiskers read.
    pub whiskers: Vec<String>,
    /// Share of runs whose most probable class is the truth.
    pub accuracy: f64,
    /// `confusion[truth][estimate]`, runs.
    pub confusion: Vec<Vec<usize>>,
    /// Mean negative log probability of the true class.
    pub log_loss: f64,
    /// Expected calibration error of the top class's probability over [`RELIABILITY_BINS`].
    pub ece: f64,
    /// The reliability diagram's bins.
    pub reliability: Vec<ReliabilityBin>,
    /// Each class's pose scores.
    pub poses: Vec<ClassPose>,
    /// Every evaluated run's truth and estimate, in order.
    pub runs: Vec<RunResult>,
    /// Seconds to fit (wall time, while the other fits share the cores).
    pub fit_seconds: f64,
    /// Milliseconds per estimate (wall time, while the other fits share the cores).
    pub estimate_ms: f64,
    /// Milliseconds per recording for the class posterior after every sample, for an online
    /// estimator (wall time, as `estimate_ms`).
    pub online_ms: Option<f64>,
    /// The fitted settings.
    pub settings: Vec<(String, f64)>,
    /// For an online estimator: the posterior over time of the first evaluated run of each
    /// class.
    pub traces: Vec<Trace>,
    /// For an online estimator: the share of runs whose most probable class is the truth after
    /// each sample (the last is `accuracy`); empty otherwise.
    pub accuracy_over_time: Vec<f64>,
}

/// One evaluated run's truth and estimate.
#[derive(Debug, Clone, Serialize)]
pub struct RunResult {
    /// True class.
    pub class: usize,
    /// True values of its unknowns.
    pub params: Vec<f64>,
    /// Class probabilities, in the family's order.
    pub probabilities: Vec<f64>,
    /// The most probable class's pose: `[unknowns][mean, lo, hi]`.
    pub pose: Vec<[f64; 3]>,
    /// The estimator's misfit, where it measures one ([`super::ShapeEstimate::misfit`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub misfit: Option<f64>,
}

/// A whole shape experiment's scores.
#[derive(Debug, Clone, Serialize)]
pub struct ShapeEvaluation {
    /// The family's name.
    pub family: String,
    /// Its classes.
    pub classes: Vec<String>,
    /// Each class's unknowns.
    pub unknowns: Vec<Vec<String>>,
    /// The recordings' variant.
    pub variant: Variant,
    /// What the estimator measured of their sensor noise, `[CHANNELS]`, SI.
    pub measured_noise: [f64; 5],
    /// Training runs per class.
    pub train_per_class: usize,
    /// Evaluated runs per class.
    pub eval_per_class: usize,
    /// The recordings' sample rate, Hz.
    pub sample_rate: f64,
    /// Whether training was randomised.
    pub randomise: bool,
    /// Seconds spent simulating.
    pub simulate_seconds: f64,
    /// The runs the simulator could not complete (left out of the training or the evaluation).
    pub failed: Vec<String>,
    /// Per whisker set.
    pub subsets: Vec<SubsetResult>,
}

/// The runs `samples` read by the whiskers at `idx` of the family's array.
pub(super) fn subset(samples: &[ShapeSample], idx: &[usize]) -> Vec<ShapeSample> {
    samples
        .iter()
        .map(|s| ShapeSample {
            whiskers: idx.iter().map(|&i| s.whiskers[i].clone()).collect(),
            ..s.clone()
        })
        .collect()
}

/// The evaluated runs' classes and values: `eval_per_class` draws of each class over its range.
pub fn evaluated_draws(family: &ShapeFamily, settings: &ShapeSettings) -> Vec<(usize, Vec<f64>)> {
    family.draws(settings.eval_per_class, false, settings.seed ^ 0xe3a1)
}

/// Runs the shape experiment on `family` (every whisker simulated once; each subset reads its
/// own). `tick(done, total)` reports the simulated runs.
pub fn evaluate_shapes(
    family: &ShapeFamily,
    settings: &ShapeSettings,
    tick: &(dyn Fn(usize, usize) + Sync),
) -> Result<ShapeEvaluation> {
    let all = family.whiskers();
    if settings.methods.is_empty() {
        return Err(Error::Setting(format!(
            "no shape method to score (known: {})",
            super::SHAPE_METHODS.join(", ")
        )));
    }
    for m in &settings.methods {
        check_shape_method(m)?;
    }
    let indices: Vec<Vec<usize>> = settings
        .subsets
        .iter()
        .map(|names| {
            names
                .iter()
                .map(|n| {
                    all.iter().position(|a| a == n).ok_or_else(|| {
                        Error::Setting(format!(
                            "{}: no whisker `{n}` (its whiskers: {})",
                            family.name(),
                            all.join(", ")
                        ))
                    })
                })
                .collect::<Result<Vec<usize>>>()
        })
        .collect::<Result<_>>()?;
    // The recordings: the variant's noise is the seed experiments' (5% of each channel's range
    // over the clean e2 runs, and the random forces).
    let noise = Family::builtin("e2")?.noise(settings.variant)?;
    // Estimators that weigh a bank of noise-free runs get one, simulated once for every set.
    let bank_per_class = if settings.methods.iter().any(|m| needs_clean_runs(m)) {
        settings.bank_per_class.max(settings.train_per_class)
    } else {
        0
    };
    let total = family.classes().len()
        * (settings.train_per_class + settings.eval_per_class + bank_per_class);
    let done = std::sync::atomic::AtomicUsize::new(0);
    let step = || {
        let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        tick(d, total);
    };
    let started = Instant::now();
    let eval_draws = evaluated_draws(family, settings);
    let (evaluated, mut failed) =
        family.simulate_completed(&eval_draws, &noise, settings.seed ^ 0xe3a2, &step)?;
    // What the estimator knows of the noise: what it measures on the recordings, pooled over
    // every whisker.
    let measured = ShapeSample::measured_noise(&evaluated)?;
    let training_family = family.randomised_if(settings.randomise)?;
    let train_draws = family.draws(settings.train_per_class, true, settings.seed ^ 0xe3b1);
    // The random forces are part of the experiment's world, stated as a scenario's
    // `process_noise` would state them (as for e1 and e2); training runs carry them and the
    // sensor noise that the measured level leaves beyond their response.
    let trained_noise = family.training_noise(measured, noise.process)?;
    let (training, failed_training) = training_family.simulate_completed(
        &train_draws,
        &trained_noise,
        settings.seed ^ 0xe3b2,
        &step,
    )?;
    failed.extend(failed_training);
    let clean = if bank_per_class > 0 {
        let (clean, failed_clean) = CleanRuns::simulate(
            &training_family,
            &train_draws,
            bank_per_class,
            settings.seed ^ 0xe3b1,
            settings.seed ^ 0xe3b2,
            &step,
        )?;
        failed.extend(failed_clean);
        Some(clean)
    } else {
        None
    };
    let simulate_seconds = started.elapsed().as_secs_f64();

    let classes = family.classes().len();
    let mut jobs = Vec::new();
    for (idx, names) in indices.iter().zip(&settings.subsets) {
        for method in &settings.methods {
            jobs.push((idx, names, method));
        }
    }
    // Every (whisker set, method) is fitted and scored at once, sharing the cores: a fit that
    // runs on one core leaves the other to the next.
    let subsets = jobs
        .into_par_iter()
        .map(|(idx, names, method)| {
            let t0 = Instant::now();
            let clean = clean.as_ref().map(|c| c.subset(idx));
            // The family as the subset reads it (the whiskers it holds), for an estimator that
            // simulates runs of its own.
            let read_by =
                family.with_whiskers(&names.iter().map(String::as_str).collect::<Vec<_>>())?;
            let model = fit_shape_method(
                method,
                &read_by,
                &subset(&training, idx),
                clean.as_ref(),
                settings.particles,
            )?;
            let fit_seconds = t0.elapsed().as_secs_f64();
            let t1 = Instant::now();
            let read = subset(&evaluated, idx);
            let estimates = read
                .iter()
                .map(|s| model.predict(&s.whiskers))
                .collect::<Result<Vec<_>>>()?;
            let estimate_ms = 1e3 * t1.elapsed().as_secs_f64() / estimates.len().max(1) as f64;
            let mut confusion = vec![vec![0usize; classes]; classes];
            let mut bins = vec![(0usize, 0.0f64, 0usize); RELIABILITY_BINS];
            let mut log_loss = 0.0;
            let mut runs = Vec::with_capacity(estimates.len());
            for (s, e) in evaluated.iter().zip(&estimates) {
                confusion[s.class][e.best] += 1;
                let top = e.class[e.best].1;
                let b = ((top * RELIABILITY_BINS as f64) as usize).min(RELIABILITY_BINS - 1);
                bins[b].0 += 1;
                bins[b].1 += top;
                bins[b].2 += usize::from(e.best == s.class);
                log_loss -= e.class[s.class].1.max(1e-300).ln();
                runs.push(RunResult {
                    class: s.class,
                    params: s.params.clone(),
                    probabilities: e.class.iter().map(|c| c.1).collect(),
                    pose: e
                        .pose
                        .iter()
                        .map(|(_, p)| [p.mean, p.ci90[0], p.ci90[1]])
                        .collect(),
                    misfit: e.misfit,
                });
            }
            let n = estimates.len().max(1) as f64;
            let right: usize = (0..classes).map(|c| confusion[c][c]).sum();
            let reliability: Vec<ReliabilityBin> = bins
                .iter()
                .map(|&(k, conf, ok)| ReliabilityBin {
                    runs: k,
                    confidence: if k > 0 { conf / k as f64 } else { 0.0 },
                    accuracy: if k > 0 { ok as f64 / k as f64 } else { 0.0 },
                })
                .collect();
            let ece = reliability
                .iter()
                .map(|b| b.runs as f64 / n * (b.accuracy - b.confidence).abs())
                .sum();
            let poses = family
                .classes()
                .iter()
                .enumerate()
                .map(|(c, class)| {
                    let mine: Vec<(&ShapeSample, &super::ShapeEstimate)> = evaluated
                        .iter()
                        .zip(&estimates)
                        .filter(|(s, _)| s.class == c)
                        .collect();
                    let ok: Vec<_> = mine.iter().filter(|(_, e)| e.best == c).collect();
                    let unknowns = class
                        .family
                        .unknowns()
                        .iter()
                        .enumerate()
                        .map(|(u, name)| {
                            let k = ok.len().max(1) as f64;
                            PoseScore {
                                name: name.to_string(),
                                mae: ok
                                    .iter()
                                    .map(|(s, e)| (e.pose[u].1.mean - s.params[u]).abs())
                                    .sum::<f64>()
                                    / k,
                                coverage: ok
                                    .iter()
                                    .filter(|(s, e)| e.pose[u].1.covers(s.params[u]))
                                    .count() as f64
                                    / k,
                            }
                        })
                        .collect();
                    ClassPose {
                        class: class.name.clone(),
                        runs: mine.len(),
                        right: ok.len(),
                        unknowns,
                    }
                })
                .collect();
            // An online estimator: the share of runs whose most probable class is the truth
            // after every sample, and the first evaluated run of each class's posterior.
            let mut accuracy_over_time = Vec::new();
            let mut traces = Vec::new();
            // (`None` for an estimator that reads the recording whole.)
            let t2 = Instant::now();
            let online = read
                .iter()
                .map(|s| model.trace(&s.whiskers))
                .collect::<Option<Vec<_>>>()
                .map(|t| t.into_iter().collect::<Result<Vec<_>>>())
                .transpose()?;
            let online_ms = online
                .as_ref()
                .map(|_| 1e3 * t2.elapsed().as_secs_f64() / read.len().max(1) as f64);
            if let Some(all) = online {
                let samples = all.iter().map(Vec::len).min().unwrap_or(0);
                accuracy_over_time = (0..samples)
                    .map(|k| {
                        read.iter()
                            .zip(&all)
                            .filter(|(s, p)| {
                                let p = &p[k];
                                (0..p.len()).fold(0, |b, c| if p[c] > p[b] { c } else { b })
                                    == s.class
                            })
                            .count() as f64
                            / n
                    })
                    .collect();
                for c in 0..classes {
                    if let Some(k) = read.iter().position(|s| s.class == c) {
                        traces.push(Trace {
                            run: k,
                            class: c,
                            probabilities: all[k].clone(),
                        });
                    }
                }
            }
            Ok(SubsetResult {
                method: model.name().to_string(),
                whiskers: names.clone(),
                accuracy: right as f64 / n,
                confusion,
                log_loss: log_loss / n,
                ece,
                reliability,
                poses,
                runs,
                fit_seconds,
                estimate_ms,
                online_ms,
                settings: model.settings(),
                traces,
                accuracy_over_time,
            })
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(ShapeEvaluation {
        family: family.name().to_string(),
        classes: family.class_names().iter().map(|s| s.to_string()).collect(),
        unknowns: family.unknown_names(),
        variant: settings.variant,
        measured_noise: measured,
        train_per_class: settings.train_per_class,
        eval_per_class: settings.eval_per_class,
        sample_rate: family.sample_rate(),
        randomise: settings.randomise,
        simulate_seconds,
        failed,
        subsets,
    })
}
