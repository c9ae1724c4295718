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
        "krr"
    }

    fn budget(&self) -> Budget {
        Budget::Free
    }

    fn channels(&self) -> Vec<usize> {
        (0..CHANNELS.len()).collect()
    }

    fn fit(&mut self, training: &Training) -> Result<()> {
        let fail = |detail: &str| Error::Fit {
            method: "krr".into(),
            detail: detail.into(),
        };
        let s: &[Sample] = &training.samples;
        if s.len() < 10 {
            return Err(fail("needs at least 10 training runs"));
        }
        if let Some(k) = latest(training) {
            *self = k;
            return Ok(());
        }
        let channels: Vec<usize> = (0..CHANNELS.len()).collect();
        self.scales = channel_scales(s, &channels);
        self.ranges = training.family.ranges();
        let x: Vec<Vec<f64>> = s
            .iter()
            .map(|r| flatten(&r.series, &channels, &self.scales))
            .collect::<Result<_>>()?;
        let dim = x[0].len();
        self.mean = (0..dim)
            .map(|k| x.iter().map(|r| r[k]).sum::<f64>() / x.len() as f64)
            .collect();
        self.axes = principal_axes(&x, &self.mean, COMPONENTS);
        let z: Vec<Vec<f64>> = x.iter().map(|r| self.project(r)).collect();
        // Targets scaled to [0, 1], `[unknowns][runs]`.
        let y: Vec<Vec<f64>> = self
            .ranges
            .iter()
            .enumerate()
            .map(|(u, [lo, hi])| s.iter().map(|r| (r.params[u] - lo) / (hi - lo)).collect())
            .collect();
        let med = median_distance(&z);
        let unknowns = self.ranges.len();
        // Runs outside the range (beyond its edges, to keep estimates there unbiased) are fitted
        // on but neither score the settings nor calibrate the std: their clipped estimates miss
        // by their distance to the range.
        let inside: Vec<bool> = (0..s.len())
            .map(|i| y.iter().all(|t| (0.0..=1.0).contains(&t[i])))
            .collect();

        // Choose ℓ and the ridge per unknown on every HOLD-th run, fitted on the rest.
        let (fit_i, held_i): (Vec<usize>, Vec<usize>) = (0..s.len()).partition(|i| i % HOLD != 0);
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
                let pairs: Vec<(f64, f64)> = (0..z.len())
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
                method: "krr".into(),
                detail: "not fitted".into(),
            });
        }
        let channels: Vec<usize> = (0..CHANNELS.len()).collect();
        let x = flatten(obs, &channels, &self.scales)?;
        let p = self.point(&self.project(&x));
        Ok(p.iter()
            .zip(&self.heads)
            .map(|(m, h)| Estimate::normal(*m, h.std))
            .collect())
    }

    fn settings(&self) -> Vec<(String, f64)> {
        let mut s = vec![("components".into(), self.axes.len() as f64)];
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
