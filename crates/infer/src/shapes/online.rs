//! `shape-esn`: an online (Markovian) discriminator that emits a class posterior at every
//! sample, an echo-state network.
//!
//! The network's state is one block of leaky units per whisker ([`UNITS`] for one whisker,
//! [`ARRAY_UNITS`] shared out among an array's), each block driven by its own whisker's
//! recording one sample at a time:
//!
//! `x_k = (1 − a) ⊙ x_{k−1} + a ⊙ tanh(W x_{k−1} + W_in u_k + b)`,
//!
//! where `u_k` is what the whisker reads at sample `k` (each channel in units of its typical
//! level over the training runs, and the base wrench's direction and moment arm, as
//! `shape-krr` reads them), `W` a fixed random matrix of spectral radius about [`RADIUS`], and
//! the leak rates `a` spread from [`LEAKS`]`.0` to `.1` so that the units remember from a
//! millisecond to tens of milliseconds. Every block has the same weights, so the whiskers'
//! histories are kept apart and encoded alike; the read-out sees them all (the joint reading).
//! Nothing but the read-out is trained: the state depends only on the previous state and the
//! current sample, so the posterior is updated online in constant time per sample.
//!
//! The read-out is linear in `[x_k, m_k, u_k, 1]` over every block, where `m_k`, the running sum of the
//! states' departures from rest (over the training runs' length), keeps what the contact did
//! after the leaky units have forgotten it. It is fitted by ridge regression on every
//! [`STRIDE`]-th sample of every training run to the run's class indicator, so its scores
//! estimate the classes' probabilities given what has been read so far (before contact, the
//! classes' shares; sharper as the contact unfolds). The scores are floored, raised to a power
//! and normalised; the floor and a power, like the ridge, are chosen by the log loss on every
//! such sample of held-out training runs, and the power is then let move through the
//! recording, from one value at its first sample to another at its last, fitted on the same
//! samples (one power for all left the last sample's posterior too timid). Each class's pose
//! is a ridge read-out of the features after the last sample, fitted on that class's runs,
//! with a 90% interval whose half-width is the split-conformal quantile of the held-out runs'
//! errors.
//!
//! The network starts at its rest state (the state it settles to without input). Its weights
//! are drawn from a fixed seed, so a fit is reproducible.

use super::estimator::{
    conformal_half_width, fit_ramp, fit_temperature, ramp, softmax, Scales, ShapeEstimate,
};
use super::family::{ShapeFamily, ShapeSample};
use crate::error::{Error, Result};
use crate::experiment::CHANNELS;
use crate::method::{Estimate, Z90};
use crate::methods::kernel_ridge::HOLD;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use vibrissa_core::rng::Rng;

/// Units of the network's state with one whisker.
pub const UNITS: usize = 200;
/// Units of the whole state with several whiskers, shared out among them.
const ARRAY_UNITS: usize = 400;
/// Fewest units per whisker.
const MIN_UNITS: usize = 64;
/// Samples between those the read-out is fitted on (neighbours say nearly the same).
const STRIDE: usize = 4;
/// Spectral radius of the recurrent weights (below 1: the state forgets its start).
const RADIUS: f64 = 0.9;
/// Range of the units' leak rates per sample (log-uniform).
const LEAKS: (f64, f64) = (0.03, 1.0);
/// Standard deviation of the biases.
const BIAS: f64 = 0.2;
/// Inputs per whisker: the five channels and the wrench's direction and arm.
const INPUTS: usize = 8;
/// Each input clamped to this many typical levels.
const CLAMP: f64 = 10.0;
/// Floors of the class scores tried (a score estimates a class's probability and may fall
/// below zero).
const FLOORS: [f64; 4] = [0.003, 0.01, 0.03, 0.1];
/// Ridges of the read-outs tried, relative to the mean diagonal of the Gram matrix.
const RIDGES: [f64; 5] = [1e-7, 1e-6, 1e-5, 1e-4, 1e-3];
/// Runs stepped together (one matrix product per sample).
const BATCH: usize = 128;
/// Seed of the fixed random weights.
const WEIGHT_SEED: u64 = 0x5e5a_e5e5;

