//! `shape-krr`: a class posterior and a pose from several whiskers, by kernel ridge regression
//! on what the recordings show of each whisker's signals.
//!
//! What it reads of a recording (all whiskers jointly): each channel of each whisker divided by
//! its own RMS (the shape and timing of the signal, blind to the sensor's gain and the whisker's
//! stiffness), and log amplitudes that are blind to the same: per whisker the wrench's ratios
//! `m0/fy` and `fx/fy` (the moment arm), and with several whiskers each channel's amplitude
//! relative to the array's mean (which whiskers the object pressed hardest). A channel quieter
//! than a floor (a small share of its typical level over the training runs) counts as silent: a
//! whisker the object missed. The series go through their leading principal components; the
//! amplitudes are appended with a weight chosen on held-out training runs.
//!
//! The class posterior is a kernel ridge regression of each class's indicator whose scores go
//! through a softmax with a temperature fitted to the leave-one-out scores (so that the
//! probabilities are calibrated on runs the fit did not see). Each class has its own pose
//! regression, fitted on that class's runs, with leave-one-out intervals.

use super::family::{ShapeFamily, ShapeSample};
use crate::error::{Error, Result};
use crate::experiment::CHANNELS;
use crate::features::dist2;
use crate::method::Estimate;
use crate::methods::kernel_ridge::{median_distance, Pca, Regression, Spread, HOLD, RIDGES};
use nalgebra::DMatrix;
use rayon::prelude::*;

/// Principal components of the series kept.
const COMPONENTS: usize = 40;
/// Weights of the amplitude features tried, per unit of a channel's RMS per sample.
const WEIGHTS: [f64; 3] = [1.0, 3.0, 10.0];
/// A channel whose RMS is below this share of its median RMS over the training runs is silent.
const FLOOR: f64 = 0.02;
/// The base force's direction and arm fade out below this share of the training runs' median
/// peak force.
const FORCE_FLOOR: f64 = 0.15;
/// Length scales tried for the classifier, as multiples of the median distance between runs.
const LENGTHS: [f64; 5] = [0.25, 0.5, 1.0, 2.0, 4.0];
/// Most centres of the classifier's kernel expansion.
const LANDMARKS: usize = 800;
/// Most runs the principal axes are found from.
const PCA_RUNS: usize = 1000;

/// A class posterior and the most probable class's pose.
#[derive(Debug, Clone, PartialEq)]
pub struct ShapeEstimate {
    /// Each class's posterior probability, in the family's order (summing to 1).
    pub class: Vec<(String, f64)>,
    /// Index of the most probable class.
    pub best: usize,
    /// That class's unknowns, by name.
    pub pose: Vec<(String, Estimate)>,
    /// How many times farther the recording lies from the nearest run the estimator could
    /// simulate than its held-out simulated recordings typically do (at least 1), where the
    /// estimator measures it (`shape-bank`). Far above 1, the model does not explain the
    /// recording (another whisker, say); the estimator has then widened its probabilities
    /// and intervals by it.
    pub misfit: Option<f64>,
}

/// The index of the largest of `p` (the last on ties; 0 when empty).
pub(super) fn argmax(p: &[f64]) -> usize {
    (0..p.len())
        .max_by(|&a, &b| p[a].total_cmp(&p[b]))
        .unwrap_or(0)
}

/// Every class's pose, `[classes]`, each unknown by name (what an estimator that follows every
/// class gives beside its [`ShapeEstimate`]).
pub type ClassPoses = Vec<Vec<(String, Estimate)>>;

/// Kernel ridge scores of each class's indicator, through a softmax.
#[derive(Debug, Clone, Default)]
struct Classifier {
    /// The centres of its kernel expansion (training points).
    z: Vec<Vec<f64>>,
    /// Dual weights `[classes][centres]`.
    alpha: Vec<Vec<f64>>,
    /// Kernel length scale.
    length: f64,
    /// Softmax temperature (scores are multiplied by it).
    temperature: f64,
}

