//! `shape-pf`: a particle filter per object class, the class chosen by marginal likelihood.
//!
//! Each class gets a filter whose particles carry that class's pose unknowns (position,
//! rotation, size, speed: static, moved at each resampling) and every read whisker's chain
//! state, stepped by the physics (a coarse chain, as the distance filter `pf`
//! steps) against the object its pose implies. One particle holds all the whiskers, so their
//! fusion is the joint posterior. The recording's marginal likelihood under each class (the
//! product over samples of the particles' mean weight) gives the class posterior after every
//! sample; the most probable class's particles give its pose.
//!
//! Nothing in the likelihood is a constant chosen on our own runs: its standard deviation per
//! channel is the residual of the filter's own model, run at the true poses of training runs,
//! against their recordings (sensor noise, random forces and the coarse chain's error together);
//! the factor it is widened by (one of [`TEMPERINGS`]), the temperature of the class posterior
//! and its floor (a share of the even split), and the widening of each class's pose intervals
//! are fitted on other training runs, held out.
//!
//! A recording that none of the classes explains as well as the held-out runs are explained
//! (another whisker's, say) reads sharper than it should: the least −2·log marginal likelihood
//! over the classes (the filters' χ², their likelihood leaving out its normalising constant) is
//! compared after every sample with its median over the held-out runs, and `r` times that
//! median (`r` > 1, the misfit) divides the class posterior's temperature, as a least-squares
//! fit scales its noise by the reduced χ². The held-out runs are scored with their own `r` when
//! the calibration and widening are fitted. How far such a reading is trusted beyond that (a
//! share of the posterior spread evenly, the pose's intervals widened by a power of `r`) is
//! learnt from noisy runs of whiskers drawn from the family's
//! randomisation prior, as `shape-bank` learns it ([`super::off_nominal`]).

mod cloud;
mod pose;
mod trust;

use super::estimator::{argmax, softmax, ClassPoses, ShapeEstimate};
use super::family::{ShapeFamily, ShapeSample};
use super::off_nominal::{self, median, misfit_ratio, Readings, Trust};
use cloud::{filter, replay, ClassModel, ClassRun, Settings, WhiskerModel};
use pose::PoseObjects;
use trust::{drawn_runs, held_posteriors, widening, HeldReading};

use crate::error::{Error, Result};
use crate::experiment::{Noise, CHANNELS};
use crate::Estimate;
use rayon::prelude::*;
use std::collections::HashMap;
use std::sync::Mutex;
use vibrissa_core::dynamics::Integrator;
use vibrissa_core::sim::BaseDrive;

/// Particles per class.
pub const SHAPE_PF_PARTICLES: usize = 1000;
/// Training runs per class that `vibrissa estimate` simulates for the filter by default: it
/// reads [`RESIDUAL_RUNS`] and [`HELD_OUT`] of them (those in the class's ranges), and the
/// training runs' margins leave some out.
pub const SHAPE_PF_TRAINING: usize = 60;
/// Training runs per class whose residuals set the likelihood's spread.
const RESIDUAL_RUNS: usize = 8;
/// Training runs per class held out to fit the class posterior's calibration and the pose
/// intervals' widening.
const HELD_OUT: usize = 10;
/// Longest step of the filter's chain, s (three per millisecond, as `pf`'s coarse model).
const MODEL_DT: f64 = 1e-3 / 3.0;
/// Factors the likelihood's spread may be widened by ([`ShapePf::fit`] chooses one on held-out
/// runs).
const TEMPERINGS: [f64; 3] = [1.0, 2.0, 4.0];
/// Largest correlation of neighbouring residuals the likelihood's spread is widened for.
const MAX_CORRELATION: f64 = 0.99;

