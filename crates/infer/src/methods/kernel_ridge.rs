//! Kernel ridge regression with an RBF kernel, shared by the regressors that differ in what
//! they read of a recording (`krr`, `krr-invariant`, the shape estimators): principal axes of
//! feature vectors, the choice of length scale and ridge per unknown on held-out runs, the fit,
//! and intervals calibrated on leave-one-out errors.

use crate::error::{Error, Result};
use crate::features::{coverage_factor_at, dist2};
use crate::method::Z90;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

/// Length scales tried, as multiples of the median distance between training runs.
const LENGTHS: [f64; 5] = [0.25, 0.5, 1.0, 2.0, 4.0];
/// Ridges tried (the kernel's diagonal is 1).
pub(crate) const RIDGES: [f64; 6] = [1e-6, 1e-4, 1e-3, 1e-2, 3e-2, 1e-1];
/// Share of the leave-one-out errors that the 90% intervals are widened to hold (above 0.9:
/// the training runs lie inside the range, away from its edges, more often than the grid's
/// runs do).
const QUANTILE: f64 = 0.92;
/// Every `HOLD`-th training run is held out while the hyper-parameters are chosen.
pub(crate) const HOLD: usize = 5;

/// Per unknown: the held-out runs' mean absolute error (scaled to the range), ℓ and the ridge.
pub(crate) type Settings = Vec<(f64, f64, f64)>;

/// How a head's std is set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) enum Spread {
    /// One std for every point ([`Head::std`]): 90% intervals hold [`QUANTILE`] of the training
    /// runs' leave-one-out errors.
    #[default]
    Constant,
    /// Normalised intervals: the std at a point is `c·s(z)`, the regression's predictive spread
    /// read as a Gaussian process's, wider away from the training runs ([`Head::factor`]). It
    /// stores each head's Cholesky factor (`runs²` numbers) and costs one triangular solve
    /// (O(runs²)) per unknown and estimate: about 2 ms for both unknowns at 1731 runs.
    Gp,
}

/// One unknown's regression: `f(z) = lo + (hi − lo)·Σ α_i exp(−|z − z_i|²/(2ℓ²))`.
#[derive(Debug, Clone, Default)]
pub(crate) struct Head {
    /// Length scale in component space.
    pub length: f64,
    /// Ridge.
    pub ridge: f64,
    /// Dual weights `[runs]`.
    alpha: Vec<f64>,
    /// The constant std, SI ([`Spread::Constant`]).
    pub std: f64,
    /// [`Spread::Gp`]: the factor `c` (SI) of the normalised stds `c·s(z)`, where
    /// `s²(z) = 1 + λ − k_zᵀA⁻¹k_z` (`A = K + λI`) is the predictive variance of the Gaussian
    /// process whose posterior mean the regression is (up to a scale). On training run `i` left
    /// out it is `s_{−i}²(z_i) = 1/(A⁻¹)_ii`, and `c` makes 90% intervals `±Z90·c·s_{−i}(z_i)`
    /// hold [`QUANTILE`] of the leave-one-out errors (leave-one-out conformal, normalised score:
    /// the intervals widen where the training runs are sparse or far, as for a recording unlike
    /// them, and narrow where they are dense).
    pub factor: f64,
    /// [`Spread::Gp`]: the lower Cholesky factor `L` of `A = K + λI` (`[runs × runs]`), for
    /// `k_zᵀA⁻¹k_z = |L⁻¹k_z|²`; `None` for [`Spread::Constant`].
    chol: Option<DMatrix<f64>>,
}

/// Kernel ridge regression per unknown (scaled to [0, 1] over its range) on points `z`, with
/// the estimate clipped to the range. Each unknown has its own ℓ and ridge, chosen on every
/// [`HOLD`]-th training run (fitted on the rest); its std is constant, set so that 90% intervals
/// cover [`QUANTILE`] of the training runs' leave-one-out errors, or with [`Spread::Gp`] grows
/// with the predictive spread at the point, calibrated on the same errors. Training runs outside
/// the range are fitted on but neither choose the settings nor calibrate the std.
#[derive(Debug, Clone, Default)]
pub(crate) struct Regression {
    /// Training points `[runs][dims]`.
    z: Vec<Vec<f64>>,
    /// Unknowns' ranges `[unknowns][lo, hi]`.
    ranges: Vec<[f64; 2]>,
    /// Per unknown.
    pub heads: Vec<Head>,
}

/// Principal axes of feature vectors and the projection onto them.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Pca {
    /// Mean feature vector.
    pub mean: Vec<f64>,
    /// Principal axes `[components][features]`.
    pub axes: Vec<Vec<f64>>,
}