/// Units of one whisker's block for an array of `whiskers` whiskers: [`UNITS`] for one
/// whisker, [`ARRAY_UNITS`] shared out among several, at least [`MIN_UNITS`] each.
pub fn units_per_whisker(whiskers: usize) -> usize {
    if whiskers <= 1 {
        UNITS
    } else {
        (ARRAY_UNITS / whiskers).max(MIN_UNITS)
    }
}

/// The fixed random network: one block of leaky units per whisker, every block with the same
/// weights, driven by its own whisker's inputs (so each whisker's history is kept apart and
/// the read-out sees them jointly).
#[derive(Debug, Clone)]
struct Reservoir {
    /// Units per block.
    units: usize,
    /// Blocks (whiskers).
    blocks: usize,
    /// Recurrent weights, `units × units`.
    w: DMatrix<f64>,
    /// Input weights, `units × INPUTS`.
    w_in: DMatrix<f64>,
    /// Biases and leak rates, `units`.
    bias: DVector<f64>,
    leak: DVector<f64>,
    /// The state a block settles to with no input (a recording's start: the whisker at rest).
    rest: DVector<f64>,
}

impl Reservoir {
    /// The network for `whiskers` whiskers (fixed by [`WEIGHT_SEED`]).
    fn new(whiskers: usize) -> Reservoir {
        let units = units_per_whisker(whiskers);
        let mut rng = Rng::new(WEIGHT_SEED ^ units as u64);
        // Gaussian entries of variance 1/units have spectral radius about 1 (the circular law).
        let s = RADIUS / (units as f64).sqrt();
        let w = DMatrix::from_fn(units, units, |_, _| s * rng.normal());
        let si = 1.0 / (INPUTS as f64).sqrt();
        let w_in = DMatrix::from_fn(units, INPUTS, |_, _| si * rng.normal());
        let bias = DVector::from_fn(units, |_, _| BIAS * rng.normal());
        let (lo, hi) = (LEAKS.0.ln(), LEAKS.1.ln());
        let leak = DVector::from_fn(units, |i, _| {
            (lo + (hi - lo) * i as f64 / (units - 1) as f64).exp()
        });
        let mut r = Reservoir {
            units,
            blocks: 1,
            w,
            w_in,
            bias,
            leak,
            rest: DVector::zeros(units),
        };
        // The slowest unit forgets its start by a factor e per 1/LEAKS.0 steps.
        let mut x = DMatrix::zeros(units, 1);
        let mut m = DMatrix::zeros(units, 1);
        let u = DMatrix::zeros(INPUTS, 1);
        for _ in 0..(40.0 / LEAKS.0) as usize {
            r.step(&mut x, &mut m, &u, 0.0);
        }
        r.rest = x.column(0).into_owned();
        r.blocks = whiskers.max(1);
        r
    }

    /// Units of the whole state (every block).
    fn size(&self) -> usize {
        self.units * self.blocks
    }

    /// The rest state repeated for `runs` runs.
    fn start(&self, runs: usize) -> DMatrix<f64> {
        DMatrix::from_fn(self.size(), runs, |i, _| self.rest[i % self.units])
    }

    /// One step of the states `x` (`size × runs`) driven by inputs `u` (`INPUTS·blocks × runs`),
    /// adding `memory` times the new states' departures from rest to their running sums `m`.
    fn step(&self, x: &mut DMatrix<f64>, m: &mut DMatrix<f64>, u: &DMatrix<f64>, memory: f64) {
        let n = self.units;
        for b in 0..self.blocks {
            let mut pre = &self.w * x.rows(b * n, n);
            pre.gemm(1.0, &self.w_in, &u.rows(b * INPUTS, INPUTS), 1.0);
            for j in 0..x.ncols() {
                for i in 0..n {
                    let a = self.leak[i];
                    let v = tanh(pre[(i, j)] + self.bias[i]);
                    let next = (1.0 - a) * x[(b * n + i, j)] + a * v;
                    x[(b * n + i, j)] = next;
                    m[(b * n + i, j)] += memory * (next - self.rest[i]);
                }
            }
        }
    }

