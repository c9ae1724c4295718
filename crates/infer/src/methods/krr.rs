//! Kernel ridge regression (RBF kernel) on principal components of normalised series.

use crate::error::{Error, Result};
use crate::experiment::{Sample, CHANNELS};
use crate::features::{channel_scales, coverage_factor_at, dist2, flatten};
use crate::method::{Budget, Estimate, Method, Training, Z90};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use std::sync::Mutex;

/// Principal components kept.
const COMPONENTS: usize = 24;
/// Principal components kept of [`Features::Invariant`]'s shapes: chosen on stand-in whiskers
/// 11–13 with `--randomise` (12, 24, 40 and 64 components: 1.13, 0.83, 0.70 and 0.72 mm mean
/// distance error; shapes normalised one by one spread over more components than raw series).
const INVARIANT_COMPONENTS: usize = 40;
/// Length scales tried, as multiples of the median distance between training runs.
const LENGTHS: [f64; 5] = [0.25, 0.5, 1.0, 2.0, 4.0];
/// Ridges tried (the kernel's diagonal is 1).
const RIDGES: [f64; 6] = [1e-6, 1e-4, 1e-3, 1e-2, 3e-2, 1e-1];
/// Share of the leave-one-out errors that the 90% intervals are widened to hold (above 0.9:
/// the training runs lie inside the range, away from its edges, more often than the grid's
/// runs do).
const QUANTILE: f64 = 0.92;
/// Every `HOLD`-th training run is held out while the hyper-parameters are chosen.
const HOLD: usize = 5;

/// Weights of the amplitude ratios tried with [`Features::Invariant`], per unit of a channel's
/// RMS (0: the shapes alone).
const WEIGHTS: [f64; 3] = [0.0, 1.0, 3.0];

/// What the regression sees of a recording.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Features {
    /// Every channel divided by its scale over the training runs: amplitudes as recorded.
    #[default]
    Raw,
    /// Every channel divided by its own RMS over the recording (the shape and timing of each
    /// signal, blind to its sensor's gain and the whisker's stiffness), followed by the log
    /// ratios of the base wrench's RMS amplitudes (`m0/fy`, `fx/fy`: the moment arm, blind to
    /// the stiffness and to a common scale of the wrench sensor), weighted by a factor chosen on
    /// held-out training runs.
    Invariant,
}

/// Per unknown: the held-out runs' mean absolute error (scaled to the range), ℓ and the ridge.
type Settings = Vec<(f64, f64, f64)>;

/// One unknown's regression: `f(z) = lo + (hi − lo)·Σ α_i exp(−|z − z_i|²/(2ℓ²))`.
#[derive(Debug, Clone, Default)]
struct Head {
    /// Length scale in component space.
    length: f64,
    /// Ridge.
    ridge: f64,
    /// Dual weights `[runs]`.
    alpha: Vec<f64>,
    /// Std, SI.
    std: f64,
}

/// Kernel ridge regression per unknown (scaled to [0, 1] over its range) on `z`, the first
/// principal components of the normalised series, with the estimate clipped to the range. Each
/// unknown has its own ℓ and ridge, chosen on every fifth training run (fitted on the rest); its
/// std is constant, set so that 90% intervals cover 90% of the training runs' leave-one-out
/// errors. Training runs outside the range are fitted on but neither choose the settings nor
/// calibrate the std.
#[derive(Debug, Clone, Default)]
pub struct Krr {
    /// Channel scales, `[CHANNELS]`.
    scales: Vec<f64>,
    /// Mean feature vector.
    mean: Vec<f64>,
    /// Principal axes `[COMPONENTS][features]`.
    axes: Vec<Vec<f64>>,
    /// Training points in component space `[runs][COMPONENTS]`.
    z: Vec<Vec<f64>>,
    /// Unknowns' ranges `[unknowns][lo, hi]`.
    ranges: Vec<[f64; 2]>,
    /// Per unknown.
    heads: Vec<Head>,
    /// What the regression sees.
    features: Features,
    /// Invariant features: the weight of the amplitude ratios, per unit of a channel's RMS.
    weight: f64,
}

