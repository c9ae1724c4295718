//! The fit of a [`ShapeBank`], stage by stage:
//!
//! 1. the runs are checked and each training run paired with its noise-free twin;
//! 2. the noise: each channel's level, then its covariance over a whisker's series;
//! 3. the principal axes of the whitened bank, and every bank run projected onto them;
//! 4. the held-out training runs scored against the bank without their twins;
//! 5. the class posterior calibrated on them: the fit between runs, then the search with the
//!    simulator, each kept where it lowers their log loss;
//! 6. their misfits, the pose (temperature, which estimate) and its intervals;
//! 7. the reference of the posterior after every sample;
//! 8. the trust in far recordings, learnt from noisy runs of drawn whiskers.

use super::{
    folded, median, misfit_ratio, nearest, whiten_runs, CleanRuns, Reading, ShapeBank, CHUNK,
    COMPONENTS, HOLD, NEIGHBOURS, NOISE_FLOOR, NOISE_SERIES, OFF_NOMINAL_PER_CLASS,
    OFF_NOMINAL_SEED, PCA_RUNS, REFINE_CLASSES, REFINE_HELD, TRACE_HELD,
};
use crate::error::{Error, Result};
use crate::experiment::{Noise, CHANNELS};
use crate::methods::kernel_ridge::Pca;
use crate::shapes::between::Between;
use crate::shapes::estimator::conformal_half_width;
use crate::shapes::family::{ShapeFamily, ShapeSample};
use crate::shapes::off_nominal::{self, Readings, Trust};
use crate::shapes::refine::Refined;
use crate::shapes::series_noise::SeriesNoise;
use nalgebra::DMatrix;
use rayon::prelude::*;
use std::collections::HashMap;

/// Temperatures tried: powers of √2 from 2^-4 to 2^28 (the squared distances are in units of
/// the noise, so a clean recording's are enormous).
pub(super) fn temperatures() -> impl Iterator<Item = f64> {
    (0..=64).map(|k| 2f64.powf(0.5 * k as f64 - 4.0))
}

/// Factors of the log evidence in the class softmax tried: powers of √2 from 2^-16 to 2^4.
fn sharpnesses() -> impl Iterator<Item = f64> {
    (0..=40).map(|k| 2f64.powf(0.5 * k as f64 - 16.0))
}

/// Shares of the class posterior spread evenly tried: 0 to 0.5 in steps of 0.02.
fn floors() -> impl Iterator<Item = f64> {
    (0..=25).map(|k| 0.02 * k as f64)
}

/// Settings chosen on the held-out runs by [`ShapeBank::calibrate`].
#[derive(Debug, Clone, Copy)]
struct Calibration {
    /// The held-out runs' mean log loss at these settings.
    loss: f64,
    temperature: f64,
    sharpness: f64,
    floor: f64,
    /// The held-out runs' median squared distance to their nearest run.
    misfit: f64,
}

/// The temperature, sharpness and even share (at least `least_floor`) with the lowest mean
/// log loss over `classes` classes of the held-out runs with log evidence `evidence`
/// (`[runs][temperatures][classes]`) and true classes `truth`: `(loss, t, s, e)`.
pub(super) fn least_loss(
    classes: usize,
    evidence: &[Vec<Vec<f64>>],
    truth: &[usize],
    least_floor: f64,
) -> (f64, f64, f64, f64) {
    let fits: Vec<(f64, f64, f64, f64)> = temperatures()
        .enumerate()
        .collect::<Vec<_>>()
        .par_iter()
        .map(|&(k, t)| {
            let mut best = (f64::INFINITY, t, 1.0, least_floor);
            for s in sharpnesses() {
                let soft: Vec<Vec<f64>> =
                    evidence.iter().map(|l| super::softmax(&l[k], s)).collect();
                for e in floors().filter(|&e| e >= least_floor) {
                    let loss: f64 = soft
                        .iter()
                        .zip(truth)
                        .map(|(p, &c)| -((1.0 - e) * p[c] + e / classes as f64).max(1e-300).ln())
                        .sum::<f64>()
                        / evidence.len() as f64;
                    if loss < best.0 {
                        best = (loss, t, s, e);
                    }
                }
            }
            best
        })
        .collect();
    fits.into_iter()
        .fold((f64::INFINITY, 1.0, 1.0, least_floor), |a, b| {
            if b.0 < a.0 {
                b
            } else {
                a
            }
        })
}

