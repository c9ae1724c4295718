//! `shape-bank`: the class posterior as a likelihood ratio, from a bank of noise-free runs.
//!
//! Every class's evidence for a recording `y` is the mean, over noise-free simulations of that
//! class at poses drawn from its prior, of the Gaussian likelihood of `y` about the simulation:
//! a Monte Carlo estimate of `p(y | class)` with the pose integrated out. Its posterior is then
//! Bayes' rule over the classes. Unlike a regressor trained on noisy runs, it never has to learn
//! what noise looks like: the likelihood states it, so a few thousand noise-free runs per class
//! go further than the same number of noisy ones.
//!
//! What the likelihood uses: every whisker's five channels, each divided by that channel's noise
//! level, the noise level being what the world adds to a noise-free run, measured on the training
//! runs against noise-free twins of the same poses (sensor noise and the response to random
//! forces together, so nothing is assumed about either). The whitened series go through their
//! leading principal components (the squared distance outside them is nearly the same for every
//! run of the bank). The bank is far sparser than the likelihood is narrow, so the evidence is
//! tempered, `exp(−χ²/(2T))`, and the class posterior is `(1 − ε)·softmax(s·log evidence) + ε/K`
//! over the K classes, with `T`, `s` and `ε` the values whose held-out training runs (each scored
//! without its own twin, those whose pose lies in the classes' ranges) get the lowest log loss:
//! the probabilities are calibrated on runs the bank did not hold. The pose is the likelihood-weighted mean of the best class's bank runs
//! (at its own temperature, chosen by the held-out runs' pose errors), with a 90% interval as
//! wide as the held-out runs' errors (a split-conformal interval).
//!
//! A recording lying farther from its nearest run than the held-out runs do (misfit ratio `r`)
//! is read with every temperature multiplied by `r`; how much of its class posterior is then
//! spread evenly, and how far its pose intervals widen, is learnt from noisy runs of whiskers
//! drawn from the randomisation prior ([`super::off_nominal`]).

mod fit;

use super::between::{between, Between};
use super::estimator::{ClassPoses, ShapeEstimate};
use super::evaluate::subset;
use super::family::{ShapeFamily, ShapeSample};
use super::off_nominal::{self, median, misfit_ratio, Trust};
use super::refine::{refine, Refined};
use super::series_noise::SeriesNoise;
use crate::error::{Error, Result};
use crate::experiment::{Noise, CHANNELS};
use crate::method::Estimate;
use crate::methods::kernel_ridge::Pca;
use nalgebra::DMatrix;
use rayon::prelude::*;

/// Noise-free runs per class in the bank by default (the training runs' twins included).
pub const BANK_PER_CLASS: usize = 3200;
/// Principal components of the whitened series kept.
const COMPONENTS: usize = 200;
/// Most bank runs the principal axes are found from.
const PCA_RUNS: usize = 1000;
/// Every `HOLD`-th training run is scored as held out.
const HOLD: usize = 2;
/// A channel's noise level is at least this share of its median RMS over the bank (a clean
/// recording still weighs the channels by their size).
const NOISE_FLOOR: f64 = 0.01;
/// Most residual series (one whisker of one training run each) the noise's covariance is
/// estimated from.
const NOISE_SERIES: usize = 16_000;
/// Runs projected onto the principal axes at once.
const CHUNK: usize = 256;
/// Neighbours tried for the fit between a class's runs (`between`; at least the class's pose
/// unknowns plus two), 0 for none: the number with the lowest held-out log loss is kept.
const NEIGHBOURS: [usize; 6] = [0, 6, 8, 10, 12, 16];
/// Classes whose nearest run is searched with the simulator ([`refine`]) for each recording:
/// those nearest it in the bank (or its fit between runs); four is every class of `e3`. A class
/// the bank ranks third can still hold the recording's own run: the bank is sparse.
const REFINE_CLASSES: usize = 4;
/// Starts of that search per class: the class's nearest bank runs whose poses lie at least
/// [`START_SEPARATION`] apart, each searched, the nearest end kept (the nearest bank run alone
/// often leads into another pose's valley).
const REFINE_STARTS: usize = 3;
/// Least distance between two starts' poses, in units of each unknown's range (Euclidean).
const START_SEPARATION: f64 = 0.15;
/// Rounds of that search (each one simulation per pose unknown and one to three more).
const REFINE_ROUNDS: usize = 2;
/// Most held-out runs on which the search is tried and, when kept, calibrated.
const REFINE_HELD: usize = 240;
/// Held-out runs whose misfit after every sample sets the reference of the posterior after
/// every sample.
const TRACE_HELD: usize = 100;
/// Noisy runs per class of whiskers drawn from the randomisation prior, read after the fit to
/// learn how far a reading can be trusted at a given misfit ([`off_nominal`]).
const OFF_NOMINAL_PER_CLASS: usize = 30;
/// Seed of those runs' poses, whiskers and sensors.
const OFF_NOMINAL_SEED: u64 = 0x0ff_a0e1;

