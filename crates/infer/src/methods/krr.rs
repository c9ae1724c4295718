//! Kernel ridge regression (RBF kernel) on principal components of normalised series.

use crate::error::{Error, Result};
use crate::experiment::{Sample, CHANNELS};
use crate::features::{channel_scales, coverage_factor, dist2, flatten};
use crate::method::{Budget, Estimate, Method, Training, Z90};
use nalgebra::{DMatrix, DVector};

/// Principal components kept.
const COMPONENTS: usize = 24;
/// Length scales tried, as multiples of the median distance between training runs.
const LENGTHS: [f64; 5] = [0.125, 0.25, 0.5, 1.0, 2.0];
/// Ridges tried (the kernel's diagonal is 1).
const RIDGES: [f64; 4] = [1e-8, 1e-6, 1e-4, 1e-2];

/// `f(z) = Σ α_i exp(−|z − z_i|²/(2ℓ²))` per unknown (scaled to [0, 1] over its range), with
/// `z` the first principal components of the normalised series. ℓ and the ridge are chosen on
/// the last fifth of the training runs (fitted on the rest); the std is constant per unknown,
/// set so that 90% intervals cover 90% of those held-out runs.
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
    /// Dual weights `[unknowns][runs]`.
    alpha: Vec<Vec<f64>>,
    /// Unknowns' ranges `[unknowns][lo, hi]`.
    ranges: Vec<[f64; 2]>,
    /// Length scale in component space.
    length: f64,
    /// Ridge.
    ridge: f64,
    /// Std per unknown, SI.
    std: Vec<f64>,
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

    /// Fits the weights for training points `z` with targets `params`.
    fn solve(&mut self, z: Vec<Vec<f64>>, params: &[Vec<f64>]) -> Result<()> {
        let n = z.len();
        let mut k = DMatrix::<f64>::zeros(n, n);
        let g = 1.0 / (2.0 * self.length * self.length);
        for i in 0..n {
            for j in 0..=i {
                let v = (-dist2(&z[i], &z[j]) * g).exp();
                k[(i, j)] = v;
                k[(j, i)] = v;
            }
            k[(i, i)] += self.ridge;
        }
        let chol = k.cholesky().ok_or_else(|| Error::Fit {
            method: "krr".into(),
            detail: "kernel matrix not positive definite".into(),
        })?;
        self.alpha = (0..self.ranges.len())
            .map(|u| {
                let [lo, hi] = self.ranges[u];
                let y = DVector::from_iterator(n, params.iter().map(|p| (p[u] - lo) / (hi - lo)));
                chol.solve(&y).iter().copied().collect()
            })
            .collect();
        self.z = z;
        Ok(())
    }

    fn point(&self, z: &[f64]) -> Vec<f64> {
        let g = 1.0 / (2.0 * self.length * self.length);
        let kx: Vec<f64> = self.z.iter().map(|t| (-dist2(t, z) * g).exp()).collect();
        self.alpha
            .iter()
            .zip(&self.ranges)
            .map(|(a, [lo, hi])| {
                lo + (hi - lo) * a.iter().zip(&kx).map(|(a, k)| a * k).sum::<f64>()
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
    let mut g = DMatrix::<f64>::zeros(n, n);
    for i in 0..n {
        for j in 0..=i {
            let v: f64 = c[i].iter().zip(&c[j]).map(|(a, b)| a * b).sum();
            g[(i, j)] = v;
            g[(j, i)] = v;
        }
    }
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
        let s: &[Sample] = &training.samples;
        if s.len() < 10 {
            return Err(Error::Fit {
                method: "krr".into(),
                detail: "needs at least 10 training runs".into(),
            });
        }
        let channels: Vec<usize> = (0..CHANNELS.len()).collect();
        self.scales = channel_scales(s, &channels);
        self.ranges = training.experiment.ranges();
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
        let params: Vec<Vec<f64>> = s.iter().map(|r| r.params.clone()).collect();
        let med = median_distance(&z);
        // Choose ℓ and the ridge on the last fifth, fitted on the rest.
        let cut = s.len() * 4 / 5;
        let mut best = (f64::INFINITY, med, RIDGES[0]);
        for l in LENGTHS {
            for r in RIDGES {
                self.length = l * med;
                self.ridge = r;
                if self.solve(z[..cut].to_vec(), &params[..cut]).is_err() {
                    continue;
                }
                let mut err = 0.0;
                for (zi, pi) in z[cut..].iter().zip(&params[cut..]) {
                    let p = self.point(zi);
                    for (u, [lo, hi]) in self.ranges.iter().enumerate() {
                        err += (p[u] - pi[u]).abs() / (hi - lo);
                    }
                }
                if err < best.0 {
                    best = (err, self.length, r);
                }
            }
        }
        (self.length, self.ridge) = (best.1, best.2);
        self.solve(z[..cut].to_vec(), &params[..cut])?;
        let mut pairs = vec![Vec::new(); self.ranges.len()];
        for (zi, pi) in z[cut..].iter().zip(&params[cut..]) {
            let p = self.point(zi);
            for u in 0..p.len() {
                pairs[u].push((p[u] - pi[u], 1.0 / Z90));
            }
        }
        self.std = pairs.iter().map(|p| coverage_factor(p) / Z90).collect();
        // The final model uses every training run.
        self.solve(z, &params)?;
        Ok(())
    }

    fn predict(&self, obs: &[Vec<f64>]) -> Result<Vec<Estimate>> {
        if self.alpha.is_empty() {
            return Err(Error::Fit {
                method: "krr".into(),
                detail: "not fitted".into(),
            });
        }
        let channels: Vec<usize> = (0..CHANNELS.len()).collect();
        let x = flatten(obs, &channels, &self.scales)?;
        let p = self.point(&self.project(&x));
        Ok(p.iter()
            .zip(&self.std)
            .map(|(m, s)| Estimate::normal(*m, *s))
            .collect())
    }

    fn settings(&self) -> Vec<(String, f64)> {
        vec![
            ("components".into(), self.axes.len() as f64),
            ("length".into(), self.length),
            ("ridge".into(), self.ridge),
        ]
    }
}