/// An error of the fit, `detail` saying what was wrong.
fn fit_error(detail: String) -> Error {
    Error::Fit {
        method: ShapeBank::NAME.into(),
        detail,
    }
}

/// The whiskers and samples per channel of the training runs, checked against every run of
/// the training set and of the bank.
fn run_shape(training: &[ShapeSample], bank: &[&ShapeSample]) -> Result<(usize, usize)> {
    let first = training
        .first()
        .ok_or_else(|| fit_error("no training runs".into()))?;
    let whiskers = first.whiskers.len();
    let samples = first
        .whiskers
        .first()
        .and_then(|w| w.first())
        .map_or(0, Vec::len);
    for s in training.iter().chain(bank.iter().copied()) {
        if s.whiskers.len() != whiskers
            || s.whiskers
                .iter()
                .any(|w| w.len() != CHANNELS.len() || w.iter().any(|c| c.len() != samples))
        {
            return Err(fit_error(format!(
                "every run must have {whiskers} whiskers of {} channels of {samples} samples",
                CHANNELS.len()
            )));
        }
    }
    Ok((whiskers, samples))
}

/// The bank's runs per class, each at least one.
fn class_counts(bank: &[&ShapeSample], classes: usize) -> Result<Vec<usize>> {
    let mut counts = vec![0usize; classes];
    for s in bank {
        counts[s.class] += 1;
    }
    if counts.contains(&0) {
        return Err(fit_error("the bank lacks a class".into()));
    }
    Ok(counts)
}

/// `(training run, its twin among clean.twins)`, by class and pose; at least 20 of them.
fn twin_pairs(training: &[ShapeSample], clean: &CleanRuns) -> Result<Vec<(usize, usize)>> {
    let key = |s: &ShapeSample| -> (usize, Vec<u64>) {
        (s.class, s.params.iter().map(|p| p.to_bits()).collect())
    };
    let twin_of: HashMap<(usize, Vec<u64>), usize> = clean
        .twins
        .iter()
        .enumerate()
        .map(|(i, s)| (key(s), i))
        .collect();
    let pairs: Vec<(usize, usize)> = training
        .iter()
        .enumerate()
        .filter_map(|(j, s)| twin_of.get(&key(s)).map(|&i| (j, i)))
        .collect();
    if pairs.len() < 20 {
        return Err(fit_error(format!(
            "only {} training runs have a noise-free twin (at least 20 needed)",
            pairs.len()
        )));
    }
    Ok(pairs)
}

/// The noise the world adds, per channel: the RMS of the training runs' residuals against
/// their twins, at least [`NOISE_FLOOR`] of the channel's median RMS over the bank.
fn channel_noise(
    training: &[ShapeSample],
    bank: &[&ShapeSample],
    pairs: &[(usize, usize)],
    samples: usize,
) -> Result<[f64; 5]> {
    let mut sigma = [0.0; 5];
    for (c, s) in sigma.iter_mut().enumerate() {
        let (mut sum, mut n) = (0.0, 0usize);
        for &(j, i) in pairs {
            for (wn, wc) in training[j].whiskers.iter().zip(&bank[i].whiskers) {
                for (a, b) in wn[c].iter().zip(&wc[c]) {
                    sum += (a - b) * (a - b);
                    n += 1;
                }
            }
        }
        let mut rms: Vec<f64> = bank
            .iter()
            .step_by(bank.len().div_ceil(500).max(1))
            .flat_map(|s| {
                s.whiskers.iter().map(move |w| {
                    (w[c].iter().map(|x| x * x).sum::<f64>() / samples.max(1) as f64).sqrt()
                })
            })
            .collect();
        rms.sort_by(|a, b| a.total_cmp(b));
        let floor = NOISE_FLOOR * rms[rms.len() / 2];
        *s = (sum / n.max(1) as f64).sqrt().max(floor);
        if !(s.is_finite() && *s > 0.0) {
            return Err(fit_error(format!(
                "channel {} is zero on every run of the bank",
                CHANNELS[c]
            )));
        }
    }
    Ok(sigma)
}