/// The latest fit and the runs it learnt from. Fitting is deterministic, so a second fit on the
/// same runs (`krr-local`'s first stage learns from the same runs as `krr` in one evaluation)
/// takes the first's result.
static LATEST: Mutex<Option<(u64, Vec<Sample>, Krr)>> = Mutex::new(None);

/// The latest fit, if it learnt from exactly `training`'s runs.
fn latest(training: &Training) -> Option<Krr> {
    let l = LATEST.lock().ok()?;
    let (e, s, k) = l.as_ref()?;
    (*e == training.family.digest() && *s == training.samples).then(|| k.clone())
}

/// Kernel matrix of `z` with length scale `length`, without ridge.
fn kernel(z: &[Vec<f64>], length: f64) -> DMatrix<f64> {
    let n = z.len();
    let g = 1.0 / (2.0 * length * length);
    let mut k = DMatrix::<f64>::zeros(n, n);
    for i in 0..n {
        for j in 0..=i {
            let v = (-dist2(&z[i], &z[j]) * g).exp();
            k[(i, j)] = v;
            k[(j, i)] = v;
        }
    }
    k
}

/// `(K + ridge·I)⁻¹ y` for each target column of `y`, or `None` if not positive definite.
fn solve(k: &DMatrix<f64>, ridge: f64, y: &[Vec<f64>]) -> Option<Vec<Vec<f64>>> {
    let n = k.nrows();
    let mut a = k.clone();
    for i in 0..n {
        a[(i, i)] += ridge;
    }
    let chol = a.cholesky()?;
    Some(
        y.iter()
            .map(|t| {
                chol.solve(&DVector::from_column_slice(t))
                    .iter()
                    .copied()
                    .collect()
            })
            .collect(),
    )
}

impl Krr {
    /// An unfitted kernel ridge regression.
    pub fn new() -> Krr {
        Krr::default()
    }

    /// An unfitted kernel ridge regression on [`Features::Invariant`].
    pub fn invariant() -> Krr {
        Krr {
            features: Features::Invariant,
            ..Krr::default()
        }
    }

    fn project(&self, x: &[f64]) -> Vec<f64> {
        self.axes
            .iter()
            .map(|a| {
                a.iter()
                    .zip(x)
                    .zip(&self.mean)
                    .map(|((a, x), m)| a * (x - m))
                    .sum()
            })
            .collect()
    }