/// The particle filter over every class's pose, the class by marginal likelihood.
pub struct ShapePf {
    classes: Vec<ClassModel>,
    set: Settings,
    whiskers: usize,
    samples: usize,
    /// How the classes' log marginal likelihoods become probabilities.
    calibration: Calibration,
    /// The factor of [`TEMPERINGS`] the likelihood's spread was widened by.
    tempering: f64,
    /// The residuals' correlation from one sample to the next, per channel.
    correlation: [f64; 5],
    /// Per class, the factor its pose's standard deviations are widened by.
    widening: Vec<f64>,
    /// After every sample, the held-out runs' median of the classes' least χ² (the misfit
    /// ratio's yardstick).
    yardstick: Vec<f64>,
    /// How far a reading at a misfit ratio above 1 is trusted ([`off_nominal`]).
    trust: Trust,
    /// `δ` of [`off_nominal`]: a pose interval widens by `r^δ`.
    widen_power: f64,
    /// The drawn whiskers' runs read to fit `trust` and `widen_power`: how many, the share named
    /// right, and their median misfit ratio (0, NaN, NaN when none could be simulated).
    off_nominal: (usize, f64, f64),
    seed: u64,
    /// Class posteriors after every sample of recordings already read, by their bits.
    traces: Mutex<HashMap<u64, Vec<Vec<f64>>>>,
}

impl ShapePf {
    /// The estimator's name.
    pub const NAME: &'static str = "shape-pf";

    /// Fits on `training` runs of `family` (its whiskers those the recordings hold): the
    /// likelihood's spread from the residuals of [`RESIDUAL_RUNS`] runs per class, the
    /// calibration and the widening from [`HELD_OUT`] others.
    pub fn fit(family: &ShapeFamily, training: &[ShapeSample]) -> Result<ShapePf> {
        Self::fit_with(family, training, SHAPE_PF_PARTICLES)
    }