/// Noise-free runs of a shape family for [`ShapeBank`]: twins of the training runs (the same
/// poses and, for randomised training, the same whiskers) and further draws.
#[derive(Debug, Clone, Default)]
pub struct CleanRuns {
    /// The training draws simulated without noise, in their order.
    pub twins: Vec<ShapeSample>,
    /// Further draws over the classes' ranges (without the training margins), without noise.
    pub extra: Vec<ShapeSample>,
}

impl CleanRuns {
    /// Simulates the twins of `train_draws` (run `k` seeded as the training run `k` was, by
    /// `train_seed`, on `train_family`, the family the training runs were simulated on) and the
    /// rest of `per_class` draws per class from `draw_seed` (the seed of `train_draws`), so that
    /// the bank holds `per_class` runs of every class. `tick` is called once per run.
    pub fn simulate(
        train_family: &ShapeFamily,
        train_draws: &[(usize, Vec<f64>)],
        per_class: usize,
        draw_seed: u64,
        train_seed: u64,
        tick: &(dyn Fn() + Sync),
    ) -> Result<(CleanRuns, Vec<String>)> {
        let classes = train_family.classes().len();
        let trained = train_draws.len() / classes.max(1);
        // The further runs lie over the ranges themselves (the recordings' prior, which the
        // training runs' margins reach beyond), spread evenly rather than drawn independently.
        let extra_draws = train_family.even_draws(per_class.saturating_sub(trained), draw_seed);
        let (twins, mut failed) =
            train_family.simulate_completed(train_draws, &Noise::NONE, train_seed, tick)?;
        let (extra, more) = train_family.simulate_completed(
            &extra_draws,
            &Noise::NONE,
            train_seed ^ 0xba4c,
            tick,
        )?;
        failed.extend(more);
        Ok((CleanRuns { twins, extra }, failed))
    }

    /// The same runs read by the whiskers at `idx` only.
    pub fn subset(&self, idx: &[usize]) -> CleanRuns {
        CleanRuns {
            twins: subset(&self.twins, idx),
            extra: subset(&self.extra, idx),
        }
    }