    /// Chooses ℓ and the ridge per unknown for the training runs' points `z` with targets `y`
    /// (`[unknowns][runs]`, scaled to [0, 1]): per unknown, the held-out runs' mean absolute
    /// error, ℓ and the ridge.
    fn choose(
        z: &[Vec<f64>],
        y: &[Vec<f64>],
        inside: &[bool],
        fail: &(dyn Fn(&str) -> Error + Sync),
    ) -> Result<Settings> {
        let med = median_distance(z);
        let unknowns = y.len();

        // Choose ℓ and the ridge per unknown on every HOLD-th run, fitted on the rest.
        let (fit_i, held_i): (Vec<usize>, Vec<usize>) = (0..z.len()).partition(|i| i % HOLD != 0);
        let held_i: Vec<usize> = held_i.into_iter().filter(|&i| inside[i]).collect();
        if held_i.is_empty() {
            return Err(fail("no held-out run inside the range"));
        }
        let zf: Vec<Vec<f64>> = fit_i.iter().map(|&i| z[i].clone()).collect();
        let yf: Vec<Vec<f64>> = y
            .iter()
            .map(|t| fit_i.iter().map(|&i| t[i]).collect())
            .collect();
        // Held-out errors `[lengths][ridges]` → per unknown (None where not positive definite),
        // the length scales in parallel.
        let errors: Vec<Vec<Option<Vec<f64>>>> = LENGTHS
            .par_iter()
            .map(|l| {
                let length = l * med;
                let k = kernel(&zf, length);
                let g = 1.0 / (2.0 * length * length);
                let kx: Vec<Vec<f64>> = held_i
                    .iter()
                    .map(|&h| zf.iter().map(|t| (-dist2(t, &z[h]) * g).exp()).collect())
                    .collect();
                RIDGES
                    .iter()
                    .map(|&r| {
                        let alpha = solve(&k, r, &yf)?;
                        Some(
                            (0..unknowns)
                                .map(|u| {
                                    held_i
                                        .iter()
                                        .zip(&kx)
                                        .map(|(&h, kh)| {
                                            let p: f64 =
                                                kh.iter().zip(&alpha[u]).map(|(a, b)| a * b).sum();
                                            (p.clamp(0.0, 1.0) - y[u][h]).abs()
                                        })
                                        .sum()
                                })
                                .collect(),
                        )
                    })
                    .collect()
            })
            .collect();
        let mut best = vec![(f64::INFINITY, med, RIDGES[0]); unknowns];
        for (l, per_ridge) in LENGTHS.iter().zip(&errors) {
            for (r, err) in RIDGES.iter().zip(per_ridge) {
                let Some(err) = err else {
                    continue;
                };
                for u in 0..unknowns {
                    if err[u] < best[u].0 {
                        best[u] = (err[u], l * med, *r);
                    }
                }
            }
        }
        for b in &mut best {
            b.0 /= held_i.len() as f64;
        }
        Ok(best)
    }

    /// Fits the heads on every training run's point `z` with the settings `best` (from
    /// [`Krr::choose`]).
    fn finish(
        &mut self,
        z: Vec<Vec<f64>>,
        y: &[Vec<f64>],
        inside: &[bool],
        best: &Settings,
        fail: &(dyn Fn(&str) -> Error + Sync),
    ) -> Result<()> {
        // Final weights on every run (the unknowns in parallel); leave-one-out errors calibrate
        // the std.
        let heads: Vec<Result<Head>> = best
            .par_iter()
            .enumerate()
            .map(|(u, &(_, length, ridge))| {
                let mut a = kernel(&z, length);
                for i in 0..z.len() {
                    a[(i, i)] += ridge;
                }
                let chol = a
                    .cholesky()
                    .ok_or_else(|| fail("kernel matrix not positive definite"))?;
                let alpha: Vec<f64> = chol
                    .solve(&DVector::from_column_slice(&y[u]))
                    .iter()
                    .copied()
                    .collect();
                // (A⁻¹)_ii = Σ_k (L⁻¹)_ki², from the inverse of the Cholesky factor alone.
                let n = z.len();
                let linv = chol
                    .l()
                    .solve_lower_triangular(&DMatrix::<f64>::identity(n, n))
                    .ok_or_else(|| fail("kernel matrix not positive definite"))?;
                let inv_diag: Vec<f64> = (0..n)
                    .map(|i| linv.column(i).iter().map(|v| v * v).sum())
                    .collect();
                let [lo, hi] = self.ranges[u];
                let pairs: Vec<(f64, f64)> = (0..n)
                    .filter(|&i| inside[i])
                    .map(|i| {
                        // f_{−i}(z_i) = y_i − α_i / (A⁻¹)_ii.
                        let loo = (y[u][i] - alpha[i] / inv_diag[i]).clamp(0.0, 1.0);
                        ((loo - y[u][i]) * (hi - lo), 1.0 / Z90)
                    })
                    .collect();
                Ok(Head {
                    length,
                    ridge,
                    alpha,
                    std: coverage_factor_at(&pairs, QUANTILE) / Z90,
                })
            })
            .collect();
        self.heads = heads.into_iter().collect::<Result<_>>()?;
        self.z = z;
        Ok(())
    }