    /// [`ShapePf::fit`] with `particles` per class.
    pub fn fit_with(
        family: &ShapeFamily,
        training: &[ShapeSample],
        particles: usize,
    ) -> Result<ShapePf> {
        let refuse = |detail: String| Error::Fit {
            method: Self::NAME.into(),
            detail,
        };
        if particles < 2 {
            return Err(refuse(format!(
                "needs at least 2 particles per class, not {particles}"
            )));
        }
        let rate = family.sample_rate();
        let period = 1.0 / rate;
        let substeps = (period / MODEL_DT - 1e-9).ceil().max(1.0) as usize;
        let stepper = Integrator {
            dt: period / substeps as f64,
            max_iterations: 1,
            ..Integrator::default()
        }
        .check()
        .map_err(|e| refuse(format!("integrator: {e}")))?;
        let mut classes = Vec::new();
        for class in family.classes() {
            let f = class.family.nominal();
            let pose = PoseObjects::new(&f, Self::NAME)?;
            let p0: Vec<f64> = f.ranges().iter().map(|[lo, hi]| 0.5 * (lo + hi)).collect();
            let scene = f.scenario(&p0)?;
            let mounts = f.mounts();
            let frames: Vec<_> = if mounts.is_empty() {
                vec![(scene.clone(), None)]
            } else {
                mounts
                    .into_iter()
                    .enumerate()
                    .map(|(k, m)| (m.scenario(&scene, k), Some(m)))
                    .collect()
            };
            let mut whiskers = Vec::new();
            for (s, mount) in frames {
                if !matches!(s.base, BaseDrive::Fixed) {
                    return Err(refuse(format!(
                        "class `{}`: its whiskers' bases move; the filter models whiskers whose \
                         bases stay still (read a whisked run with shape-bank or shape-esn)",
                        class.name
                    )));
                }
                let segments = crate::pf::coarse_segments(&s.whisker).min(s.segments);
                whiskers.push(WhiskerModel::new(&s, mount, segments, Self::NAME)?);
            }
            classes.push(ClassModel {
                name: class.name.clone(),
                unknowns: f.unknowns().iter().map(|s| s.to_string()).collect(),
                // The training runs' ranges (each widened by its margin), as `pf`'s prior.
                ranges: f
                    .ranges()
                    .iter()
                    .zip(f.margins())
                    .map(|([lo, hi], [below, above])| [lo - below, hi + above])
                    .collect(),
                pose,
                whiskers,
            });
        }
        let whiskers = classes[0].whiskers.len();
        let samples = family.samples();
        for (i, s) in training.iter().enumerate() {
            check_shape(&s.whiskers, whiskers, samples)
                .map_err(|e| refuse(format!("training run {i}: {e}")))?;
        }
        // Runs of each class: the first for the residuals, the next held out.
        let mut by_class: Vec<Vec<&ShapeSample>> = vec![Vec::new(); classes.len()];
        for s in training {
            by_class[s.class].push(s);
        }
        if let Some((c, runs)) = by_class.iter().enumerate().find(|(_, r)| r.len() < 4) {
            return Err(refuse(format!(
                "class `{}` has {} training runs; at least 4 are needed",
                classes[c].name,
                runs.len()
            )));
        }
        let split: Vec<usize> = by_class
            .iter()
            .map(|r| RESIDUAL_RUNS.min(r.len() / 2))
            .collect();
        let mut set = Settings {
            particles,
            stepper,
            substeps,
            period,
            sigma: [1.0; 5],
            ess_fraction: 0.5,
        };
        let (sigma, correlation) =
            residual_sigma(&classes, &set, &by_class, &split, training, samples)?;
        set.sigma = sigma;
        let mut m = ShapePf {
            classes,
            set,
            whiskers,
            samples,
            calibration: Calibration {
                temperature: 1.0,
                floor: 0.0,
            },
            tempering: 1.0,
            correlation,
            widening: Vec::new(),
            yardstick: Vec::new(),
            trust: Trust::default(),
            widen_power: 0.5,
            off_nominal: (0, f64::NAN, f64::NAN),
            seed: 0x7368_6170,
            traces: Mutex::new(HashMap::new()),
        };
        m.widening = vec![1.0; m.classes.len()];
        // Held out: runs whose poses lie in the class's ranges (the training runs' margins hold
        // poses no recording is meant to show), or any if too few do.
        let held: Vec<&ShapeSample> = by_class
            .iter()
            .zip(&split)
            .zip(family.classes())
            .flat_map(|((runs, &k), class)| {
                let ranges = class.family.ranges();
                let inside = |s: &&ShapeSample| {
                    s.params
                        .iter()
                        .zip(&ranges)
                        .all(|(x, [lo, hi])| (lo..=hi).contains(&x))
                };
                let within: Vec<&ShapeSample> = runs[k..]
                    .iter()
                    .copied()
                    .filter(inside)
                    .take(HELD_OUT)
                    .collect();
                if within.len() >= HELD_OUT.min(runs.len() - k) / 2 && !within.is_empty() {
                    within
                } else {
                    runs[k..].iter().take(HELD_OUT).copied().collect()
                }
            })
            .collect();
        // The likelihood's spread treats the model's error as independent from sample to sample
        // and its clouds degenerate under a likelihood that is too sharp: it is widened by the
        // factor of [`TEMPERINGS`] under which the held-out runs' classes are read with the
        // least log loss.
        let sigma = m.set.sigma;
        let mut best: Option<(f64, f64, HeldOutFit)> = None;
        for &t in &TEMPERINGS {
            m.set.sigma = sigma.map(|s| s * t);
            let (loss, readings) = m.calibrate(&held)?;
            if best.as_ref().is_none_or(|b| loss < b.1) {
                let fit = HeldOutFit {
                    calibration: m.calibration,
                    widening: m.widening.clone(),
                    yardstick: m.yardstick.clone(),
                    held: readings,
                };
                best = Some((t, loss, fit));
            }
        }
        if let Some((t, _, fit)) = best {
            m.tempering = t;
            m.set.sigma = sigma.map(|s| s * t);
            m.calibration = fit.calibration;
            m.widening = fit.widening;
            m.yardstick = fit.yardstick;
            m.learn_trust(family, &held, &fit.held);
        }
        Ok(m)
    }