    /// Features of the read-outs: the state, its running sums, the inputs and 1.
    fn features_len(&self) -> usize {
        2 * self.size() + INPUTS * self.blocks + 1
    }

    /// The read-out's features of the runs' states: `[x; m; u; 1]`, one column per run.
    fn features(
        &self,
        x: &DMatrix<f64>,
        m: &DMatrix<f64>,
        u: &DMatrix<f64>,
        phi: &mut DMatrix<f64>,
    ) {
        let (n, inputs) = (self.size(), u.nrows());
        phi.rows_mut(0, n).copy_from(x);
        phi.rows_mut(n, n).copy_from(m);
        phi.rows_mut(2 * n, inputs).copy_from(u);
        phi.row_mut(2 * n + inputs).fill(1.0);
    }
}

/// The share of a recording of `samples` samples read after sample `k` (0 at the first, 1 at
/// the last).
fn sample_share(k: usize, samples: usize) -> f64 {
    if samples > 1 {
        k as f64 / (samples - 1) as f64
    } else {
        1.0
    }
}

/// `tanh(x)` as `1 − 2/(e^{2x} + 1)`: one exponential, cheaper than the library's `tanh`
/// (which the network's fit spent most of its stepping in). Its absolute error stays below
/// 1e-15, far below what the read-out resolves.
#[inline]
fn tanh(x: f64) -> f64 {
    1.0 - 2.0 / ((2.0 * x).exp() + 1.0)
}

/// The online shape estimator `shape-esn` (see the module's documentation).
#[derive(Debug, Clone)]
pub struct ShapeEsn {
    /// Class names, in order.
    classes: Vec<String>,
    /// Each class's unknowns' names.
    names: Vec<Vec<String>>,
    /// Whiskers read.
    whiskers: usize,
    /// Samples of the training runs (the running sums are scaled to it: recordings must have it).
    samples: usize,
    /// The channels' typical levels.
    scales: Scales,
    reservoir: Reservoir,
    /// Weight of each state in the running sums (one over the training runs' samples).
    memory: f64,
    /// Class read-out, `classes × features`.
    readout: DMatrix<f64>,
    /// The class probabilities are the read-out's scores (estimates of the indicators'
    /// expectations) floored at `floor`, raised to a power and normalised; the power moves
    /// from `power[0]` at the first sample to `power[1]` at the last (see `ramp`).
    floor: f64,
    power: [f64; 2],
    /// Each class's pose read-out (`unknowns × features`, in units of the ranges), the
    /// held-out spread of each unknown (same units) and the ranges.
    poses: Vec<PoseReadout>,
}

/// A class's pose read-out: weights (`unknowns × features`, values in units of the ranges),
/// each unknown's spread in the same units (see [`ShapeEsn::pose_readout`]), and the ranges.
#[derive(Debug, Clone)]
struct PoseReadout {
    weights: DMatrix<f64>,
    spread: Vec<f64>,
    ranges: Vec<[f64; 2]>,
}

/// The inputs of one sample of every whisker: `[whiskers][CHANNELS][samples]` at `k`.
fn inputs_at(scales: &Scales, whiskers: &[Vec<Vec<f64>>], k: usize, to: &mut [f64]) {
    for (w, series) in whiskers.iter().enumerate() {
        let values = std::array::from_fn(|c| series[c][k]);
        input_of(scales, &values, &mut to[w * INPUTS..(w + 1) * INPUTS]);
    }
}