/// The noise's covariance over one whisker's series (every whisker's alike, pooled), from the
/// residuals against their twins of the training runs never scored as held out (every
/// [`HOLD`]-th pair is). A covariance read on the very residuals it whitens makes them look
/// smaller than a recording's: with a few thousand series of a thousand samples each, the
/// held-out runs' misfit came out at about half a fresh run's, and every recording of the
/// bank's own whisker seemed far from it.
fn noise_covariance(
    training: &[ShapeSample],
    bank: &[&ShapeSample],
    pairs: &[(usize, usize)],
    sigma: &[f64; 5],
    whiskers: usize,
    samples: usize,
) -> Result<SeriesNoise> {
    let fitting: Vec<(usize, usize)> = pairs
        .iter()
        .enumerate()
        .filter(|(n, _)| n % HOLD != 0)
        .map(|(_, &p)| p)
        .collect();
    let block = CHANNELS.len() * samples;
    let pair_step = (fitting.len() * whiskers).div_ceil(NOISE_SERIES).max(1);
    let used: Vec<(usize, usize)> = fitting.iter().copied().step_by(pair_step).collect();
    let residuals = DMatrix::from_fn(used.len() * whiskers, block, |row, col| {
        let (j, i) = used[row / whiskers];
        let w = row % whiskers;
        let (t, c) = (col / CHANNELS.len(), col % CHANNELS.len());
        (training[j].whiskers[w][c][t] - bank[i].whiskers[w][c][t]) / sigma[c]
    });
    SeriesNoise::fit(&residuals, CHANNELS.len())
        .ok_or_else(|| fit_error("the noise's covariance is not positive definite".into()))
}

/// The training runs scored as held out (each against the bank without its own twin), and
/// what the stages of the fit make of them.
struct Held<'a> {
    /// The training runs.
    training: &'a [ShapeSample],
    /// `(training run, its twin in the bank)` of each held-out run.
    pairs: Vec<(usize, usize)>,
    /// Their components.
    z: Vec<Vec<f64>>,
    /// Their squared distances to the bank's runs (infinite to their twins).
    d2: Vec<Vec<f64>>,
    /// Their classes.
    truth: Vec<usize>,
    /// Each class's fit between its runs, per held-out run.
    between: Vec<Vec<Option<Between>>>,
    /// The held-out runs searched with the simulator, and the search's result per class (empty
    /// when the search was not kept).
    searched: Vec<usize>,
    refined: Vec<Vec<Option<Refined>>>,
    /// Squared distances to each class's one more run (the fit between runs' or the search's),
    /// as the estimator would use them, and the misfit ratios they give.
    extra: Vec<Vec<f64>>,
    ratio: Vec<f64>,
}

impl Held<'_> {
    /// Held-out run `r`'s training run.
    fn run(&self, r: usize) -> &ShapeSample {
        &self.training[self.pairs[r].0]
    }

    /// How many there are.
    fn len(&self) -> usize {
        self.pairs.len()
    }
}

impl ShapeBank {
    /// Fits on the noisy `training` runs of `family` and the noise-free `clean` runs (whose
    /// twins are the training runs' poses).
    pub fn fit(family: &ShapeFamily, training: &[ShapeSample], clean: &CleanRuns) -> Result<Self> {
        Self::fit_with(family, training, clean, None)
    }