    /// Fits the misfit's yardstick, the class posterior's calibration and each class's
    /// widening on the runs `held`; returns their classes' mean log loss and the runs as read.
    fn calibrate(&mut self, held: &[&ShapeSample]) -> Result<(f64, Vec<HeldReading>)> {
        let m = &*self;
        let runs: Vec<Vec<ClassRun>> = held
            .par_iter()
            .map(|s| m.run_all(&s.whiskers))
            .collect::<Result<_>>()?;
        let chi2: Vec<Vec<f64>> = runs.iter().map(|r| least_chi2(r)).collect();
        self.yardstick = (0..self.samples)
            .map(|k| median(&chi2.iter().map(|c| c[k]).collect::<Vec<_>>()))
            .collect();
        // Each held-out run as a recording is read, at its own misfit.
        let readings: Vec<HeldReading> = held
            .iter()
            .zip(runs)
            .map(|(s, r)| HeldReading::new(s, &self.reading(r)))
            .collect();
        let scores: Vec<Vec<f64>> = readings
            .iter()
            .map(|h| h.scores.iter().map(|s| s / h.ratio).collect())
            .collect();
        let labels: Vec<usize> = held.iter().map(|s| s.class).collect();
        let (calibration, loss) = class_calibration(&scores, &labels);
        self.widening = widening(&readings, self.classes.len(), self.widen_power);
        self.calibration = calibration;
        Ok((loss, readings))
    }

    /// How far a reading at a misfit ratio above 1 is trusted, and by what power of the ratio
    /// its pose's intervals widen: fitted on the drawn whiskers' runs ([`drawn_runs`]) at the
    /// poses of the runs `held` beside those runs as read (`own`). Every drawn run is read, or
    /// none is used (the trust then stays full and the power ½).
    fn learn_trust(&mut self, family: &ShapeFamily, held: &[&ShapeSample], own: &[HeldReading]) {
        let drawn = drawn_runs(family, held);
        if drawn.is_empty() {
            return;
        }
        let m = &*self;
        let Ok(readings) = drawn
            .par_iter()
            .map(|s| m.read(&s.whiskers))
            .collect::<Result<Vec<Reading>>>()
        else {
            return;
        };
        let own_p = held_posteriors(own, self.calibration);
        let own_truth: Vec<usize> = own.iter().map(|h| h.class).collect();
        let own_r: Vec<f64> = own.iter().map(|h| h.ratio).collect();
        let drawn_p: Vec<Vec<f64>> = readings.iter().map(|r| r.last(self.calibration)).collect();
        let drawn_truth: Vec<usize> = drawn.iter().map(|s| s.class).collect();
        let drawn_r: Vec<f64> = readings.iter().map(|r| r.misfit()).collect();
        self.trust = off_nominal::fit_trust(
            &Readings {
                probs: &own_p,
                truth: &own_truth,
                ratio: &own_r,
            },
            &Readings {
                probs: &drawn_p,
                truth: &drawn_truth,
                ratio: &drawn_r,
            },
        );
        // The pose intervals of the drawn whiskers' runs named right.
        let right: Vec<(&Reading, &ShapeSample, usize)> = readings
            .iter()
            .zip(&drawn)
            .zip(&drawn_p)
            .map(|((r, s), p)| (r, s, argmax(p)))
            .filter(|(_, s, best)| *best == s.class)
            .collect();
        let classes = self.classes.len();
        self.widen_power = off_nominal::widen_power(|power| {
            if right.len() < 2 * classes {
                return None;
            }
            let w = widening(own, classes, power);
            let (mut inside, mut all) = (0usize, 0usize);
            for (r, s, c) in &right {
                let run = &r.runs[*c];
                let scale = w[*c] * r.misfit().powf(power);
                for ((t, m), sd) in s.params.iter().zip(&run.mean).zip(&run.std) {
                    if m.is_finite() {
                        all += 1;
                        inside += usize::from((t - m).abs() <= crate::method::Z90 * sd * scale);
                    }
                }
            }
            (all > 0).then(|| inside as f64 / all as f64)
        });
        self.widening = widening(own, classes, self.widen_power);
        self.off_nominal = (
            readings.len(),
            right.len() as f64 / readings.len() as f64,
            median(&drawn_r),
        );
    }