impl Pca {
    /// The leading `count` principal axes of the rows of `x` (all of one length).
    pub fn fit(x: &[Vec<f64>], count: usize) -> Pca {
        let dim = x.first().map_or(0, |r| r.len());
        let mean: Vec<f64> = (0..dim)
            .map(|k| x.iter().map(|r| r[k]).sum::<f64>() / x.len() as f64)
            .collect();
        let axes = principal_axes(x, &mean, count);
        Pca { mean, axes }
    }

    /// The components of `x`.
    pub fn project(&self, x: &[f64]) -> Vec<f64> {
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
}

/// Kernel matrix of `z` with length scale `length`, without ridge.
pub(crate) fn kernel(z: &[Vec<f64>], length: f64) -> DMatrix<f64> {
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
pub(crate) fn solve(k: &DMatrix<f64>, ridge: f64, y: &[Vec<f64>]) -> Option<Vec<Vec<f64>>> {
    let n = k.nrows();
    let mut a = k.clone();
    for i in 0..n {
        a[(i, i)] += ridge;
    }
    let chol = crate::linalg::cholesky(a)?;
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

impl Regression {
    /// Chooses ℓ and the ridge per unknown for the training runs' points `z` with targets `y`
    /// (`[unknowns][runs]`, scaled to [0, 1]): per unknown, the held-out runs' mean absolute
    /// error, ℓ and the ridge.
    pub(crate) fn choose(
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
    /// [`Regression::choose`]); `ranges` are the unknowns' `[lo, hi]`, to which `y` is scaled;
    /// `spread` says how the std is set.
    pub(crate) fn finish(
        z: Vec<Vec<f64>>,
        y: &[Vec<f64>],
        inside: &[bool],
        best: &Settings,
        ranges: Vec<[f64; 2]>,
        spread: Spread,
        fail: &(dyn Fn(&str) -> Error + Sync),
    ) -> Result<Regression> {
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
                let chol = crate::linalg::cholesky(a)
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
                let [lo, hi] = ranges[u];
                // Leave-one-out errors (SI) of the runs inside the range, with their runs'
                // leave-one-out predictive spreads 1/√(A⁻¹)_ii.
                let loo: Vec<(f64, f64)> = (0..n)
                    .filter(|&i| inside[i])
                    .map(|i| {
                        // f_{−i}(z_i) = y_i − α_i / (A⁻¹)_ii.
                        let loo = (y[u][i] - alpha[i] / inv_diag[i]).clamp(0.0, 1.0);
                        ((loo - y[u][i]) * (hi - lo), 1.0 / inv_diag[i].sqrt())
                    })
                    .collect();
                let constant: Vec<(f64, f64)> = loo.iter().map(|&(e, _)| (e, 1.0 / Z90)).collect();
                let (factor, chol) = match spread {
                    Spread::Constant => (0.0, None),
                    Spread::Gp => (coverage_factor_at(&loo, QUANTILE), Some(chol.unpack())),
                };
                Ok(Head {
                    length,
                    ridge,
                    alpha,
                    std: coverage_factor_at(&constant, QUANTILE) / Z90,
                    factor,
                    chol,
                })
            })
            .collect();
        Ok(Regression {
            heads: heads.into_iter().collect::<Result<_>>()?,
            z,
            ranges,
        })
    }

    /// Estimate of every unknown at `z`, clipped to its range.
    pub(crate) fn point(&self, z: &[f64]) -> Vec<f64> {
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

    /// The std of every unknown at `z`, SI: the constant std ([`Spread::Constant`]) or `c·s(z)`
    /// ([`Spread::Gp`], [`Head::factor`]; O(runs²) per unknown, one triangular solve).
    pub(crate) fn std_at(&self, z: &[f64]) -> Vec<f64> {
        self.heads
            .iter()
            .zip(self.spreads(z))
            .map(|(h, s)| s.map_or(h.std, |s| h.factor * s))
            .collect()
    }

    /// Per unknown, with [`Spread::Gp`], the predictive spread `s(z) = √(1 + λ − |L⁻¹k_z|²)`
    /// (at least √λ, the floor it reaches on a training run, against rounding).
    pub(crate) fn spreads(&self, z: &[f64]) -> Vec<Option<f64>> {
        self.heads
            .iter()
            .map(|h| {
                let l = h.chol.as_ref()?;
                let g = 1.0 / (2.0 * h.length * h.length);
                let k = DVector::from_iterator(
                    self.z.len(),
                    self.z.iter().map(|t| (-dist2(t, z) * g).exp()),
                );
                let w = l.solve_lower_triangular(&k).unwrap_or(k);
                Some((1.0 + h.ridge - w.norm_squared()).max(h.ridge).sqrt())
            })
            .collect()
    }

    /// Whether it has been fitted.
    pub(crate) fn is_fitted(&self) -> bool {
        !self.heads.is_empty()
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
pub(crate) fn median_distance(z: &[Vec<f64>]) -> f64 {
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

#[cfg(test)]
mod tests {
    use super::*;
    use vibrissa_core::rng::Rng;

    /// `count` points of a 1-D regression, dense on [0, 0.5] and sparse on [0.5, 1], with
    /// targets `0.5 + 0.3 sin 6z` and noise of std 0.03.
    fn toy(rng: &mut Rng, count: usize) -> (Vec<Vec<f64>>, Vec<f64>) {
        (0..count)
            .map(|_| {
                let z = if rng.uniform() < 0.85 {
                    0.5 * rng.uniform()
                } else {
                    0.5 + 0.5 * rng.uniform()
                };
                (vec![z], 0.5 + 0.3 * (6.0 * z).sin() + 0.03 * rng.normal())
            })
            .unzip()
    }

    fn fail(d: &str) -> Error {
        Error::Observation(d.into())
    }

    /// The regression of `y` on `z` with the settings `settings`.
    fn fit(z: &[Vec<f64>], y: &[f64], settings: &Settings, spread: Spread) -> Regression {
        let inside = vec![true; z.len()];
        let y = vec![y.to_vec()];
        Regression::finish(
            z.to_vec(),
            &y,
            &inside,
            settings,
            vec![[0.0, 1.0]],
            spread,
            &fail,
        )
        .unwrap()
    }

    #[test]
    fn gp_stds_grow_away_from_the_training_runs_and_hold_the_leave_one_out_errors() {
        let mut rng = Rng::new(7);
        let (z, y) = toy(&mut rng, 200);
        let settings =
            Regression::choose(&z, std::slice::from_ref(&y), &[true; 200], &fail).unwrap();
        let gp = fit(&z, &y, &settings, Spread::Gp);
        let constant = fit(&z, &y, &settings, Spread::Constant);
        let std = |r: &Regression, z: f64| r.std_at(&[z])[0];
        // The constant std is the same everywhere; the normalised one is narrower where the runs
        // are dense than where they are sparse, and wider still beyond them, where the spread is
        // the prior's, √(1 + λ).
        assert_eq!(std(&constant, 0.25), std(&constant, 30.0));
        let (dense, sparse, far) = (std(&gp, 0.25), std(&gp, 0.8), std(&gp, 30.0));
        assert!(dense < sparse && sparse < far, "{dense} {sparse} {far}");
        let h = &gp.heads[0];
        assert!((far - h.factor * (1.0 + h.ridge).sqrt()).abs() < 1e-6 * far);
        // Each run left out in turn and refitted on the rest: its error and the refit's spread
        // at it. The intervals ±Z90·c·s_{−i}(z_i) hold QUANTILE of the errors (the calibration
        // read s_{−i} off the full fit's inverse), and so do the constant ones.
        let (mut by_gp, mut by_constant) = (0, 0);
        for i in 0..z.len() {
            let keep = |v: &[f64]| -> Vec<f64> { [&v[..i], &v[i + 1..]].concat() };
            let zi: Vec<Vec<f64>> = [&z[..i], &z[i + 1..]].concat();
            let r = fit(&zi, &keep(&y), &settings, Spread::Gp);
            let e = (r.point(&z[i])[0] - y[i]).abs();
            let s = r.spreads(&z[i])[0].unwrap();
            by_gp += usize::from(e <= Z90 * h.factor * s);
            by_constant += usize::from(e <= Z90 * constant.heads[0].std);
        }
        for held in [by_gp, by_constant] {
            let share = held as f64 / z.len() as f64;
            assert!(
                (share - QUANTILE).abs() <= 1.5 / z.len() as f64,
                "{held} of 200"
            );
        }
        // On fresh points drawn as the training runs were, about 90% of the intervals hold the
        // truth.
        let (zt, yt) = toy(&mut rng, 2000);
        let held = zt
            .iter()
            .zip(&yt)
            .filter(|(z, y)| (gp.point(z)[0] - *y).abs() <= Z90 * gp.std_at(z)[0])
            .count();
        assert!(
            (0.85..=0.97).contains(&(held as f64 / 2000.0)),
            "{held} of 2000"
        );
    }
}