    /// What the regression reads of `obs` (channel-major, every channel present and as long as
    /// the first): the series, each channel scaled, and the amplitude ratios (none for
    /// [`Features::Raw`]).
    fn features_of(&self, obs: &[Vec<f64>]) -> Result<(Vec<f64>, Vec<f64>)> {
        let channels: Vec<usize> = (0..CHANNELS.len()).collect();
        match self.features {
            Features::Raw => Ok((flatten(obs, &channels, &self.scales)?, Vec::new())),
            Features::Invariant => {
                // Every channel present and as long as the first, or a clear error.
                let mut x = flatten(obs, &channels, &vec![1.0; channels.len()])?;
                let n = x.len() / channels.len();
                let rms: Vec<f64> = x
                    .chunks(n)
                    .map(|ch| (ch.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt())
                    .collect();
                for (c, r) in rms.iter().enumerate() {
                    if !(*r > 0.0 && r.is_finite()) {
                        return Err(Error::Observation(format!(
                            "channel {} is zero throughout (or not finite): its shape is undefined",
                            CHANNELS[c]
                        )));
                    }
                    x[c * n..(c + 1) * n].iter_mut().for_each(|v| *v /= r);
                }
                // The moment arm and the wrench's direction.
                let [m0, fx, fy] = [rms[2], rms[3], rms[4]];
                Ok((x, vec![(m0 / fy).ln(), (fx / fy).ln()]))
            }
        }
    }

    /// The point of `obs` in the regression's space: the principal components of its series,
    /// followed by its amplitude ratios, each worth `weight` RMS units per sample.
    fn point_of(&self, series: &[f64], ratios: &[f64]) -> Vec<f64> {
        let w = self.weight * ((series.len() / CHANNELS.len()) as f64).sqrt();
        let mut z = self.project(series);
        z.extend(ratios.iter().map(|r| w * r));
        z
    }

    /// Estimate of every unknown at `z`, clipped to its range.
    fn point(&self, z: &[f64]) -> Vec<f64> {
        self.heads
            .iter()
            .zip(&self.ranges)
            .map(|(h, [lo, hi])| {
                let g = 1.0 / (2.0 * h.length * h.length);
                let s: f64 = self
                    .z
                    .iter()
                    .zip(&h.alpha)
                    .map(|(t, a)| a * (-dist2(t, z) * g).exp())
                    .sum();
                lo + (hi - lo) * s.clamp(0.0, 1.0)
            })
            .collect()
    }
}

/// The leading `count` principal axes of the rows of `x` about `mean` (through the eigenvectors
/// of the runs' Gram matrix, cheaper than the features' covariance when runs are fewer).
fn principal_axes(x: &[Vec<f64>], mean: &[f64], count: usize) -> Vec<Vec<f64>> {
    let n = x.len();
    let c: Vec<Vec<f64>> = x
        .iter()
        .map(|r| r.iter().zip(mean).map(|(a, m)| a - m).collect())
        .collect();
    // The Gram matrix C Cᵀ as one matrix product.
    let cm = DMatrix::from_fn(n, mean.len(), |i, j| c[i][j]);
    let g = &cm * cm.transpose();
    let eig = g.symmetric_eigen();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    order
        .into_iter()
        .take(count)
        .filter(|&k| eig.eigenvalues[k] > 1e-12)
        .map(|k| {
            // Axis = Xᵀu / |Xᵀu|.
            let u = eig.eigenvectors.column(k);
            let mut a = vec![0.0; mean.len()];
            for (i, row) in c.iter().enumerate() {
                for (aj, xj) in a.iter_mut().zip(row) {
                    *aj += u[i] * xj;
                }
            }
            let norm = a.iter().map(|v| v * v).sum::<f64>().sqrt();
            a.iter().map(|v| v / norm).collect()
        })
        .collect()
}

/// Median pairwise distance among (at most the first 200) points.
fn median_distance(z: &[Vec<f64>]) -> f64 {
    let m = z.len().min(200);
    let mut d = Vec::new();
    for i in 0..m {
        for j in 0..i {
            d.push(dist2(&z[i], &z[j]).sqrt());
        }
    }
    d.sort_by(|a, b| a.total_cmp(b));
    d.get(d.len() / 2).copied().unwrap_or(1.0).max(1e-12)
}

impl Method for Krr {
    fn name(&self) -> &'static str {
        match self.features {
            Features::Raw => "krr",
            Features::Invariant => "krr-invariant",
        }
    }