/// Probabilities of `scores` multiplied by `t`, through a softmax.
pub(super) fn softmax(scores: &[f64], t: f64) -> Vec<f64> {
    let m = scores.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let e: Vec<f64> = scores.iter().map(|s| ((s - m) * t).exp()).collect();
    let sum: f64 = e.iter().sum();
    e.iter().map(|x| x / sum).collect()
}

/// Mean negative log probability of the true labels of `scores` (`[runs][classes]`) at
/// temperature `t`.
fn log_loss(scores: &[Vec<f64>], labels: &[usize], t: f64) -> f64 {
    scores
        .iter()
        .zip(labels)
        .map(|(s, &l)| -softmax(s, t)[l].max(1e-300).ln())
        .sum::<f64>()
        / scores.len().max(1) as f64
}

/// The temperature in [0.1, 1000] that minimises [`log_loss`] (golden-section search on its
/// logarithm; the loss is unimodal in it for scores that rank the true class first on average).
pub(super) fn fit_temperature(scores: &[Vec<f64>], labels: &[usize]) -> (f64, f64) {
    let (u, loss) = golden(
        |u| log_loss(scores, labels, u.exp()),
        (0.1f64.ln(), 1000f64.ln()),
    );
    (u.exp(), loss)
}

/// Golden-section search of `f` over `[a, b]` (60 steps); returns the argument and value.
fn golden(f: impl Fn(f64) -> f64, (mut a, mut b): (f64, f64)) -> (f64, f64) {
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..60 {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    let u = 0.5 * (a + b);
    (u, f(u))
}

/// A temperature that moves through a recording: `t0` at its first sample and `t1` at its
/// last, geometrically in between (`t0^(1−τ)·t1^τ` at the share τ of the recording read).
/// Scores early in a recording say little, late ones much; one temperature for all of them
/// leaves the last too timid or the first too sure.
pub(super) fn ramp(t: [f64; 2], tau: f64) -> f64 {
    let tau = tau.clamp(0.0, 1.0);
    (t[0].ln() * (1.0 - tau) + t[1].ln() * tau).exp()
}

/// The [`ramp`] in [0.1, 1000]² that minimises the log loss of `scores` (`[samples][classes]`,
/// each read at the share `tau` of its recording) with their `labels`, from the constant
/// temperature `start`: golden-section searches on the logarithm of each end in turn, until
/// neither moves the loss by 1e-9.
pub(super) fn fit_ramp(
    scores: &[Vec<f64>],
    labels: &[usize],
    tau: &[f64],
    start: f64,
) -> ([f64; 2], f64) {
    let loss = |t: [f64; 2]| {
        scores
            .iter()
            .zip(labels)
            .zip(tau)
            .map(|((s, &l), &x)| -softmax(s, ramp(t, x))[l].max(1e-300).ln())
            .sum::<f64>()
            / scores.len().max(1) as f64
    };
    let range = (0.1f64.ln(), 1000f64.ln());
    let mut t = [start, start];
    let mut best = loss(t);
    for _ in 0..6 {
        let before = best;
        for end in 0..2 {
            let (u, l) = golden(
                |u| {
                    let mut x = t;
                    x[end] = u.exp();
                    loss(x)
                },
                range,
            );
            if l < best {
                t[end] = u.exp();
                best = l;
            }
        }
        if before - best < 1e-9 {
            break;
        }
    }
    (t, best)
}

/// The split-conformal 90% half-width of held-out absolute errors `errors` (sorted here): the
/// ⌈0.9·(n + 1)⌉-th smallest, which a new run's error exceeds with probability at most 10%
/// when it is exchangeable with the held-out runs; `None` without errors.
pub(super) fn conformal_half_width(errors: &mut [f64]) -> Option<f64> {
    if errors.is_empty() {
        return None;
    }
    errors.sort_by(|a, b| a.total_cmp(b));
    let k = ((0.9 * (errors.len() + 1) as f64).ceil() as usize).min(errors.len());
    Some(errors[k - 1])
}

/// The training runs used as the classifier's centres (Nyström landmarks): all of them up to
/// [`LANDMARKS`], else that many spread evenly over them.
fn landmarks(n: usize) -> Vec<usize> {
    if n <= LANDMARKS {
        (0..n).collect()
    } else {
        (0..LANDMARKS).map(|j| j * n / LANDMARKS).collect()
    }
}

/// The kernel between the rows of `a` and of `b` with length scale `length`.
fn cross_kernel(a: &[&Vec<f64>], b: &[&Vec<f64>], length: f64) -> DMatrix<f64> {
    let g = 1.0 / (2.0 * length * length);
    DMatrix::from_fn(a.len(), b.len(), |i, j| (-dist2(a[i], b[j]) * g).exp())
}

/// Dual weights on the centres for each ridge of [`RIDGES`] (`None` where the system is not
/// positive definite): the minimiser of `|Y − K_nm α|² + ridge·αᵀ K_mm α`, `[classes][centres]`.
fn nystrom_weights(
    knm: &DMatrix<f64>,
    kmm: &DMatrix<f64>,
    y: &DMatrix<f64>,
) -> Vec<Option<Vec<Vec<f64>>>> {
    let m = kmm.nrows();
    let knm_t = knm.transpose();
    let mut a = DMatrix::zeros(m, m);
    crate::linalg::add_gram_lower(&mut a, &knm_t, knm);
    crate::linalg::mirror_lower(&mut a);
    let b = knm_t * y;
    RIDGES
        .iter()
        .map(|&r| {
            let mut s = &a + kmm * r;
            let jitter = 1e-10 * (0..m).map(|i| s[(i, i)]).sum::<f64>() / m as f64;
            for i in 0..m {
                s[(i, i)] += jitter;
            }
            let alpha = crate::linalg::cholesky(s)?.solve(&b);
            Some(
                (0..y.ncols())
                    .map(|c| alpha.column(c).iter().copied().collect())
                    .collect(),
            )
        })
        .collect()
}

impl Classifier {
    /// Fits on points `z` with class `labels` of `classes` classes, by kernel ridge regression
    /// of each class's indicator on at most [`LANDMARKS`] centres (Nyström's approximation,
    /// so that the cost grows linearly with the runs): the length scale and ridge by the
    /// held-out log loss (every [`HOLD`]-th run held out, each setting at its best temperature),
    /// the temperature on those held-out scores, then the weights on every run. Returns it and
    /// the held-out log loss.
    fn fit(z: &[Vec<f64>], labels: &[usize], classes: usize) -> Result<(Classifier, f64)> {
        let fail = |d: &str| Error::Fit {
            method: "shape-krr".into(),
            detail: d.into(),
        };
        let onehot = |idx: &[usize]| {
            DMatrix::from_fn(idx.len(), classes, |i, c| {
                if labels[idx[i]] == c {
                    1.0
                } else {
                    0.0
                }
            })
        };
        let med = median_distance(z);
        let (fit_i, held_i): (Vec<usize>, Vec<usize>) = (0..z.len()).partition(|i| i % HOLD != 0);
        let zf: Vec<&Vec<f64>> = fit_i.iter().map(|&i| &z[i]).collect();
        let zh: Vec<&Vec<f64>> = held_i.iter().map(|&i| &z[i]).collect();
        let centres: Vec<&Vec<f64>> = landmarks(zf.len()).into_iter().map(|i| zf[i]).collect();
        let yf = onehot(&fit_i);
        let held_labels: Vec<usize> = held_i.iter().map(|&i| labels[i]).collect();
        let tried: Vec<(f64, f64, f64, f64)> = LENGTHS
            .par_iter()
            .flat_map_iter(|l| {
                let length = l * med;
                let knm = cross_kernel(&zf, &centres, length);
                let kmm = cross_kernel(&centres, &centres, length);
                let khm = cross_kernel(&zh, &centres, length);
                nystrom_weights(&knm, &kmm, &yf)
                    .into_iter()
                    .zip(RIDGES)
                    .filter_map(|(alpha, r)| {
                        let alpha = alpha?;
                        let scores: Vec<Vec<f64>> = (0..zh.len())
                            .map(|h| {
                                alpha
                                    .iter()
                                    .map(|a| {
                                        a.iter().enumerate().map(|(j, w)| w * khm[(h, j)]).sum()
                                    })
                                    .collect()
                            })
                            .collect();
                        let (t, loss) = fit_temperature(&scores, &held_labels);
                        Some((loss, length, r, t))
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        let &(held_loss, length, ridge, temperature) = tried
            .iter()
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .ok_or_else(|| fail("no kernel setting gave a positive definite system"))?;
        // Every run, with the chosen settings.
        let all: Vec<&Vec<f64>> = z.iter().collect();
        let centres: Vec<&Vec<f64>> = landmarks(z.len()).into_iter().map(|i| all[i]).collect();
        let knm = cross_kernel(&all, &centres, length);
        let kmm = cross_kernel(&centres, &centres, length);
        let idx: Vec<usize> = (0..z.len()).collect();
        let k = RIDGES.iter().position(|r| *r == ridge).unwrap_or(0);
        let alpha = nystrom_weights(&knm, &kmm, &onehot(&idx))
            .swap_remove(k)
            .ok_or_else(|| fail("kernel matrix not positive definite"))?;
        Ok((
            Classifier {
                z: centres.into_iter().cloned().collect(),
                alpha,
                length,
                temperature,
            },
            held_loss,
        ))
    }

    /// Class probabilities at `z`.
    fn probabilities(&self, z: &[f64]) -> Vec<f64> {
        let g = 1.0 / (2.0 * self.length * self.length);
        let k: Vec<f64> = self.z.iter().map(|t| (-dist2(t, z) * g).exp()).collect();
        let scores: Vec<f64> = self.alpha.iter().map(|a| dot(&k, a)).collect();
        softmax(&scores, self.temperature)
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// What the training runs show of each channel's typical level, shared by the shape estimators.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Scales {
    /// Per channel: the floor below which it is silent, and its median RMS over training runs.
    pub floors: [f64; 5],
    pub medians: [f64; 5],
    /// The base force below which the wrench's direction and arm are faded out, N, and the
    /// arm's typical value over the training runs, m.
    pub force_floor: f64,
    pub arm_scale: f64,
}

impl Scales {
    /// The levels of `training` (every whisker of every run); `method` names the estimator in
    /// errors.
    pub fn of(training: &[ShapeSample], method: &str) -> Result<Scales> {
        let fail = |d: String| Error::Fit {
            method: method.into(),
            detail: d,
        };
        let mut m = Scales::default();
        // Each channel's median RMS over the training runs' whiskers, and its floor.
        for (c, channel) in CHANNELS.iter().enumerate() {
            let mut levels: Vec<f64> = training
                .iter()
                .flat_map(|s| s.whiskers.iter().map(move |w| rms_of(w)[c]))
                .collect();
            levels.sort_by(|a, b| a.total_cmp(b));
            let median = levels.get(levels.len() / 2).copied().unwrap_or(0.0);
            if !(median > 0.0 && median.is_finite()) {
                return Err(fail(format!(
                    "channel {channel} is silent in most training runs"
                )));
            }
            m.medians[c] = median;
            m.floors[c] = FLOOR * median;
        }
        // The force floor: a share of the typical peak base force; the arm's scale: its median
        // where the force is above the floor.
        let mut peaks: Vec<f64> = training
            .iter()
            .flat_map(|s| s.whiskers.iter())
            .map(|w| {
                w[3].iter()
                    .zip(&w[4])
                    .map(|(a, b)| a.hypot(*b))
                    .fold(0.0, f64::max)
            })
            .collect();
        peaks.sort_by(|a, b| a.total_cmp(b));
        m.force_floor = FORCE_FLOOR * peaks[peaks.len() / 2];
        let mut arms: Vec<f64> = training
            .iter()
            .flat_map(|s| s.whiskers.iter())
            .flat_map(|w| {
                (0..w[2].len()).filter_map(|k| {
                    let f = w[3][k].hypot(w[4][k]);
                    (f > m.force_floor).then(|| (w[2][k] / f).abs())
                })
            })
            .collect();
        arms.sort_by(|a, b| a.total_cmp(b));
        m.arm_scale = arms.get(arms.len() / 2).copied().unwrap_or(1.0);
        if !(m.force_floor > 0.0 && m.arm_scale > 0.0 && m.arm_scale.is_finite()) {
            return Err(fail("the training runs' base forces are zero".into()));
        }
        Ok(m)
    }

    /// The contact's geometry at one sample of the base wrench: the base force's direction
    /// (for a frictionless contact, the object's surface normal where it touches) and the
    /// moment arm `m0/|f|` in units of its typical value (how far out it touches), faded out
    /// where the force is weak.
    pub fn geometry(&self, m0: f64, fx: f64, fy: f64) -> [f64; 3] {
        let f2 = fx * fx + fy * fy;
        if f2 > 0.0 {
            let f = f2.sqrt();
            let fade = f2 / (f2 + self.force_floor * self.force_floor);
            let arm = (m0 / f / self.arm_scale).clamp(-3.0, 3.0);
            [fade * fx / f, fade * fy / f, fade * arm]
        } else {
            [0.0; 3]
        }
    }
}

/// The shape estimator `shape-krr` (see the module's documentation).
#[derive(Debug, Clone, Default)]
pub struct ShapeKrr {
    /// Class names, in order.
    classes: Vec<String>,
    /// Each class's unknowns' names.
    names: Vec<Vec<String>>,
    /// Whiskers and samples per whisker read.
    whiskers: usize,
    samples: usize,
    /// The channels' typical levels over the training runs.
    scales: Scales,
    /// Principal axes of the normalised series.
    pca: Pca,
    /// Weight of the amplitude features.
    weight: f64,
    classifier: Classifier,
    /// Each class's pose regression.
    poses: Vec<Regression>,
}

/// A whisker's per-channel RMS, `[CHANNELS]`.
pub(super) fn rms_of(series: &[Vec<f64>]) -> [f64; 5] {
    std::array::from_fn(|c| {
        let ch = &series[c];
        (ch.iter().map(|v| v * v).sum::<f64>() / ch.len().max(1) as f64).sqrt()
    })
}

impl ShapeKrr {
    /// The method's name.
    pub const NAME: &'static str = "shape-krr";

    /// Normalised series and amplitude features of one recording (`[whiskers][CHANNELS]
    /// [samples]`).
    fn features(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<(Vec<f64>, Vec<f64>)> {
        if whiskers.len() != self.whiskers {
            return Err(Error::Observation(format!(
                "{} whiskers where {} was trained on {}",
                whiskers.len(),
                Self::NAME,
                self.whiskers
            )));
        }
        let mut x = Vec::with_capacity(self.whiskers * CHANNELS.len() * self.samples);
        let mut logs = Vec::with_capacity(self.whiskers);
        for (w, series) in whiskers.iter().enumerate() {
            if series.len() < CHANNELS.len()
                || series.iter().any(|ch| ch.len() != self.samples)
                || series.iter().flatten().any(|v| !v.is_finite())
            {
                return Err(Error::Observation(format!(
                    "whisker {} needs the channels {} of {} finite samples each",
                    w + 1,
                    CHANNELS.join(", "),
                    self.samples
                )));
            }
            let rms = rms_of(series);
            let level: [f64; 5] = std::array::from_fn(|c| rms[c].max(self.scales.floors[c]));
            for c in 0..CHANNELS.len() {
                x.extend(series[c].iter().map(|v| v / level[c]));
            }
            logs.push(std::array::from_fn::<f64, 5, _>(|c| {
                (level[c] / self.scales.medians[c]).ln()
            }));
            // The contact's geometry at every sample (see [`Scales::geometry`]).
            let mut geometry = [
                Vec::with_capacity(self.samples),
                Vec::with_capacity(self.samples),
                Vec::with_capacity(self.samples),
            ];
            for ((m0, fx), fy) in series[2].iter().zip(&series[3]).zip(&series[4]) {
                let g = self.scales.geometry(*m0, *fx, *fy);
                for (to, v) in geometry.iter_mut().zip(g) {
                    to.push(v);
                }
            }
            for g in geometry {
                x.extend(g);
            }
        }
        // Per whisker the moment arm and the wrench's direction; with several whiskers each
        // channel's level relative to the array's mean.
        let mut amps = Vec::new();
        for l in &logs {
            amps.push(l[2] - l[4]);
            amps.push(l[3] - l[4]);
        }
        if self.whiskers > 1 {
            for c in 0..CHANNELS.len() {
                let mean = logs.iter().map(|l| l[c]).sum::<f64>() / logs.len() as f64;
                amps.extend(logs.iter().map(|l| l[c] - mean));
            }
        }
        Ok((x, amps))
    }

    /// The point of a recording in the regressions' space.
    fn point_of(&self, series: &[f64], amps: &[f64]) -> Vec<f64> {
        let w = self.weight * (self.samples as f64).sqrt();
        let mut z = self.pca.project(series);
        z.extend(amps.iter().map(|a| w * a));
        z
    }

    /// Fits on the runs `training` of `family` (every class represented).
    pub fn fit(family: &ShapeFamily, training: &[ShapeSample]) -> Result<ShapeKrr> {
        let fail = |d: &str| Error::Fit {
            method: Self::NAME.into(),
            detail: d.into(),
        };
        let classes = family.classes().len();
        for c in 0..classes {
            if training.iter().filter(|s| s.class == c).count() < 10 {
                return Err(fail(&format!(
                    "needs at least 10 training runs of every class (`{}` has fewer)",
                    family.classes()[c].name
                )));
            }
        }
        let first = &training[0];
        let mut m = ShapeKrr {
            classes: family.class_names().iter().map(|s| s.to_string()).collect(),
            names: family.unknown_names(),
            whiskers: first.whiskers.len(),
            samples: first.whiskers[0][0].len(),
            ..ShapeKrr::default()
        };
        m.scales = Scales::of(training, Self::NAME)?;
        let (x, amps): (Vec<Vec<f64>>, Vec<Vec<f64>>) = training
            .iter()
            .map(|s| m.features(&s.whiskers))
            .collect::<Result<Vec<_>>>()?
            .into_iter()
            .unzip();
        // Principal axes from at most PCA_RUNS runs spread over the training set.
        let step = x.len().div_ceil(PCA_RUNS).max(1);
        let sub: Vec<Vec<f64>> = x.iter().step_by(step).cloned().collect();
        m.pca = Pca::fit(&sub, COMPONENTS);
        let labels: Vec<usize> = training.iter().map(|s| s.class).collect();
        // The amplitudes' weight whose classifier predicts held-out runs best.
        let mut best: Option<(f64, f64, Vec<Vec<f64>>, Classifier)> = None;
        for &w in &WEIGHTS {
            m.weight = w;
            let z: Vec<Vec<f64>> = x.iter().zip(&amps).map(|(x, a)| m.point_of(x, a)).collect();
            let (classifier, loss) = Classifier::fit(&z, &labels, classes)?;
            if best.as_ref().is_none_or(|b| loss < b.0) {
                best = Some((loss, w, z, classifier));
            }
        }
        let (_, w, z, classifier) = best.expect("at least one weight");
        m.weight = w;
        m.classifier = classifier;
        // Each class's pose, on its own runs.
        m.poses = family
            .classes()
            .iter()
            .enumerate()
            .map(|(c, class)| {
                let idx: Vec<usize> = (0..training.len())
                    .filter(|&i| training[i].class == c)
                    .collect();
                let ranges = class.family.ranges();
                let zc: Vec<Vec<f64>> = idx.iter().map(|&i| z[i].clone()).collect();
                let y: Vec<Vec<f64>> = ranges
                    .iter()
                    .enumerate()
                    .map(|(u, [lo, hi])| {
                        idx.iter()
                            .map(|&i| (training[i].params[u] - lo) / (hi - lo))
                            .collect()
                    })
                    .collect();
                let inside: Vec<bool> = (0..idx.len())
                    .map(|i| y.iter().all(|t| (0.0..=1.0).contains(&t[i])))
                    .collect();
                let settings = Regression::choose(&zc, &y, &inside, &fail)?;
                Regression::finish(zc, &y, &inside, &settings, ranges, Spread::Constant, &fail)
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(m)
    }

    /// The class posterior and the most probable class's pose from one recording
    /// (`[whiskers][CHANNELS][samples]`, the whiskers it was trained on, in order).
    pub fn predict(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<ShapeEstimate> {
        if self.poses.is_empty() {
            return Err(Error::Fit {
                method: Self::NAME.into(),
                detail: "not fitted".into(),
            });
        }
        let (x, amps) = self.features(whiskers)?;
        let z = self.point_of(&x, &amps);
        let p = self.classifier.probabilities(&z);
        let best = (0..p.len()).fold(0, |b, c| if p[c] > p[b] { c } else { b });
        let reg = &self.poses[best];
        let pose = reg
            .point(&z)
            .into_iter()
            .zip(&reg.heads)
            .zip(&self.names[best])
            .map(|((m, h), n)| (n.clone(), Estimate::normal(m, h.std)))
            .collect();
        Ok(ShapeEstimate {
            class: self.classes.iter().cloned().zip(p).collect(),
            best,
            pose,
            misfit: None,
        })
    }

    /// Fitted settings worth reporting.
    pub fn settings(&self) -> Vec<(String, f64)> {
        vec![
            ("components".into(), self.pca.axes.len() as f64),
            ("amplitude_weight".into(), self.weight),
            ("class_length".into(), self.classifier.length),
            ("class_temperature".into(), self.classifier.temperature),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_temperature_fit_sharpens_confident_scores_and_softens_wrong_ones() {
        // Scores that rank the truth first every time deserve a high temperature…
        let right: Vec<Vec<f64>> = (0..20)
            .map(|i| {
                let mut s = vec![0.0; 3];
                s[i % 3] = 1.0;
                s
            })
            .collect();
        let labels: Vec<usize> = (0..20).map(|i| i % 3).collect();
        let (t, loss) = fit_temperature(&right, &labels);
        assert!(t > 100.0 && loss < 0.01, "{t} {loss}");
        // …scores that are right only half the time a low one.
        let half: Vec<usize> = (0..20)
            .map(|i| if i % 2 == 0 { i % 3 } else { (i + 1) % 3 })
            .collect();
        let (t, _) = fit_temperature(&right, &half);
        assert!(t < 5.0, "{t}");
        let p = softmax(&[1.0, 0.0, 0.0], 2.0);
        assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-12 && p[0] > p[1]);
    }

    #[test]
    fn conformal_half_width_is_the_held_out_quantile() {
        // ⌈0.9·(n + 1)⌉-th smallest: the 10th of 10, the 90th of 99, whatever the order.
        let mut e: Vec<f64> = (1..=10).rev().map(f64::from).collect();
        assert_eq!(conformal_half_width(&mut e), Some(10.0));
        let mut e: Vec<f64> = (1..=99).map(f64::from).collect();
        assert_eq!(conformal_half_width(&mut e), Some(90.0));
        assert_eq!(conformal_half_width(&mut []), None);
    }
}