    /// Runs in all.
    pub fn len(&self) -> usize {
        self.twins.len() + self.extra.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// The fitted estimator (see the module's documentation).
#[derive(Debug, Clone)]
pub struct ShapeBank {
    classes: Vec<String>,
    names: Vec<Vec<String>>,
    whiskers: usize,
    samples: usize,
    /// Each channel's noise level, `[CHANNELS]`, SI.
    sigma: [f64; 5],
    /// The noise's covariance over one whisker's series (in units of `sigma`).
    noise: SeriesNoise,
    /// Principal components kept.
    components: usize,
    /// The projection onto the principal axes of the whitened series, folded with the
    /// whitening: components = `x · fold − offset`, `x` a run divided by `sigma`, end to end.
    fold: DMatrix<f64>,
    offset: Vec<f64>,
    /// Every bank run's whitened series in full (`[runs][whiskers][samples][CHANNELS]`, f32),
    /// for the class posterior after every sample.
    whitened: Vec<f32>,
    /// The bank: class, pose, components.
    class_of: Vec<usize>,
    params: Vec<Vec<f64>>,
    z: Vec<Vec<f64>>,
    /// Bank runs of each class.
    counts: Vec<usize>,
    /// Each class's bank runs nearest a recording that its fit between runs uses (0: none).
    neighbours: usize,
    /// Whether the pose is the fit between runs' (else the weighted mean of the bank's poses).
    pose_between: bool,
    /// The family whose noise-free runs the search for a class's nearest run simulates (the
    /// bank's whiskers and timing), each class's pose ranges, and how many classes it searches
    /// per recording (0: none).
    family: Option<ShapeFamily>,
    ranges: Vec<Vec<[f64; 2]>>,
    refine_classes: usize,
    /// Whether the pose is the search's (where it searched the most probable class).
    pose_refined: bool,
    /// Mean simulations per recording on the held-out runs searched.
    refine_runs: f64,
    /// Temperature of the class evidence, the factor of its logarithm in the class softmax,
    /// and the temperature of the pose's weights.
    temperature: f64,
    sharpness: f64,
    /// The share of the class posterior spread evenly over the classes.
    floor: f64,
    /// The held-out runs' log loss at the chosen settings.
    held_out_loss: f64,
    /// The median, over the held-out runs, of a run's squared distance to the nearest run that
    /// explains it (the bank's, the fit between runs' or the search's): what a recording the
    /// model can explain leaves unexplained. A recording that lies `r` > 1 times as far from
    /// its nearest run is read with every temperature `r` times higher ([`ShapeBank::misfit`]).
    misfit: f64,
    /// The same median of the cumulative squared distance in the full whitened series after
    /// every sample, for the posterior after every sample ([`ShapeBank::trace`]).
    misfit_trace: Vec<f64>,
    pose_temperature: f64,
    /// 90% half-widths `[classes][unknowns]`, at a misfit ratio of 1.
    half_width: Vec<Vec<f64>>,
    /// How far a reading is trusted at a given misfit ratio ([`off_nominal`]).
    trust: Trust,
    /// `δ` of [`off_nominal`]: a pose interval widens by `r^δ`.
    widen_power: f64,
    /// The drawn whiskers' runs read to fit `trust` and `widen_power`: how many, the share named
    /// right, and their median misfit ratio (0, NaN, NaN when none could be simulated).
    off_nominal: (usize, f64, f64),
}

/// What [`ShapeBank::read`] makes of a recording before the trust in it is applied.
struct Reading {
    /// The class posterior.
    p: Vec<f64>,
    /// The most probable class.
    best: usize,
    /// Every class's pose.
    poses: Vec<Vec<f64>>,
    /// The misfit ratio.
    ratio: f64,
}

/// The least of the squared distances `d2` to the bank's runs and `extra` to the classes' one
/// more run: how far the recording lies from the nearest run that explains it.
fn nearest(d2: &[f64], extra: &[f64]) -> f64 {
    d2.iter()
        .chain(extra)
        .copied()
        .fold(f64::INFINITY, f64::min)
}

/// `exp(s·l)` normalised.
fn softmax(l: &[f64], s: f64) -> Vec<f64> {
    let top = l.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let e: Vec<f64> = l.iter().map(|x| (s * (x - top)).exp()).collect();
    let sum: f64 = e.iter().sum();
    e.iter().map(|x| x / sum).collect()
}

/// A run's channels (`[whiskers][CHANNELS][samples]`), each divided by its noise level, whisker
/// after whisker, each whisker's time-major (its five channels at one sample, then the next).
fn scaled(whiskers: &[Vec<Vec<f64>>], sigma: &[f64; 5]) -> Vec<f64> {
    let samples = whiskers.first().and_then(|w| w.first()).map_or(0, Vec::len);
    let mut out = Vec::with_capacity(whiskers.len() * 5 * samples);
    for w in whiskers {
        for t in 0..w[0].len() {
            for (ch, sd) in w.iter().zip(sigma) {
                out.push(ch[t] / sd);
            }
        }
    }
    out
}

/// Runs scaled and whitened, every whisker's series by the noise's covariance (the whitening is
/// lower triangular: see [`crate::linalg::mul_lower_transposed`]).
fn whiten_runs(runs: &[&ShapeSample], sigma: &[f64; 5], noise: &SeriesNoise) -> Vec<Vec<f64>> {
    let whiskers = runs.first().map_or(0, |s| s.whiskers.len());
    let block = noise.width();
    let x: Vec<Vec<f64>> = runs.iter().map(|s| scaled(&s.whiskers, sigma)).collect();
    // One row per whisker of every run, whitened together.
    let rows = DMatrix::from_fn(runs.len() * whiskers, block, |r, c| {
        x[r / whiskers][(r % whiskers) * block + c]
    });
    drop(x);
    let u = crate::linalg::mul_lower_transposed(&rows, noise.whitening());
    (0..runs.len())
        .map(|k| {
            (0..whiskers)
                .flat_map(|w| u.row(k * whiskers + w).iter().copied().collect::<Vec<_>>())
                .collect()
        })
        .collect()
}

/// The projection onto `pca`'s axes (of whitened series) as one acting on scaled series:
/// `fold` = blockdiag(W)ᵀ · axes, `offset` = mean · axes.
fn folded(pca: &Pca, noise: &SeriesNoise, whiskers: usize) -> (DMatrix<f64>, Vec<f64>) {
    let block = noise.width();
    let k = pca.axes.len();
    let axes = DMatrix::from_fn(whiskers * block, k, |i, j| pca.axes[j][i]);
    let wt = noise.whitening().transpose();
    let mut fold = DMatrix::zeros(whiskers * block, k);
    for w in 0..whiskers {
        let part = &wt * axes.rows(w * block, block);
        fold.rows_mut(w * block, block).copy_from(&part);
    }
    let offset = (0..k)
        .map(|j| pca.axes[j].iter().zip(&pca.mean).map(|(a, m)| a * m).sum())
        .collect();
    (fold, offset)
}

impl ShapeBank {
    /// The estimator's name.
    pub const NAME: &'static str = "shape-bank";

    /// How many times farther than the held-out runs' median the recording with squared
    /// distances `d2` to the bank's runs and `extra` to the classes' one more run lies from the
    /// nearest run that explains it (at least 1). Far beyond what noise and the bank's spacing
    /// leave, the model does not explain the recording (another whisker, say), and its
    /// differences between classes are not evidence: every temperature is raised by this ratio,
    /// as a least-squares fit scales its noise by the reduced χ², and the pose's intervals widen
    /// by a power of it ([`off_nominal`]).
    fn misfit(&self, d2: &[f64], extra: &[f64]) -> f64 {
        misfit_ratio(nearest(d2, extra), self.misfit)
    }

    /// Every class's fit between its `k` runs nearest the recording (none when `k` is 0).
    fn between_all(&self, z: &[f64], d2: &[f64], k: usize) -> Vec<Option<Between>> {
        (0..self.counts.len())
            .map(|c| {
                (k > 0)
                    .then(|| {
                        // At least the class's unknowns plus two runs.
                        let least = self.names[c].len() + 2;
                        between(
                            z,
                            d2,
                            &self.class_of,
                            &self.params,
                            &self.z,
                            c,
                            k.max(least),
                        )
                    })
                    .flatten()
            })
            .collect()
    }

    /// The squared distance of each class's fit between runs (infinite where there is none).
    fn between_d2(b: &[Option<Between>]) -> Vec<f64> {
        b.iter()
            .map(|b| b.as_ref().map_or(f64::INFINITY, |b| b.d2))
            .collect()
    }

    /// Each class's one more run: the search's nearest run where it searched the class, else
    /// the fit between runs' (infinite where there is neither).
    fn extra_d2(b: &[Option<Between>], refined: &[Option<Refined>]) -> Vec<f64> {
        b.iter()
            .zip(refined)
            .map(|(b, f)| match f {
                Some(f) => f.d2,
                None => b.as_ref().map_or(f64::INFINITY, |b| b.d2),
            })
            .collect()
    }

    /// The nearest run, searched with the simulator, of each of the `classes` classes that come
    /// nearest the recording `z` (squared distances `d2` to the bank's runs, fits between runs
    /// `between`), starting from each one's [`REFINE_STARTS`] nearest bank runs of distinct
    /// poses ([`starts`]), the first trying its fit between runs' pose first; `None` for the
    /// other classes, or without a family to simulate.
    fn refined_all(
        &self,
        z: &[f64],
        d2: &[f64],
        between: &[Option<Between>],
        classes: usize,
    ) -> Vec<Option<Refined>> {
        let k = self.counts.len();
        let mut out = vec![None; k];
        if self.family.is_none() || classes == 0 {
            return out;
        }
        // Each class's nearest bank run, and how near the class comes.
        let mut nearest: Vec<Option<(f64, usize)>> = vec![None; k];
        for (i, (d, &c)) in d2.iter().zip(&self.class_of).enumerate() {
            if d.is_finite() && nearest[c].is_none_or(|(b, _)| *d < b) {
                nearest[c] = Some((*d, i));
            }
        }
        let mut order: Vec<(f64, usize)> = (0..k)
            .filter_map(|c| {
                let (d, _) = nearest[c]?;
                let plane = between[c].as_ref().map_or(f64::INFINITY, |b| b.d2);
                Some((d.min(plane), c))
            })
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0));
        // Every (class, start) pair is one search; they run side by side.
        let tasks: Vec<(usize, usize, bool)> = order
            .iter()
            .take(classes)
            .flat_map(|&(_, c)| {
                let first = nearest[c].map(|(_, i)| i);
                starts(&self.params, &self.class_of, &self.ranges[c], c, d2, first)
                    .into_iter()
                    .enumerate()
                    .map(move |(k, i)| (c, i, k == 0))
            })
            .collect();
        let found: Vec<(usize, Refined)> = tasks
            .par_iter()
            .map(|&(c, i, first)| {
                let simulate = |p: &[f64]| self.simulate_z(c, p);
                let proposal = if first {
                    between[c].as_ref().map(|b| &b.pose[..])
                } else {
                    None
                };
                let f = refine(
                    z,
                    &self.ranges[c],
                    (&self.params[i], &self.z[i]),
                    proposal,
                    REFINE_ROUNDS,
                    &simulate,
                );
                (c, f)
            })
            .collect();
        // Per class, the nearest end of its searches, counting the runs of all of them.
        for (c, f) in found {
            out[c] = Some(match out[c].take() {
                None => f,
                Some(kept) => {
                    let runs = kept.runs + f.runs;
                    let mut nearer = if f.d2 < kept.d2 { f } else { kept };
                    nearer.runs = runs;
                    nearer
                }
            });
        }
        out
    }