    fn budget(&self) -> Budget {
        Budget::Free
    }

    fn channels(&self) -> Vec<usize> {
        (0..CHANNELS.len()).collect()
    }

    fn fit(&mut self, training: &Training) -> Result<()> {
        let name = self.name();
        let fail = |detail: &str| Error::Fit {
            method: name.into(),
            detail: detail.into(),
        };
        let s: &[Sample] = &training.samples;
        if s.len() < 10 {
            return Err(fail("needs at least 10 training runs"));
        }
        if let Some(k) = latest(training).filter(|k| k.features == self.features) {
            *self = k;
            return Ok(());
        }
        let channels: Vec<usize> = (0..CHANNELS.len()).collect();
        self.scales = channel_scales(s, &channels);
        self.ranges = training.family.ranges();
        // Targets scaled to [0, 1], `[unknowns][runs]`.
        let y: Vec<Vec<f64>> = self
            .ranges
            .iter()
            .enumerate()
            .map(|(u, [lo, hi])| s.iter().map(|r| (r.params[u] - lo) / (hi - lo)).collect())
            .collect();
        // Runs outside the range (beyond its edges, to keep estimates there unbiased) are fitted
        // on but neither score the settings nor calibrate the std: their clipped estimates miss
        // by their distance to the range.
        let inside: Vec<bool> = (0..s.len())
            .map(|i| y.iter().all(|t| (0.0..=1.0).contains(&t[i])))
            .collect();
        let weights: &[f64] = match self.features {
            Features::Raw => &[0.0],
            Features::Invariant => &WEIGHTS,
        };
        let (x, ratios): (Vec<Vec<f64>>, Vec<Vec<f64>>) = s
            .iter()
            .map(|r| self.features_of(&r.series))
            .collect::<Result<Vec<_>>>()?
            .into_iter()
            .unzip();
        let dim = x[0].len();
        self.mean = (0..dim)
            .map(|k| x.iter().map(|r| r[k]).sum::<f64>() / x.len() as f64)
            .collect();
        let components = match self.features {
            Features::Raw => COMPONENTS,
            Features::Invariant => INVARIANT_COMPONENTS,
        };
        self.axes = principal_axes(&x, &self.mean, components);
        // The weight of the amplitude ratios whose settings predict the held-out runs best.
        let mut best: Option<(f64, f64, Vec<Vec<f64>>, Settings)> = None;
        for &w in weights {
            self.weight = w;
            let z: Vec<Vec<f64>> = x
                .iter()
                .zip(&ratios)
                .map(|(x, r)| self.point_of(x, r))
                .collect();
            let settings = Krr::choose(&z, &y, &inside, &fail)?;
            let held: f64 = settings.iter().map(|b| b.0).sum();
            if best.as_ref().map_or(true, |b| held < b.0) {
                best = Some((held, w, z, settings));
            }
        }
        let (_, w, z, settings) = best.expect("at least one weight");
        self.weight = w;
        self.finish(z, &y, &inside, &settings, &fail)?;
        if let Ok(mut l) = LATEST.lock() {
            *l = Some((
                training.family.digest(),
                training.samples.clone(),
                self.clone(),
            ));
        }
        Ok(())
    }

    fn predict(&self, obs: &[Vec<f64>]) -> Result<Vec<Estimate>> {
        if self.heads.is_empty() {
            return Err(Error::Fit {
                method: self.name().into(),
                detail: "not fitted".into(),
            });
        }
        let (x, ratios) = self.features_of(obs)?;
        if x.len() != self.mean.len() {
            return Err(Error::Observation(format!(
                "{} samples per channel where {} was trained on {}",
                x.len() / CHANNELS.len(),
                self.name(),
                self.mean.len() / CHANNELS.len()
            )));
        }
        let p = self.point(&self.point_of(&x, &ratios));
        Ok(p.iter()
            .zip(&self.heads)
            .map(|(m, h)| Estimate::normal(*m, h.std))
            .collect())
    }