/// The inputs of one whisker's sample (its [`CHANNELS`]) into `to` (`INPUTS` long).
fn input_of(scales: &Scales, values: &[f64; 5], to: &mut [f64]) {
    for c in 0..CHANNELS.len() {
        to[c] = (values[c] / scales.medians[c]).clamp(-CLAMP, CLAMP);
    }
    to[5..8].copy_from_slice(&scales.geometry(values[2], values[3], values[4]));
}

/// What a pass over a batch of runs accumulates.
struct Pass {
    /// `Φᵀ Φ` and `Φᵀ Y` over every sample (features × features, features × classes).
    gram: DMatrix<f64>,
    cross: DMatrix<f64>,
    /// Each run's features after its last sample.
    finals: Vec<DVector<f64>>,
    /// With read-outs given: each run's scores `[read-outs][samples][classes]`.
    scores: Vec<Vec<Vec<Vec<f64>>>>,
}

impl ShapeEsn {
    /// The method's name.
    pub const NAME: &'static str = "shape-esn";

    fn fail(detail: &str) -> Error {
        Error::Fit {
            method: Self::NAME.into(),
            detail: detail.into(),
        }
    }

    /// Steps `runs` through the network in batches, accumulating the read-out's Gram matrices
    /// (labels from `labels`) and, for each of `readouts`, the scores at every sample.
    fn pass(
        scales: &Scales,
        reservoir: &Reservoir,
        runs: &[&ShapeSample],
        classes: usize,
        readouts: &[DMatrix<f64>],
        memory: f64,
    ) -> Pass {
        let inputs = INPUTS * reservoir.blocks;
        let f = reservoir.features_len();
        let chunks: Vec<&[&ShapeSample]> = runs.chunks(BATCH).collect();
        let parts: Vec<Pass> = chunks
            .par_iter()
            .map(|chunk| {
                let b = chunk.len();
                let samples = chunk[0].whiskers[0][0].len();
                let mut x = reservoir.start(b);
                let mut mem = DMatrix::<f64>::zeros(reservoir.size(), b);
                let mut u = DMatrix::<f64>::zeros(inputs, b);
                let mut phi = DMatrix::<f64>::zeros(f, b);
                let y = DMatrix::from_fn(b, classes, |j, c| f64::from(chunk[j].class == c));
                let mut gram = DMatrix::<f64>::zeros(f, f);
                let mut cross = DMatrix::<f64>::zeros(f, classes);
                let mut scores = vec![vec![Vec::with_capacity(samples); readouts.len()]; b];
                let mut col = vec![0.0; inputs];
                for k in 0..samples {
                    for (j, s) in chunk.iter().enumerate() {
                        inputs_at(scales, &s.whiskers, k, &mut col);
                        u.column_mut(j).copy_from_slice(&col);
                    }
                    reservoir.step(&mut x, &mut mem, &u, memory);
                    reservoir.features(&x, &mem, &u, &mut phi);
                    if k % STRIDE != STRIDE - 1 {
                        continue;
                    }
                    crate::linalg::add_gram_lower(&mut gram, &phi, &phi.transpose());
                    cross.gemm(1.0, &phi, &y, 1.0);
                    for (r, readout) in readouts.iter().enumerate() {
                        let s = readout * &phi;
                        for (j, run) in scores.iter_mut().enumerate() {
                            run[r].push(s.column(j).iter().copied().collect());
                        }
                    }
                }
                crate::linalg::mirror_lower(&mut gram);
                let finals = (0..b).map(|j| phi.column(j).into_owned()).collect();
                Pass {
                    gram,
                    cross,
                    finals,
                    scores,
                }
            })
            .collect();
        let mut out = Pass {
            gram: DMatrix::zeros(f, f),
            cross: DMatrix::zeros(f, classes),
            finals: Vec::with_capacity(runs.len()),
            scores: Vec::with_capacity(runs.len()),
        };
        for p in parts {
            out.gram += p.gram;
            out.cross += p.cross;
            out.finals.extend(p.finals);
            out.scores.extend(p.scores);
        }
        out
    }