    /// The components of class `c`'s noise-free run at pose `p` (`None` where it cannot be
    /// simulated or does not have the bank's shape).
    fn simulate_z(&self, c: usize, p: &[f64]) -> Option<Vec<f64>> {
        let family = self.family.as_ref()?;
        let run = family
            .simulate_one(&(c, p.to_vec()), &Noise::NONE, 0)
            .ok()?;
        let fits = run.whiskers.len() == self.whiskers
            && run
                .whiskers
                .iter()
                .all(|w| w.len() == CHANNELS.len() && w.iter().all(|c| c.len() == self.samples));
        fits.then(|| self.project(&run.whiskers))
    }

    /// The components of one run (`[whiskers][CHANNELS][samples]`).
    fn project(&self, whiskers: &[Vec<Vec<f64>>]) -> Vec<f64> {
        let x = scaled(whiskers, &self.sigma);
        self.fold
            .column_iter()
            .zip(&self.offset)
            .map(|(a, o)| a.iter().zip(&x).map(|(a, x)| a * x).sum::<f64>() - o)
            .collect()
    }

    /// Components of many runs, a chunk at a time, each chunk one matrix product with the
    /// folded projection, in parallel.
    fn project_all(&self, runs: &[&ShapeSample]) -> Vec<Vec<f64>> {
        runs.par_chunks(CHUNK)
            .flat_map_iter(|runs| {
                let chunk: Vec<Vec<f64>> = runs
                    .iter()
                    .map(|s| scaled(&s.whiskers, &self.sigma))
                    .collect();
                let dim = self.fold.nrows();
                let rows = DMatrix::from_fn(chunk.len(), dim, |i, j| chunk[i][j]);
                let p = rows * &self.fold;
                (0..chunk.len())
                    .map(|i| {
                        p.row(i)
                            .iter()
                            .zip(&self.offset)
                            .map(|(a, o)| a - o)
                            .collect::<Vec<f64>>()
                    })
                    .collect::<Vec<_>>()
            })
            .collect()
    }