    /// Every class's filter over one recording and its misfit ratio after every sample.
    fn read(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<Reading> {
        let runs = self.run_all(whiskers)?;
        Ok(self.reading(runs))
    }

    /// The reading of a recording whose classes' filters gave `runs`.
    fn reading(&self, runs: Vec<ClassRun>) -> Reading {
        let ratio = least_chi2(&runs)
            .iter()
            .zip(&self.yardstick)
            .map(|(&x, &y)| misfit_ratio(x, y))
            .collect();
        Reading { runs, ratio }
    }

    /// Every class's filter over one recording, the classes side by side.
    fn run_all(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<Vec<ClassRun>> {
        check_shape(whiskers, self.whiskers, self.samples)
            .map_err(|e| Error::Observation(format!("{}: {e}", Self::NAME)))?;
        self.classes
            .par_iter()
            .enumerate()
            .map(|(c, class)| {
                filter(
                    class,
                    &self.set,
                    whiskers,
                    vibrissa_core::rng::Rng::stream(self.seed, c as u64).next_u64(),
                )
            })
            .collect()
    }

    /// The class posterior and the most probable class's pose from one recording
    /// (`[whiskers][CHANNELS][samples]`).
    pub fn predict(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<ShapeEstimate> {
        Ok(self.predict_every_class(whiskers)?.0)
    }

    /// [`ShapePf::predict`] with every class's pose beside it (`[classes]`, by name).
    pub fn predict_every_class(
        &self,
        whiskers: &[Vec<Vec<f64>>],
    ) -> Result<(ShapeEstimate, ClassPoses)> {
        let reading = self.read(whiskers)?;
        let trace: Vec<Vec<f64>> = (0..self.samples)
            .map(|k| {
                let p = reading.at(k, self.calibration);
                off_nominal::trusted(&p, reading.ratio[k], self.trust)
            })
            .collect();
        let misfit = reading.misfit();
        let runs = reading.runs;
        let probabilities = trace.last().cloned().unwrap_or_default();
        self.traces
            .lock()
            .map_err(|_| Error::Observation(format!("{}: a reading failed", Self::NAME)))?
            .insert(digest(whiskers), trace);
        let best = argmax(&probabilities);
        let poses: ClassPoses = self
            .classes
            .iter()
            .zip(&runs)
            .zip(&self.widening)
            .map(|((class, run), widening)| {
                class
                    .unknowns
                    .iter()
                    .enumerate()
                    .map(|(j, name)| {
                        let [lo, hi] = class.ranges[j];
                        let (mean, std) = if run.mean[j].is_finite() {
                            (
                                run.mean[j],
                                run.std[j] * widening * misfit.powf(self.widen_power),
                            )
                        } else {
                            // No particle of the class survived: its prior.
                            (0.5 * (lo + hi), (hi - lo) / 12f64.sqrt())
                        };
                        (name.clone(), Estimate::normal(mean, std))
                    })
                    .collect()
            })
            .collect();
        let estimate = ShapeEstimate {
            class: self
                .classes
                .iter()
                .zip(&probabilities)
                .map(|(c, p)| (c.name.clone(), *p))
                .collect(),
            best,
            pose: poses[best].clone(),
            misfit: Some(misfit),
        };
        Ok((estimate, poses))
    }

    /// The class posterior after every sample (`[samples][classes]`).
    pub fn trace(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<Vec<Vec<f64>>> {
        let key = digest(whiskers);
        let known = self
            .traces
            .lock()
            .map_err(|_| Error::Observation(format!("{}: a reading failed", Self::NAME)))?
            .get(&key)
            .cloned();
        match known {
            Some(t) => Ok(t),
            None => {
                self.predict(whiskers)?;
                self.trace(whiskers)
            }
        }
    }

    /// Fitted settings worth reporting.
    pub fn settings(&self) -> Vec<(String, f64)> {
        let mut s = vec![
            ("particles".to_string(), self.set.particles as f64),
            ("temperature".to_string(), self.calibration.temperature),
            ("floor".to_string(), self.calibration.floor),
            ("tempering".to_string(), self.tempering),
            (
                "misfit_yardstick".to_string(),
                self.yardstick.last().copied().unwrap_or(f64::NAN),
            ),
            ("trust_threshold".to_string(), self.trust.threshold),
            ("trust_step".to_string(), self.trust.step),
            ("trust_power".to_string(), self.trust.power),
            ("widen_power".to_string(), self.widen_power),
            ("off_nominal_runs".to_string(), self.off_nominal.0 as f64),
            ("off_nominal_accuracy".to_string(), self.off_nominal.1),
            ("off_nominal_misfit".to_string(), self.off_nominal.2),
        ];
        for (c, x) in self.set.sigma.iter().enumerate() {
            s.push((format!("sigma_{}", CHANNELS[c]), *x));
        }
        for (c, x) in self.correlation.iter().enumerate() {
            s.push((format!("correlation_{}", CHANNELS[c]), *x));
        }
        for (class, w) in self.classes.iter().zip(&self.widening) {
            s.push((format!("widening_{}", class.name), *w));
        }
        s
    }
}

/// What [`ShapePf::calibrate`] fits on the held-out runs under one tempering, and the runs as
/// read.
struct HeldOutFit {
    calibration: Calibration,
    widening: Vec<f64>,
    yardstick: Vec<f64>,
    held: Vec<HeldReading>,
}

/// Every class's filter over one recording, before the trust in it is applied.
struct Reading {
    runs: Vec<ClassRun>,
    /// The misfit ratio after every sample.
    ratio: Vec<f64>,
}

impl Reading {
    /// The class posterior after sample `k` under `c`, at its misfit.
    fn at(&self, k: usize, c: Calibration) -> Vec<f64> {
        let scores: Vec<f64> = self.runs.iter().map(|r| r.log_z[k]).collect();
        posterior(&scores, c.at_misfit(self.ratio[k]))
    }

    /// The class posterior of the whole recording under `c`, at its misfit.
    fn last(&self, c: Calibration) -> Vec<f64> {
        posterior(&last_log_z(&self.runs), c.at_misfit(self.misfit()))
    }

    /// The whole recording's misfit ratio.
    fn misfit(&self) -> f64 {
        self.ratio.last().copied().unwrap_or(1.0)
    }
}

/// The class posterior from log marginal likelihoods under the calibration `c` (a class that
/// lost every particle gets only the floor's share; if all did, an even split).
fn posterior(scores: &[f64], c: Calibration) -> Vec<f64> {
    let even = 1.0 / scores.len() as f64;
    if scores.iter().all(|s| !s.is_finite()) {
        return vec![even; scores.len()];
    }
    softmax(scores, c.temperature)
        .into_iter()
        .map(|p| (1.0 - c.floor) * p + c.floor * even)
        .collect()
}

/// How log marginal likelihoods become class probabilities: multiplied by `temperature`
/// through a softmax, and mixed with the even split by `floor` (the share of recordings on
/// which the filters' evidence is no guide: a cloud that lost the true pose).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Calibration {
    temperature: f64,
    floor: f64,
}

impl Calibration {
    /// The calibration of a recording at misfit ratio `ratio`: its temperature divided by it.
    fn at_misfit(self, ratio: f64) -> Calibration {
        Calibration {
            temperature: self.temperature / ratio,
            ..self
        }
    }
}

/// Shares of the even split [`class_calibration`] tries.
const FLOORS: [f64; 6] = [0.0, 0.01, 0.02, 0.05, 0.1, 0.2];

/// The calibration (temperature from 1e-6 to 10 on a log grid, floor one of [`FLOORS`]) under
/// which the class posteriors of held-out runs (`scores`: their classes' log marginal
/// likelihoods; `labels`: their classes) have the least log loss, and that mean loss.
fn class_calibration(scores: &[Vec<f64>], labels: &[usize]) -> (Calibration, f64) {
    let loss = |c: Calibration| -> f64 {
        scores
            .iter()
            .zip(labels)
            .map(|(s, &l)| -posterior(s, c)[l].max(1e-300).ln())
            .sum::<f64>()
            / scores.len().max(1) as f64
    };
    let start = Calibration {
        temperature: 1.0,
        floor: 0.0,
    };
    FLOORS
        .iter()
        .flat_map(|&floor| {
            (0..=140).map(move |k| Calibration {
                temperature: 10f64.powf(-6.0 + k as f64 / 20.0),
                floor,
            })
        })
        .map(|c| (c, loss(c)))
        .fold((start, f64::INFINITY), |best, (c, l)| {
            if l < best.1 {
                (c, l)
            } else {
                best
            }
        })
}

/// Each class's log marginal likelihood of the whole recording.
fn last_log_z(runs: &[ClassRun]) -> Vec<f64> {
    runs.iter()
        .map(|r| {
            let z = r.log_z.last().copied().unwrap_or(f64::NEG_INFINITY);
            // A class that lost every particle scores far below any other.
            if z.is_finite() {
                z
            } else {
                -1e300
            }
        })
        .collect()
}

/// After every sample, the least over the classes of −2·log marginal likelihood (infinite
/// where every class lost its particles).
fn least_chi2(runs: &[ClassRun]) -> Vec<f64> {
    let samples = runs.first().map_or(0, |r| r.log_z.len());
    (0..samples)
        .map(|k| {
            let best = runs
                .iter()
                .map(|r| r.log_z[k])
                .fold(f64::NEG_INFINITY, f64::max);
            -2.0 * best
        })
        .collect()
}

/// Refuses a recording that does not hold `whiskers` whiskers of five channels of `samples`.
fn check_shape(rec: &[Vec<Vec<f64>>], whiskers: usize, samples: usize) -> Result<()> {
    if rec.len() != whiskers {
        return Err(Error::Observation(format!(
            "{} whiskers recorded where {whiskers} are read",
            rec.len()
        )));
    }
    for (w, ch) in rec.iter().enumerate() {
        if ch.len() != CHANNELS.len() || ch.iter().any(|c| c.len() != samples) {
            return Err(Error::Observation(format!(
                "whisker {w}: expected {} channels of {samples} samples",
                CHANNELS.len()
            )));
        }
    }
    Ok(())
}

/// The likelihood's standard deviation per channel: the RMS residual of the filter's model, run
/// at the true pose of the first `split[c]` training runs of each class `c`, against their
/// recordings, over every whisker and sample (at least the sensor noise the runs show), widened
/// for the residuals' correlation from one sample to the next; and that correlation.
fn residual_sigma(
    classes: &[ClassModel],
    set: &Settings,
    by_class: &[Vec<&ShapeSample>],
    split: &[usize],
    training: &[ShapeSample],
    samples: usize,
) -> Result<([f64; 5], [f64; 5])> {
    let runs: Vec<(usize, &ShapeSample)> = by_class
        .iter()
        .zip(split)
        .enumerate()
        .flat_map(|(c, (r, &k))| r[..k].iter().map(move |s| (c, *s)))
        .collect();
    // Per channel: the residuals' sum of squares, count, and sum of products of neighbours.
    let sums: Vec<[[f64; 3]; 5]> = runs
        .par_iter()
        .map(|&(c, s)| {
            let model = replay(&classes[c], set, &s.params, samples)?;
            let mut acc = [[0.0; 3]; 5];
            for (w, series) in model.iter().enumerate() {
                for (ch, a) in acc.iter_mut().enumerate() {
                    let mut last: Option<f64> = None;
                    for (k, pred) in series.iter().enumerate() {
                        let y = s.whiskers[w][ch][k];
                        if !y.is_finite() {
                            last = None;
                            continue;
                        }
                        let r = y - pred[ch];
                        a[0] += r * r;
                        a[1] += 1.0;
                        if let Some(l) = last {
                            a[2] += l * r;
                        }
                        last = Some(r);
                    }
                }
            }
            Ok(acc)
        })
        .collect::<Result<_>>()?;
    let noise = ShapeSample::measured_noise(training).unwrap_or(Noise::NONE.sensor);
    let mut sigma = [0.0; 5];
    let mut correlation = [0.0; 5];
    for ch in 0..5 {
        let [ss, n, lag] = sums.iter().fold([0.0; 3], |t, a| {
            [t[0] + a[ch][0], t[1] + a[ch][1], t[2] + a[ch][2]]
        });
        let rms = if n > 0.0 { (ss / n).sqrt() } else { 0.0 };
        let rho = if ss > 0.0 {
            (lag / ss).clamp(0.0, MAX_CORRELATION)
        } else {
            0.0
        };
        correlation[ch] = rho;
        // Residuals correlated from sample to sample (as AR(1) with coefficient `rho`) carry
        // (1 − rho)/(1 + rho) of the information of as many independent ones.
        sigma[ch] = rms.max(noise[ch]) * ((1.0 + rho) / (1.0 - rho)).sqrt();
        if !(sigma[ch].is_finite() && sigma[ch] > 0.0) {
            return Err(Error::Fit {
                method: ShapePf::NAME.into(),
                detail: format!(
                    "the channel {} shows neither noise nor a residual on the training runs",
                    CHANNELS[ch]
                ),
            });
        }
    }
    Ok((sigma, correlation))
}

/// A digest of a recording's bits.
fn digest(rec: &[Vec<Vec<f64>>]) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    for w in rec {
        for c in w {
            for x in c {
                x.to_bits().hash(&mut h);
            }
        }
    }
    h.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_misfit_is_measured_against_the_best_class_and_cools_the_posterior() {
        let run = |log_z: Vec<f64>| ClassRun {
            log_z,
            mean: vec![0.0],
            std: vec![1.0],
        };
        // The least χ² after each sample is the best class's; where every class lost its
        // particles it is infinite, and no misfit ratio can be told from it.
        let runs = [
            run(vec![-1.0, -5.0, f64::NEG_INFINITY]),
            run(vec![-2.0, -4.0, f64::NEG_INFINITY]),
        ];
        assert_eq!(least_chi2(&runs), vec![2.0, 8.0, f64::INFINITY]);
        assert_eq!(misfit_ratio(f64::INFINITY, 4.0), 1.0);
        // At misfit r the evidence counts 1/r as much: scores four apart at temperature 1/2
        // and r = 2 read as scores one apart at temperature 1; the floor stays.
        let c = Calibration {
            temperature: 0.5,
            floor: 0.1,
        };
        let far = posterior(&[0.0, -4.0], c.at_misfit(2.0));
        let near = posterior(
            &[0.0, -1.0],
            Calibration {
                temperature: 1.0,
                floor: 0.1,
            },
        );
        for (a, b) in far.iter().zip(&near) {
            assert!((a - b).abs() < 1e-12, "{far:?} {near:?}");
        }
        let plain = posterior(&[0.0, -4.0], c);
        assert!(far[0] < plain[0] && far[0] > 0.5);
    }
}