    /// Ridge solutions `(G + r·mean(diag G)·I)⁻¹ C`, transposed, for every ridge of [`RIDGES`]
    /// (`None` where not positive definite).
    fn ridge(gram: &DMatrix<f64>, cross: &DMatrix<f64>) -> Vec<Option<DMatrix<f64>>> {
        let n = gram.nrows();
        let scale = gram.diagonal().sum() / n as f64;
        RIDGES
            .iter()
            .map(|r| {
                let mut g = gram.clone();
                for i in 0..n {
                    g[(i, i)] += r * scale;
                }
                crate::linalg::cholesky(g).map(|c| c.solve(cross).transpose())
            })
            .collect()
    }

    /// Fits on the runs `training` of `family` (every class represented, runs of equal length).
    pub fn fit(family: &ShapeFamily, training: &[ShapeSample]) -> Result<ShapeEsn> {
        let classes = family.classes().len();
        for c in 0..classes {
            if training.iter().filter(|s| s.class == c).count() < 10 {
                return Err(Self::fail(&format!(
                    "needs at least 10 training runs of every class (`{}` has fewer)",
                    family.classes()[c].name
                )));
            }
        }
        let whiskers = training[0].whiskers.len();
        let samples = training[0]
            .whiskers
            .first()
            .and_then(|w| w.first())
            .map_or(0, |c| c.len());
        if whiskers == 0 || samples < 2 * STRIDE {
            return Err(Self::fail(&format!(
                "training runs need at least one whisker and {} samples (got {whiskers} whiskers \
                 of {samples} samples)",
                2 * STRIDE
            )));
        }
        if training.iter().any(|s| {
            s.whiskers.len() != whiskers
                || s.whiskers.iter().any(|w| {
                    w.len() < CHANNELS.len()
                        || w.iter()
                            .any(|ch| ch.len() != samples || ch.iter().any(|v| !v.is_finite()))
                })
        }) {
            return Err(Self::fail(
                "training runs differ in whiskers or length, or hold non-finite samples",
            ));
        }
        let scales = Scales::of(training, Self::NAME)?;
        let reservoir = Reservoir::new(whiskers);
        let memory = 1.0 / samples as f64;
        let (fit_i, held_i): (Vec<usize>, Vec<usize>) =
            (0..training.len()).partition(|i| i % HOLD != 0);
        let fit_runs: Vec<&ShapeSample> = fit_i.iter().map(|&i| &training[i]).collect();
        let held_runs: Vec<&ShapeSample> = held_i.iter().map(|&i| &training[i]).collect();
        // The read-out on the fitted runs for every ridge, scored on the held-out ones at every
        // sample; the ridge and temperature with the lowest held-out log loss win.
        let fitted = Self::pass(&scales, &reservoir, &fit_runs, classes, &[], memory);
        let candidates: Vec<(usize, DMatrix<f64>)> = Self::ridge(&fitted.gram, &fitted.cross)
            .into_iter()
            .enumerate()
            .filter_map(|(i, r)| r.map(|r| (i, r)))
            .collect();
        if candidates.is_empty() {
            return Err(Self::fail("the read-out's system is not positive definite"));
        }
        let readouts: Vec<DMatrix<f64>> = candidates.iter().map(|c| c.1.clone()).collect();
        let held = Self::pass(&scales, &reservoir, &held_runs, classes, &readouts, memory);
        let labels: Vec<usize> = held_runs.iter().map(|s| s.class).collect();
        let mut best: Option<(f64, usize, usize, f64, f64)> = None;
        for (r, &(ridge, _)) in candidates.iter().enumerate() {
            for floor in FLOORS {
                // The logarithms of the floored scores and the labels of every held-out sample.
                let mut logs = Vec::new();
                let mut each = Vec::new();
                for (run, &l) in held.scores.iter().zip(&labels) {
                    for s in &run[r] {
                        logs.push(s.iter().map(|v| v.max(floor).ln()).collect());
                        each.push(l);
                    }
                }
                let (power, loss) = fit_temperature(&logs, &each);
                if best.is_none_or(|b| loss < b.0) {
                    best = Some((loss, r, ridge, floor, power));
                }
            }
        }
        let (_, r, ridge, floor, power) = best.expect("at least one candidate");
        // The power then moves through the recording (see `ramp`), fitted on the same samples.
        let (mut logs, mut each, mut tau) = (Vec::new(), Vec::new(), Vec::new());
        for (run, &l) in held.scores.iter().zip(&labels) {
            for (j, s) in run[r].iter().enumerate() {
                logs.push(s.iter().map(|v| v.max(floor).ln()).collect());
                each.push(l);
                tau.push(sample_share(j * STRIDE + STRIDE - 1, samples));
            }
        }
        let (power, _) = fit_ramp(&logs, &each, &tau, power);
        // The final read-out on every run.
        let gram = &fitted.gram + &held.gram;
        let cross = &fitted.cross + &held.cross;
        let readout = Self::ridge(&gram, &cross)
            .swap_remove(ridge)
            .ok_or_else(|| Self::fail("the read-out's system is not positive definite"))?;
        // Each class's pose from the final states.
        let mut finals = vec![None; training.len()];
        for (i, v) in fit_i.iter().zip(fitted.finals) {
            finals[*i] = Some(v);
        }
        for (i, v) in held_i.iter().zip(held.finals) {
            finals[*i] = Some(v);
        }
        let finals: Vec<DVector<f64>> = finals.into_iter().map(|v| v.expect("every run")).collect();
        let poses = family
            .classes()
            .iter()
            .enumerate()
            .map(|(c, class)| {
                let ranges = class.family.ranges();
                let idx: Vec<usize> = (0..training.len())
                    .filter(|&i| training[i].class == c)
                    .collect();
                Self::pose_readout(&finals, training, &idx, &ranges).map(|(weights, spread)| {
                    PoseReadout {
                        weights,
                        spread,
                        ranges,
                    }
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(ShapeEsn {
            classes: family.class_names().iter().map(|s| s.to_string()).collect(),
            names: family.unknown_names(),
            whiskers,
            samples,
            scales,
            reservoir,
            memory,
            readout,
            floor,
            power,
            poses,
        })
    }

    /// A class's pose read-out from the final states of its runs `idx` (values in units of
    /// `ranges`): the ridge with the least held-out error, refitted on all of them, and each
    /// unknown's spread: the std of a normal whose 90% interval is the split-conformal
    /// half-width of the held-out errors.
    fn pose_readout(
        finals: &[DVector<f64>],
        training: &[ShapeSample],
        idx: &[usize],
        ranges: &[[f64; 2]],
    ) -> Result<(DMatrix<f64>, Vec<f64>)> {
        let n = finals[idx[0]].len();
        let target = |i: usize| {
            DVector::from_fn(ranges.len(), |u, _| {
                let [lo, hi] = ranges[u];
                (training[i].params[u] - lo) / (hi - lo)
            })
        };
        let accumulate = |runs: &[usize]| {
            let mut g = DMatrix::zeros(n, n);
            let mut c = DMatrix::zeros(n, ranges.len());
            for &i in runs {
                g.ger(1.0, &finals[i], &finals[i], 1.0);
                c.ger(1.0, &finals[i], &target(i), 1.0);
            }
            (g, c)
        };
        // Every HOLD-th of the class's runs held out while the ridge is chosen.
        let fit: Vec<usize> = (0..idx.len())
            .filter(|j| j % HOLD != 0)
            .map(|j| idx[j])
            .collect();
        let held: Vec<usize> = (0..idx.len()).step_by(HOLD).map(|j| idx[j]).collect();
        let (g, c) = accumulate(&fit);
        let mut best: Option<(f64, usize, Vec<f64>)> = None;
        for (r, m) in Self::ridge(&g, &c).into_iter().enumerate() {
            let Some(m) = m else { continue };
            // Each unknown's held-out errors; the intervals from the runs whose pose lies in
            // the class's ranges (the recordings' prior: the training draws' margins reach
            // beyond it, where the read-out errs more).
            let mut total = 0.0;
            let mut errors = vec![Vec::with_capacity(held.len()); ranges.len()];
            for &i in &held {
                let y = target(i);
                let e = &m * &finals[i] - &y;
                total += e.norm_squared();
                if y.iter().all(|v| (0.0..=1.0).contains(v)) {
                    for (list, v) in errors.iter_mut().zip(e.iter()) {
                        list.push(v.abs());
                    }
                }
            }
            if best.as_ref().is_none_or(|b| total < b.0) {
                // The std of a normal whose 90% interval is the split-conformal half-width.
                let spread = errors
                    .iter_mut()
                    .map(|e| conformal_half_width(e).unwrap_or(0.5) / Z90)
                    .collect();
                best = Some((total, r, spread));
            }
        }
        let (_, r, spread) =
            best.ok_or_else(|| Self::fail("a pose read-out's system is not positive definite"))?;
        let (g, c) = accumulate(idx);
        let m = Self::ridge(&g, &c)
            .swap_remove(r)
            .ok_or_else(|| Self::fail("a pose read-out's system is not positive definite"))?;
        Ok((m, spread))
    }

    /// A filter over one recording, fed one sample at a time.
    pub fn start(&self) -> Online<'_> {
        let r = &self.reservoir;
        let inputs = INPUTS * r.blocks;
        Online {
            model: self,
            x: r.start(1),
            m: DMatrix::zeros(r.size(), 1),
            u: DMatrix::zeros(inputs, 1),
            phi: DMatrix::zeros(r.features_len(), 1),
            column: vec![0.0; inputs],
            read: 0,
        }
    }

    /// The class posterior after every sample of one recording (`[whiskers][CHANNELS]
    /// [samples]`), `[samples][classes]`.
    pub fn trace(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<Vec<Vec<f64>>> {
        Ok(self.read(whiskers)?.1)
    }

    /// The class posterior after the last sample and the most probable class's pose.
    pub fn predict(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<ShapeEstimate> {
        Ok(self.read(whiskers)?.0)
    }

    /// The estimate after the last sample and the posterior after every sample.
    pub fn read(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<(ShapeEstimate, Vec<Vec<f64>>)> {
        self.check(whiskers)?;
        let mut online = self.start();
        let mut trace = Vec::with_capacity(self.samples);
        for k in 0..self.samples {
            let sample: Vec<[f64; 5]> = whiskers
                .iter()
                .map(|w| std::array::from_fn(|c| w[c][k]))
                .collect();
            trace.push(online.push(&sample)?);
        }
        let last = trace.last().cloned().unwrap_or_default();
        Ok((online.estimate(last), trace))
    }

    fn check(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<()> {
        if whiskers.len() != self.whiskers {
            return Err(Error::Observation(format!(
                "{} whiskers where {} was trained on {}",
                whiskers.len(),
                Self::NAME,
                self.whiskers
            )));
        }
        let samples = whiskers[0].first().map_or(0, |c| c.len());
        if samples != self.samples {
            return Err(Error::Observation(format!(
                "{} was trained on recordings of {} samples (its running sums are scaled to that \
                 length); this one has {samples}",
                Self::NAME,
                self.samples
            )));
        }
        for (w, series) in whiskers.iter().enumerate() {
            if samples == 0
                || series.len() < CHANNELS.len()
                || series.iter().any(|ch| ch.len() != samples)
                || series.iter().flatten().any(|v| !v.is_finite())
            {
                return Err(Error::Observation(format!(
                    "whisker {} needs the channels {} with the same number (at least 1) of finite samples",
                    w + 1,
                    CHANNELS.join(", ")
                )));
            }
        }
        Ok(())
    }

    /// Fitted settings worth reporting.
    pub fn settings(&self) -> Vec<(String, f64)> {
        vec![
            ("units".into(), self.reservoir.size() as f64),
            ("class_floor".into(), self.floor),
            ("class_power_first".into(), self.power[0]),
            ("class_power_last".into(), self.power[1]),
        ]
    }
}

/// A recording being read by [`ShapeEsn`], one sample at a time.
#[derive(Debug, Clone)]
pub struct Online<'a> {
    model: &'a ShapeEsn,
    x: DMatrix<f64>,
    m: DMatrix<f64>,
    u: DMatrix<f64>,
    phi: DMatrix<f64>,
    column: Vec<f64>,
    /// Samples read so far.
    read: usize,
}

impl Online<'_> {
    /// Reads one sample of every whisker (each whisker's [`CHANNELS`], in the order the model
    /// was trained on) and returns the class posterior after it.
    pub fn push(&mut self, sample: &[[f64; 5]]) -> Result<Vec<f64>> {
        let m = self.model;
        if sample.len() != m.whiskers {
            return Err(Error::Observation(format!(
                "a sample of {} whiskers where {} was trained on {}",
                sample.len(),
                ShapeEsn::NAME,
                m.whiskers
            )));
        }
        if sample.iter().flatten().any(|v| !v.is_finite()) {
            return Err(Error::Observation(format!(
                "a sample with a value that is not finite: {sample:?}"
            )));
        }
        for (w, values) in sample.iter().enumerate() {
            input_of(
                &m.scales,
                values,
                &mut self.column[w * INPUTS..(w + 1) * INPUTS],
            );
        }
        self.u.column_mut(0).copy_from_slice(&self.column);
        m.reservoir
            .step(&mut self.x, &mut self.m, &self.u, m.memory);
        m.reservoir
            .features(&self.x, &self.m, &self.u, &mut self.phi);
        let logs: Vec<f64> = (&m.readout * &self.phi)
            .iter()
            .map(|s| s.max(m.floor).ln())
            .collect();
        let power = ramp(m.power, sample_share(self.read, m.samples));
        self.read += 1;
        Ok(softmax(&logs, power))
    }

    /// The estimate with posterior `p` at the current state.
    pub fn estimate(&self, p: Vec<f64>) -> ShapeEstimate {
        let m = self.model;
        let best = (0..p.len()).fold(0, |b, c| if p[c] > p[b] { c } else { b });
        let PoseReadout {
            weights,
            spread,
            ranges,
        } = &m.poses[best];
        let y = weights * &self.phi;
        let pose = m.names[best]
            .iter()
            .enumerate()
            .map(|(u, n)| {
                let [lo, hi] = ranges[u];
                let w = hi - lo;
                (n.clone(), Estimate::normal(lo + w * y[u], w * spread[u]))
            })
            .collect();
        ShapeEstimate {
            class: m.classes.iter().cloned().zip(p).collect(),
            best,
            pose,
            misfit: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::tanh;

    #[test]
    fn tanh_by_one_exponential_matches_the_library() {
        let mut worst: f64 = 0.0;
        for k in -40_000..=40_000 {
            let x = k as f64 * 1e-3;
            worst = worst.max((tanh(x) - x.tanh()).abs());
        }
        for x in [1e-300, 1e-12, -1e-8, 3e-5, 800.0, -800.0, f64::INFINITY] {
            worst = worst.max((tanh(x) - x.tanh()).abs());
        }
        assert!(worst < 1e-15, "largest difference {worst:e}");
        assert!(tanh(f64::NAN).is_nan());
    }
}