    /// Squared distances from components `z` to every bank run.
    fn distances(&self, z: &[f64]) -> Vec<f64> {
        self.z
            .iter()
            .map(|b| b.iter().zip(z).map(|(a, c)| (a - c) * (a - c)).sum())
            .collect()
    }

    /// Each class's log evidence at temperature `t`, up to a common constant, from the squared
    /// distances `d2` to the bank's runs and `extra` to each class's fit between its runs (one
    /// more run of the class, infinite where there is none).
    fn log_evidence(&self, d2: &[f64], extra: &[f64], t: f64) -> Vec<f64> {
        let lo = d2
            .iter()
            .chain(extra)
            .copied()
            .fold(f64::INFINITY, f64::min);
        let mut sum = vec![0.0f64; self.counts.len()];
        for (d, &c) in d2.iter().zip(&self.class_of) {
            sum[c] += (-(d - lo) / (2.0 * t)).exp();
        }
        let mut runs = self.counts.clone();
        for (c, d) in extra.iter().enumerate() {
            if d.is_finite() {
                sum[c] += (-(d - lo) / (2.0 * t)).exp();
                runs[c] += 1;
            }
        }
        sum.iter()
            .zip(&runs)
            .map(|(s, &n)| (s / n as f64).ln())
            .collect()
    }