    /// [`ShapeBank::fit`], with `drawn` the noise-free runs of other whiskers that the trust
    /// in a reading is fitted on (when `None`, [`OFF_NOMINAL_PER_CLASS`] runs per class of
    /// whiskers drawn from the family's randomisation prior, when the bank can simulate).
    pub(super) fn fit_with(
        family: &ShapeFamily,
        training: &[ShapeSample],
        clean: &CleanRuns,
        drawn: Option<Vec<ShapeSample>>,
    ) -> Result<Self> {
        let bank: Vec<&ShapeSample> = clean.twins.iter().chain(&clean.extra).collect();
        let (whiskers, samples) = run_shape(training, &bank)?;
        let counts = class_counts(&bank, family.classes().len())?;
        let pairs = twin_pairs(training, clean)?;
        let sigma = channel_noise(training, &bank, &pairs, samples)?;
        let noise = noise_covariance(training, &bank, &pairs, &sigma, whiskers, samples)?;
        let mut m = Self::projected(family, &bank, sigma, noise, counts, whiskers, samples);
        let mut held = m.held_out(training, &pairs)?;
        m.calibrate_between(&mut held);
        m.calibrate_search(&mut held);
        m.held_misfits(&mut held);
        let poses = m.fit_pose(&held);
        let traced: Vec<(&ShapeSample, usize)> = held
            .pairs
            .iter()
            .step_by(held.len().div_ceil(TRACE_HELD).max(1))
            .map(|&(j, i)| (&training[j], i))
            .collect();
        m.misfit_trace = m.trace_misfit(&traced);
        m.half_width = m.half_widths(&held, &poses, m.widen_power);
        let drawn = drawn.unwrap_or_else(|| m.drawn_runs());
        m.learn_trust(&held, &poses, &bank, &drawn);
        Ok(m)
    }

    /// The bank before anything is calibrated: the principal axes of the whitened series of a
    /// subset of the `bank`'s runs, every run projected onto them and whitened in full.
    fn projected(
        family: &ShapeFamily,
        bank: &[&ShapeSample],
        sigma: [f64; 5],
        noise: SeriesNoise,
        counts: Vec<usize>,
        whiskers: usize,
        samples: usize,
    ) -> ShapeBank {
        let step = bank.len().div_ceil(PCA_RUNS).max(1);
        let sub_runs: Vec<&ShapeSample> = bank.iter().copied().step_by(step).collect();
        let sub = whiten_runs(&sub_runs, &sigma, &noise);
        let components = COMPONENTS.min(sub.len().saturating_sub(1)).max(1);
        let pca = Pca::fit(&sub, components);
        drop(sub);
        let (fold, offset) = folded(&pca, &noise, whiskers);
        let mut m = ShapeBank {
            classes: family.class_names().iter().map(|s| s.to_string()).collect(),
            names: family.unknown_names(),
            whiskers,
            samples,
            sigma,
            noise,
            components: pca.axes.len(),
            fold,
            offset,
            whitened: Vec::new(),
            class_of: bank.iter().map(|s| s.class).collect(),
            params: bank.iter().map(|s| s.params.clone()).collect(),
            z: Vec::new(),
            counts,
            neighbours: 0,
            pose_between: false,
            family: (family.whiskers().len() == whiskers && family.samples() == samples)
                .then(|| family.clone()),
            ranges: family.classes().iter().map(|c| c.family.ranges()).collect(),
            refine_classes: 0,
            pose_refined: false,
            refine_runs: 0.0,
            temperature: 1.0,
            sharpness: 1.0,
            floor: 0.0,
            held_out_loss: f64::NAN,
            misfit: f64::NAN,
            misfit_trace: Vec::new(),
            pose_temperature: 1.0,
            half_width: Vec::new(),
            trust: Trust::default(),
            widen_power: 0.5,
            off_nominal: (0, f64::NAN, f64::NAN),
        };
        m.z = m.project_all(bank);
        m.whitened = bank
            .par_chunks(CHUNK)
            .flat_map_iter(|runs| {
                whiten_runs(runs, &m.sigma, &m.noise)
                    .into_iter()
                    .flat_map(|u| u.into_iter().map(|x| x as f32))
            })
            .collect();
        m
    }