    fn settings(&self) -> Vec<(String, f64)> {
        let mut s = vec![("components".into(), self.axes.len() as f64)];
        if self.features == Features::Invariant {
            s.push(("ratio_weight".into(), self.weight));
        }
        for (h, name) in self.heads.iter().zip(["d", "v"]) {
            s.push((format!("length_{name}"), h.length));
            s.push((format!("ridge_{name}"), h.ridge));
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 40 synthetic runs whose series depend smoothly on (d, v), shifted by `shift`.
    fn runs(shift: f64) -> Training {
        let samples = (0..40)
            .map(|k| {
                let d = 0.015 + 0.000_37 * k as f64;
                let v = 0.3 + 0.17 * (k % 7) as f64;
                Sample {
                    series: (0..CHANNELS.len())
                        .map(|c| {
                            (0..151)
                                .map(|t| {
                                    let t = t as f64 * 1e-3;
                                    (c as f64 + 1.0) * (t * (30.0 + 900.0 * d) * v + shift).sin()
                                })
                                .collect()
                        })
                        .collect(),
                    params: vec![d, v],
                }
            })
            .collect();
        Training {
            family: crate::Family::builtin("e2").unwrap(),
            samples,
            calibration: Vec::new(),
            noise: crate::experiment::Noise::NONE,
        }
    }

    #[test]
    fn invariant_features_ignore_each_angle_gain_and_a_common_wrench_scale() {
        let training = runs(0.0);
        let mut m = Krr::invariant();
        m.fit(&training).unwrap();
        assert_eq!(m.name(), "krr-invariant");
        let probe = &training.samples[17].series;
        let before = m.predict(probe).unwrap();
        let gains = [0.6, 1.7, 1.25, 1.25, 1.25];
        let scaled: Vec<Vec<f64>> = probe
            .iter()
            .zip(gains)
            .map(|(ch, g)| ch.iter().map(|x| x * g).collect())
            .collect();
        let after = m.predict(&scaled).unwrap();
        for (a, b) in before.iter().zip(&after) {
            assert!((a.mean - b.mean).abs() < 1e-9 * a.mean.abs(), "{a:?} {b:?}");
            assert_eq!(a.std, b.std);
        }
        // The raw regression reads the amplitudes.
        let mut raw = Krr::new();
        raw.fit(&training).unwrap();
        assert_ne!(raw.predict(probe).unwrap(), raw.predict(&scaled).unwrap());
        // A channel that is zero throughout has no shape.
        let mut flat = probe.clone();
        flat[3].iter_mut().for_each(|x| *x = 0.0);
        let err = m.predict(&flat).unwrap_err().to_string();
        assert!(err.contains("fx") && err.contains("zero"), "{err}");
        // A recording of another length than the training runs is refused, not truncated.
        let short: Vec<Vec<f64>> = probe.iter().map(|ch| ch[..100].to_vec()).collect();
        let err = m.predict(&short).unwrap_err().to_string();
        assert!(err.contains("100 samples"), "{err}");
    }

    #[test]
    fn a_refit_on_the_same_runs_matches_and_other_runs_are_not_mistaken_for_them() {
        let (a, b) = (runs(0.0), runs(0.7));
        let probe = &a.samples[11].series;
        let mut first = Krr::new();
        first.fit(&a).unwrap();
        let pa = first.predict(probe).unwrap();
        let mut other = Krr::new();
        other.fit(&b).unwrap();
        assert_ne!(other.predict(probe).unwrap(), pa);
        let mut again = Krr::new();
        again.fit(&a).unwrap();
        assert_eq!(again.predict(probe).unwrap(), pa);
        assert_eq!(again.settings(), first.settings());
    }
}