    /// Class `c`'s pose: its bank runs' poses weighted by their tempered likelihood.
    fn pose(&self, d2: &[f64], c: usize, t: f64) -> Vec<f64> {
        let lo = d2
            .iter()
            .zip(&self.class_of)
            .filter(|(_, &k)| k == c)
            .map(|(d, _)| *d)
            .fold(f64::INFINITY, f64::min);
        let mut mean = vec![0.0; self.names[c].len()];
        let mut total = 0.0;
        for ((d, &k), p) in d2.iter().zip(&self.class_of).zip(&self.params) {
            if k != c {
                continue;
            }
            let w = (-(d - lo) / (2.0 * t)).exp();
            if w < 1e-12 {
                continue;
            }
            total += w;
            for (m, x) in mean.iter_mut().zip(p) {
                *m += w * x;
            }
        }
        mean.iter().map(|m| m / total).collect()
    }

    /// A recording's shape and values, checked against the training runs'.
    fn check(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<()> {
        if whiskers.len() != self.whiskers
            || whiskers
                .iter()
                .any(|w| w.len() != CHANNELS.len() || w.iter().any(|c| c.len() != self.samples))
        {
            return Err(Error::Observation(format!(
                "{}: the recording must have {} whiskers of {} channels of {} samples, as the \
                 training runs",
                Self::NAME,
                self.whiskers,
                CHANNELS.len(),
                self.samples
            )));
        }
        if whiskers.iter().flatten().flatten().any(|x| !x.is_finite()) {
            return Err(Error::Observation(format!(
                "{}: the recording holds a value that is not finite",
                Self::NAME
            )));
        }
        Ok(())
    }

    /// The class posterior of a recording with squared distances `d2` to the bank's runs and
    /// `extra` to each class's one more run, at misfit ratio `ratio`, before the trust in it.
    fn posterior(&self, d2: &[f64], extra: &[f64], ratio: f64) -> Vec<f64> {
        let k = self.classes.len() as f64;
        softmax(
            &self.log_evidence(d2, extra, self.temperature * ratio),
            self.sharpness,
        )
        .into_iter()
        .map(|p| (1.0 - self.floor) * p + self.floor / k)
        .collect()
    }

    /// One recording's class posterior, most probable class, its pose and the misfit ratio,
    /// before the trust in them.
    fn read(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<Reading> {
        self.check(whiskers)?;
        let z = self.project(whiskers);
        let d2 = self.distances(&z);
        let fitted = self.between_all(&z, &d2, self.neighbours);
        let refined = self.refined_all(&z, &d2, &fitted, self.refine_classes);
        let extra = Self::extra_d2(&fitted, &refined);
        let ratio = self.misfit(&d2, &extra);
        let p = self.posterior(&d2, &extra, ratio);
        let best = (0..p.len()).fold(0, |b, c| if p[c] > p[b] { c } else { b });
        let poses = (0..p.len())
            .map(|c| match (&refined[c], &fitted[c]) {
                (Some(f), _) if self.pose_refined => f.pose.clone(),
                (_, Some(b)) if self.pose_between => b.pose.clone(),
                _ => self.pose(&d2, c, self.pose_temperature * ratio),
            })
            .collect();
        Ok(Reading {
            p,
            best,
            poses,
            ratio,
        })
    }

    /// Class `c`'s pose in `reading`, each unknown with its 90% interval widened by the
    /// reading's misfit.
    fn pose_estimates(&self, reading: &Reading, c: usize) -> Vec<(String, Estimate)> {
        let widen = reading.ratio.powf(self.widen_power);
        reading.poses[c]
            .iter()
            .zip(&self.half_width[c])
            .zip(&self.names[c])
            .map(|((m, h), n)| {
                (
                    n.clone(),
                    Estimate::normal(*m, widen * h / crate::method::Z90),
                )
            })
            .collect()
    }

    /// [`ShapeBank::predict`] with every class's pose beside it (`[classes]`, by name).
    pub fn predict_every_class(
        &self,
        whiskers: &[Vec<Vec<f64>>],
    ) -> Result<(ShapeEstimate, ClassPoses)> {
        let reading = self.read(whiskers)?;
        let poses: Vec<_> = (0..reading.p.len())
            .map(|c| self.pose_estimates(&reading, c))
            .collect();
        let p = off_nominal::trusted(&reading.p, reading.ratio, self.trust);
        let estimate = ShapeEstimate {
            class: self.classes.iter().cloned().zip(p).collect(),
            best: reading.best,
            pose: poses[reading.best].clone(),
            misfit: Some(reading.ratio),
        };
        Ok((estimate, poses))
    }

    /// The class posterior and the most probable class's pose of one recording
    /// (`[whiskers][CHANNELS][samples]`).
    pub fn predict(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<ShapeEstimate> {
        Ok(self.predict_every_class(whiskers)?.0)
    }

    /// One recording's whitened series in full (`[whiskers][samples][CHANNELS]`, f32).
    fn whiten_one(&self, whiskers: &[Vec<Vec<f64>>]) -> Vec<f32> {
        let run = ShapeSample {
            class: 0,
            params: Vec::new(),
            whiskers: whiskers.to_vec(),
        };
        whiten_runs(&[&run], &self.sigma, &self.noise)
            .pop()
            .unwrap_or_default()
            .into_iter()
            .map(|x| x as f32)
            .collect()
    }

    /// Each bank run's squared distance to the whitened recording `u` so far, after every
    /// sample (`[bank runs][samples]`).
    fn cumulative(&self, u: &[f32]) -> Vec<Vec<f32>> {
        let (samples, channels) = (self.samples, CHANNELS.len());
        let width = self.whiskers * samples * channels;
        self.whitened
            .par_chunks(width)
            .map(|b| {
                let mut sum = vec![0.0f32; samples];
                for w in 0..self.whiskers {
                    let mut acc = 0.0f32;
                    for (t, s) in sum.iter_mut().enumerate() {
                        let at = (w * samples + t) * channels;
                        for k in at..at + channels {
                            let d = u[k] - b[k];
                            acc += d * d;
                        }
                        *s += acc;
                    }
                }
                sum
            })
            .collect()
    }

    /// The median, over `runs` (each a recording and the bank index of its own twin, left
    /// out), of the squared distance to the nearest bank run after every sample.
    fn trace_misfit(&self, runs: &[(&ShapeSample, usize)]) -> Vec<f64> {
        let nearest: Vec<Vec<f64>> = runs
            .iter()
            .map(|(s, twin)| {
                let mut c = self.cumulative(&self.whiten_one(&s.whiskers));
                c[*twin].fill(f32::INFINITY);
                (0..self.samples)
                    .map(|t| {
                        c.iter()
                            .map(|c| f64::from(c[t]))
                            .fold(f64::INFINITY, f64::min)
                    })
                    .collect()
            })
            .collect();
        (0..self.samples)
            .map(|t| median(&nearest.iter().map(|n| n[t]).collect::<Vec<_>>()))
            .collect()
    }

    /// The class posterior after every sample of one recording (`[samples][classes]`): the
    /// same evidence as [`ShapeBank::predict`]'s, each bank run's likelihood that of the
    /// recording so far (the whitening is causal: see [`SeriesNoise::whitening`]), in the full
    /// whitened series rather than its principal components.
    pub fn trace(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<Vec<Vec<f64>>> {
        self.check(whiskers)?;
        let cumulative = self.cumulative(&self.whiten_one(whiskers));
        Ok((0..self.samples)
            .map(|t| {
                let d2: Vec<f64> = cumulative.iter().map(|c| f64::from(c[t])).collect();
                let none = vec![f64::INFINITY; self.counts.len()];
                let reference = self.misfit_trace.get(t).copied().unwrap_or(f64::NAN);
                let ratio = misfit_ratio(nearest(&d2, &none), reference);
                off_nominal::trusted(&self.posterior(&d2, &none, ratio), ratio, self.trust)
            })
            .collect())
    }

    /// Fitted settings worth reporting.
    pub fn settings(&self) -> Vec<(String, f64)> {
        let mut s = vec![
            ("bank_runs".into(), self.z.len() as f64),
            ("components".into(), self.components as f64),
            ("noise_shrinkage".into(), self.noise.shrinkage()),
            ("temperature".into(), self.temperature),
            ("sharpness".into(), self.sharpness),
            ("floor".into(), self.floor),
            ("held_out_log_loss".into(), self.held_out_loss),
            ("pose_temperature".into(), self.pose_temperature),
            ("neighbours".into(), self.neighbours as f64),
            (
                "pose_between".into(),
                f64::from(u8::from(self.pose_between)),
            ),
            ("refine_classes".into(), self.refine_classes as f64),
            ("refine_runs".into(), self.refine_runs),
            (
                "pose_refined".into(),
                f64::from(u8::from(self.pose_refined)),
            ),
            ("trust_threshold".into(), self.trust.threshold),
            ("trust_step".into(), self.trust.step),
            ("trust_power".into(), self.trust.power),
            ("widen_power".into(), self.widen_power),
            ("off_nominal_runs".into(), self.off_nominal.0 as f64),
            ("off_nominal_accuracy".into(), self.off_nominal.1),
            ("off_nominal_misfit".into(), self.off_nominal.2),
        ];
        for (c, x) in CHANNELS.iter().zip(self.sigma) {
            s.push((format!("noise_{c}"), x));
        }
        s
    }
}

/// Starts of class `c`'s search among bank runs with poses `params` and classes `class_of`, at
/// squared distances `d2` from the recording: the class's nearest run `first`, then its next
/// nearest runs whose poses lie at least [`START_SEPARATION`] (in units of the class's `ranges`)
/// from every start taken, up to [`REFINE_STARTS`] in all.
fn starts(
    params: &[Vec<f64>],
    class_of: &[usize],
    ranges: &[[f64; 2]],
    c: usize,
    d2: &[f64],
    first: Option<usize>,
) -> Vec<usize> {
    let Some(first) = first else {
        return Vec::new();
    };
    let apart = |a: usize, b: usize| -> bool {
        let sq: f64 = params[a]
            .iter()
            .zip(&params[b])
            .zip(ranges)
            .filter(|(_, [lo, hi])| hi > lo)
            .map(|((x, y), [lo, hi])| ((x - y) / (hi - lo)).powi(2))
            .sum();
        sq.sqrt() >= START_SEPARATION
    };
    let mut mine: Vec<(f64, usize)> = d2
        .iter()
        .zip(class_of)
        .enumerate()
        .filter(|(i, (d, &k))| k == c && d.is_finite() && *i != first)
        .map(|(i, (d, _))| (*d, i))
        .collect();
    mine.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut taken = vec![first];
    for (_, i) in mine {
        if taken.len() >= REFINE_STARTS {
            break;
        }
        if taken.iter().all(|&s| apart(s, i)) {
            taken.push(i);
        }
    }
    taken
}

#[cfg(test)]
mod tests;