    /// Every [`HOLD`]-th training run of `pairs` whose pose lies in its class's ranges, scored
    /// against the bank without its own twin. (The ranges are the recordings' prior; the
    /// training draws' margins reach beyond it, where runs are rarer in the bank and often
    /// barely touched, so that probabilities calibrated on them would be too timid.)
    fn held_out<'a>(
        &self,
        training: &'a [ShapeSample],
        pairs: &[(usize, usize)],
    ) -> Result<Held<'a>> {
        let inside = |s: &ShapeSample| {
            s.params
                .iter()
                .zip(&self.ranges[s.class])
                .all(|(x, [lo, hi])| (lo..=hi).contains(&x))
        };
        let held: Vec<(usize, usize)> = pairs
            .iter()
            .copied()
            .step_by(HOLD)
            .filter(|&(j, _)| inside(&training[j]))
            .collect();
        let classes = self.classes.len();
        if held.len() < 8 * classes {
            return Err(fit_error(format!(
                "only {} held-out training runs lie in the classes' ranges (at least {} needed)",
                held.len(),
                8 * classes
            )));
        }
        let z = self.project_all(&held.iter().map(|&(j, _)| &training[j]).collect::<Vec<_>>());
        let d2: Vec<Vec<f64>> = z
            .par_iter()
            .zip(&held)
            .map(|(z, &(_, twin))| {
                let mut d = self.distances(z);
                d[twin] = f64::INFINITY;
                d
            })
            .collect();
        let truth = held.iter().map(|&(j, _)| training[j].class).collect();
        Ok(Held {
            training,
            pairs: held,
            z,
            d2,
            truth,
            between: Vec::new(),
            searched: Vec::new(),
            refined: Vec::new(),
            extra: Vec::new(),
            ratio: Vec::new(),
        })
    }

    /// The class evidence's temperature, the sharpness of its softmax and the share of every
    /// posterior spread evenly over the classes: the three whose held-out log loss is lowest.
    /// (A single temperature would have to be high to calibrate, and a high one favours the
    /// class with the fewest unknowns, whose bank is densest near any recording; without the
    /// even share, the few runs whose nearest bank runs are of another class, confidently named
    /// wrong, would force every posterior to be timid.)
    ///
    /// Each number of neighbours for the fit between runs is tried alike (0: the bank alone),
    /// and the one with the lowest held-out log loss kept.
    fn calibrate_between(&mut self, held: &mut Held) {
        let mut chosen: Option<(Calibration, usize)> = None;
        for k in NEIGHBOURS {
            let fitted: Vec<Vec<Option<Between>>> = held
                .d2
                .par_iter()
                .zip(&held.z)
                .map(|(d, z)| self.between_all(z, d, k))
                .collect();
            let extra: Vec<Vec<f64>> = fitted.iter().map(|b| Self::between_d2(b)).collect();
            let best = self.calibrate(&held.d2, &extra, &held.truth);
            if chosen.as_ref().is_none_or(|(c, _)| best.loss < c.loss) {
                chosen = Some((best, k));
                held.between = fitted;
            }
        }
        if let Some((c, k)) = chosen {
            self.set_calibration(&c);
            self.neighbours = k;
        }
    }

    /// The search for each class's nearest run with the simulator, tried on a subset of the
    /// held-out runs: kept, with its own temperature, sharpness and even share, when its log
    /// loss there is lower than the bank's (and fit between runs') on the same runs.
    fn calibrate_search(&mut self, held: &mut Held) {
        held.searched = (0..held.len())
            .step_by(held.len().div_ceil(REFINE_HELD).max(1))
            .collect();
        if self.family.is_none() {
            return;
        }
        let searched = &held.searched;
        let refined: Vec<Vec<Option<Refined>>> = searched
            .par_iter()
            .map(|&r| self.refined_all(&held.z[r], &held.d2[r], &held.between[r], REFINE_CLASSES))
            .collect();
        let d2_sub: Vec<Vec<f64>> = searched.iter().map(|&r| held.d2[r].clone()).collect();
        let truth_sub: Vec<usize> = searched.iter().map(|&r| held.truth[r]).collect();
        let plain: Vec<Vec<f64>> = searched
            .iter()
            .map(|&r| Self::between_d2(&held.between[r]))
            .collect();
        let with: Vec<Vec<f64>> = searched
            .iter()
            .zip(&refined)
            .map(|(&r, f)| Self::extra_d2(&held.between[r], f))
            .collect();
        let before = self.calibrate(&d2_sub, &plain, &truth_sub);
        let after = self.calibrate(&d2_sub, &with, &truth_sub);
        let runs: usize = refined.iter().flatten().flatten().map(|f| f.runs).sum();
        self.refine_runs = runs as f64 / searched.len().max(1) as f64;
        if after.loss < before.loss {
            self.set_calibration(&after);
            self.refine_classes = REFINE_CLASSES;
            held.refined = refined;
        }
    }

    /// Each held-out run's one more run per class as the estimator would use it (the search's
    /// where it searched, else the fit between runs'), and its misfit ratio.
    fn held_misfits(&self, held: &mut Held) {
        let mut search_of = vec![None; held.len()];
        if !held.refined.is_empty() {
            for (i, &r) in held.searched.iter().enumerate() {
                search_of[r] = Some(i);
            }
        }
        held.extra = (0..held.len())
            .map(|r| {
                let b = held.between.get(r).map_or(&[][..], |b| &b[..]);
                match search_of[r] {
                    Some(i) => Self::extra_d2(b, &held.refined[i]),
                    None => Self::between_d2(b),
                }
            })
            .collect();
        held.ratio = (0..held.len())
            .map(|r| self.misfit(&held.d2[r], &held.extra[r]))
            .collect();
    }

    /// Each unknown's range, per class.
    fn spans(&self) -> Vec<Vec<f64>> {
        self.ranges
            .iter()
            .map(|r| r.iter().map(|[lo, hi]| hi - lo).collect())
            .collect()
    }

    /// The pose: the temperature of the bank's weights with the lowest held-out error, then
    /// the fit between runs' pose or the search's instead where they err less. Returns the
    /// held-out runs' poses as the estimator gives them, each with its held-out run.
    fn fit_pose(&mut self, held: &Held) -> Vec<(Vec<f64>, usize)> {
        let spans = self.spans();
        // A pose's error, summed over its unknowns in units of each one's range.
        let error = |p: &[f64], s: &ShapeSample| -> f64 {
            p.iter()
                .zip(&s.params)
                .zip(&spans[s.class])
                .map(|((p, x), w)| (p - x).abs() / w)
                .sum()
        };
        let mut best = (f64::INFINITY, 1.0);
        for t in temperatures() {
            let err: f64 = (0..held.len())
                .map(|r| {
                    let s = held.run(r);
                    error(&self.pose(&held.d2[r], s.class, t * held.ratio[r]), s)
                })
                .sum();
            if err < best.0 {
                best = (err, t);
            }
        }
        self.pose_temperature = best.1;
        // Held-out run `r`'s pose: the fit between runs' (where there is one), or the weighted
        // mean of the bank's poses.
        let held_pose = |r: usize, between: bool| -> Vec<f64> {
            let c = held.run(r).class;
            match held.between.get(r).and_then(|b| b[c].as_ref()) {
                Some(b) if between => b.pose.clone(),
                _ => self.pose(&held.d2[r], c, self.pose_temperature * held.ratio[r]),
            }
        };
        // The fit between runs' pose instead, where it errs less on the held-out runs.
        let pose_between = self.neighbours > 0
            && (0..held.len())
                .map(|r| error(&held_pose(r, true), held.run(r)))
                .sum::<f64>()
                < best.0;
        // The search's pose instead where it searched the true class, when that errs less on
        // the runs searched.
        let searched = &held.searched;
        let refined_pose = |i: usize| -> Vec<f64> {
            let r = searched[i];
            match held.refined[i][held.truth[r]].as_ref() {
                Some(f) => f.pose.clone(),
                None => held_pose(r, pose_between),
            }
        };
        let pose_refined = !held.refined.is_empty()
            && (0..searched.len())
                .map(|i| error(&refined_pose(i), held.run(searched[i])))
                .sum::<f64>()
                < searched
                    .iter()
                    .map(|&r| error(&held_pose(r, pose_between), held.run(r)))
                    .sum::<f64>();
        let poses = if pose_refined {
            (0..searched.len())
                .map(|i| (refined_pose(i), searched[i]))
                .collect()
        } else {
            (0..held.len())
                .map(|r| (held_pose(r, pose_between), r))
                .collect()
        };
        (self.pose_between, self.pose_refined) = (pose_between, pose_refined);
        poses
    }

    /// Split-conformal 90% half-widths per class and unknown of the held-out runs' pose errors
    /// (`poses`, as [`ShapeBank::fit_pose`] gives them), each divided by its run's misfit ratio
    /// to the power `power` (a recording's are widened by its own).
    fn half_widths(&self, held: &Held, poses: &[(Vec<f64>, usize)], power: f64) -> Vec<Vec<f64>> {
        let spans = self.spans();
        (0..self.classes.len())
            .map(|c| {
                let runs: Vec<(&Vec<f64>, &ShapeSample, f64)> = poses
                    .iter()
                    .map(|(p, r)| (p, held.run(*r), held.ratio[*r].powf(power)))
                    .filter(|(_, s, _)| s.class == c)
                    .collect();
                (0..self.names[c].len())
                    .map(|u| {
                        let mut e: Vec<f64> = runs
                            .iter()
                            .map(|(p, s, w)| (p[u] - s.params[u]).abs() / w)
                            .collect();
                        conformal_half_width(&mut e).unwrap_or(0.5 * spans[c][u])
                    })
                    .collect()
            })
            .collect()
    }

    /// How far a reading can be trusted at a given misfit, and how far its pose intervals
    /// widen: learnt from the noise-free runs of other whiskers `drawn`, each given a held-out
    /// training run's own noise (its residual against its twin among the `bank`'s runs, a
    /// residual the noise's covariance was not read on). Every drawn run is read, or none is
    /// used (a run the bank cannot read leaves the trust full).
    fn learn_trust(
        &mut self,
        held: &Held,
        poses: &[(Vec<f64>, usize)],
        bank: &[&ShapeSample],
        drawn: &[ShapeSample],
    ) {
        if drawn.is_empty() {
            return;
        }
        let noisy: Vec<ShapeSample> = drawn
            .iter()
            .enumerate()
            .map(|(k, s)| {
                // A large prime's stride apart from one drawn run to the next, so that classes
                // and poses mix.
                let (j, i) = held.pairs[(k * 7919) % held.len()];
                let mut s = s.clone();
                for ((w, wn), wc) in s
                    .whiskers
                    .iter_mut()
                    .zip(&held.training[j].whiskers)
                    .zip(&bank[i].whiskers)
                {
                    for ((c, cn), cc) in w.iter_mut().zip(wn).zip(wc) {
                        for ((x, a), b) in c.iter_mut().zip(cn).zip(cc) {
                            *x += a - b;
                        }
                    }
                }
                s
            })
            .collect();
        let readings: Option<Vec<Reading>> = noisy
            .par_iter()
            .map(|s| self.read(&s.whiskers).ok())
            .collect();
        let Some(readings) = readings else {
            return;
        };
        let truth_drawn: Vec<usize> = noisy.iter().map(|s| s.class).collect();
        let own_p: Vec<Vec<f64>> = (0..held.len())
            .map(|r| self.posterior(&held.d2[r], &held.extra[r], held.ratio[r]))
            .collect();
        let drawn_p: Vec<Vec<f64>> = readings.iter().map(|r| r.p.clone()).collect();
        let drawn_r: Vec<f64> = readings.iter().map(|r| r.ratio).collect();
        self.trust = off_nominal::fit_trust(
            &Readings {
                probs: &own_p,
                truth: &held.truth,
                ratio: &held.ratio,
            },
            &Readings {
                probs: &drawn_p,
                truth: &truth_drawn,
                ratio: &drawn_r,
            },
        );
        // The pose intervals of the drawn whiskers' runs named right.
        let right: Vec<(&Reading, &ShapeSample)> = readings
            .iter()
            .zip(&noisy)
            .filter(|(r, s)| r.best == s.class)
            .collect();
        let classes = self.classes.len();
        self.widen_power = off_nominal::widen_power(|power| {
            if right.len() < 2 * classes {
                return None;
            }
            let h = self.half_widths(held, poses, power);
            let (mut held_in, mut all) = (0usize, 0usize);
            for (r, s) in &right {
                let w = r.ratio.powf(power);
                for (u, (p, x)) in r.poses[r.best].iter().zip(&s.params).enumerate() {
                    all += 1;
                    held_in += usize::from((p - x).abs() <= h[s.class][u] * w);
                }
            }
            Some(held_in as f64 / all.max(1) as f64)
        });
        self.half_width = self.half_widths(held, poses, self.widen_power);
        self.off_nominal = (
            readings.len(),
            right.len() as f64 / readings.len() as f64,
            median(&drawn_r),
        );
    }

    /// Noise-free runs, [`OFF_NOMINAL_PER_CLASS`] per class, of whiskers and sensors drawn from
    /// the randomisation prior of the family the bank simulates (none when it simulates none,
    /// or the runs cannot be made).
    fn drawn_runs(&self) -> Vec<ShapeSample> {
        let Some(family) = &self.family else {
            return Vec::new();
        };
        let Ok(drawn) = family.randomised_if(true) else {
            return Vec::new();
        };
        let draws = drawn.draws(OFF_NOMINAL_PER_CLASS, false, OFF_NOMINAL_SEED);
        drawn
            .simulate_completed(&draws, &Noise::NONE, OFF_NOMINAL_SEED, &|| {})
            .map(|(runs, _)| runs)
            .unwrap_or_default()
    }

    /// Takes the settings of `c`.
    fn set_calibration(&mut self, c: &Calibration) {
        self.held_out_loss = c.loss;
        self.temperature = c.temperature;
        self.sharpness = c.sharpness;
        self.floor = c.floor;
        self.misfit = c.misfit;
    }

    /// The temperature, sharpness and even share with the lowest held-out log loss, that loss
    /// and the held-out runs' median misfit, for held-out runs with squared distances `d2` to
    /// the bank's runs and `extra` to each class's one more run, and true classes `truth`. Each
    /// run's temperatures are scaled by its own misfit ratio, as a recording's are; the even
    /// share is at least the one chosen without that scaling. (Every held-out run is one the
    /// family explains, and those of them whose nearest runs mislead lie a little farther than
    /// the rest, so that with the scaling a smaller share would do; a recording that the family
    /// explains wrongly but closely, as another whisker's may be, still needs it.)
    fn calibrate(&self, d2: &[Vec<f64>], extra: &[Vec<f64>], truth: &[usize]) -> Calibration {
        let near: Vec<f64> = d2.iter().zip(extra).map(|(d, x)| nearest(d, x)).collect();
        let reference = median(&near);
        let evidence = |scaled: bool| -> Vec<Vec<Vec<f64>>> {
            d2.par_iter()
                .zip(extra)
                .zip(&near)
                .map(|((d, x), &n)| {
                    let r = if scaled {
                        misfit_ratio(n, reference)
                    } else {
                        1.0
                    };
                    temperatures()
                        .map(|t| self.log_evidence(d, x, t * r))
                        .collect()
                })
                .collect()
        };
        let classes = self.counts.len();
        let plain = least_loss(classes, &evidence(false), truth, 0.0);
        let best = least_loss(classes, &evidence(true), truth, plain.3);
        Calibration {
            loss: best.0,
            temperature: best.1,
            sharpness: best.2,
            floor: best.3,
            misfit: reference,
        }
    }
}
