//! A recording's likelihood under one class at one pose when the world pushes the whiskers with
//! random forces (a scenario's `process_noise`).
//!
//! The forces' response is not white: they set the whiskers ringing at their low modes, so
//! that a recording strays from the noise-free run by slow, correlated swings that a
//! per-sample noise level (which a smooth fit measures on the recording) does not see. Weighed
//! by that level alone, those swings count as evidence; a class whose pose can bend its run
//! toward them wins where the truth should. Here they are noise: their mean and covariance at
//! the pose are read off `m` runs of that pose with the forces alone, and the sensor noise is
//! added on the diagonal, so that in whitened units (each channel over its sensor noise) the
//! recording `z` is normal with mean `μ` and covariance `Σ = I + R·Rᵀ/m`, the columns of `R`
//! the `m` runs less their mean. Woodbury and the determinant lemma give the likelihood
//! through an `m × m` Cholesky factor: `(z − μ)ᵀΣ⁻¹(z − μ) = δᵀδ − uᵀ(m·I + RᵀR)⁻¹u` with
//! `u = Rᵀδ`, and `log det Σ = log det(m·I + RᵀR) − m·log m`.

use super::family::ShapeFamily;
use crate::experiment::Noise;
use nalgebra::{Cholesky, DMatrix, DVector, Dyn};

/// A run's series whitened and laid end to end: whiskers, channels, samples; each value over
/// its channel's noise level.
pub fn whitened(whiskers: &[Vec<Vec<f64>>], sigma: &[f64; 5]) -> Vec<f64> {
    whiskers
        .iter()
        .flat_map(|w| {
            w.iter()
                .zip(sigma)
                .flat_map(move |(ch, s)| ch.iter().map(move |v| v / s))
        })
        .collect()
}

/// Dot product.
pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The noise of a recording at one class and pose: the forces' mean response and its spread,
/// whitened.
pub(super) struct Forced {
    /// The mean run, whitened.
    pub mean: Vec<f64>,
    /// The runs less their mean (the columns of `R`).
    r: Vec<Vec<f64>>,
    /// Cholesky factor of `m·I + RᵀR` (none without runs).
    chol: Option<Cholesky<f64, Dyn>>,
    /// `log det Σ`.
    logdet: f64,
}

impl Forced {
    /// From whitened runs of one pose: their mean and spread. One run gives its own series and
    /// white noise alone. `None` without runs.
    pub fn from_runs(runs: Vec<Vec<f64>>) -> Option<Forced> {
        let m = runs.len();
        let first = runs.first()?;
        let dim = first.len();
        let mean: Vec<f64> = (0..dim)
            .map(|i| runs.iter().map(|v| v[i]).sum::<f64>() / m as f64)
            .collect();
        if m < 2 {
            return Some(Forced {
                mean,
                r: Vec::new(),
                chol: None,
                logdet: 0.0,
            });
        }
        let r: Vec<Vec<f64>> = runs
            .iter()
            .map(|v| v.iter().zip(&mean).map(|(a, b)| a - b).collect())
            .collect();
        let g = DMatrix::from_fn(m, m, |i, j| {
            dot(&r[i], &r[j]) + if i == j { m as f64 } else { 0.0 }
        });
        let chol = g.cholesky()?;
        let logdet = 2.0 * chol.l().diagonal().iter().map(|d| d.ln()).sum::<f64>()
            - m as f64 * (m as f64).ln();
        Some(Forced {
            mean,
            r,
            chol: Some(chol),
            logdet,
        })
    }

    /// Simulates `runs` runs of `class` at `pose` with the random forces `process` alone (sensor
    /// noise none; seeded by `seed`), whitened by the sensor noise `sigma`: without forces, the
    /// noise-free run alone. `None` if none could be simulated.
    pub fn simulate(
        family: &ShapeFamily,
        class: usize,
        pose: &[f64],
        sigma: &[f64; 5],
        process: f64,
        runs: usize,
        seed: u64,
    ) -> Option<Forced> {
        let (noise, count) = if process > 0.0 && runs > 1 {
            (
                Noise {
                    sensor: [0.0; 5],
                    process,
                },
                runs,
            )
        } else {
            (Noise::NONE, 1)
        };
        let same = vec![(class, pose.to_vec()); count];
        let (done, _) = family
            .simulate_completed(&same, &noise, seed, &|| {})
            .ok()?;
        Forced::from_runs(done.iter().map(|s| whitened(&s.whiskers, sigma)).collect())
    }

    /// `Σ⁻¹·v`.
    pub fn solve(&self, v: &[f64]) -> Vec<f64> {
        let Some(chol) = &self.chol else {
            return v.to_vec();
        };
        let m = self.r.len();
        let u = DVector::from_fn(m, |i, _| dot(&self.r[i], v));
        let w = chol.solve(&u);
        let mut out = v.to_vec();
        for (i, ri) in self.r.iter().enumerate() {
            for (o, x) in out.iter_mut().zip(ri) {
                *o -= w[i] * x;
            }
        }
        out
    }

    /// `(z − μ)ᵀΣ⁻¹(z − μ)` of a whitened recording.
    pub fn chi2(&self, z: &[f64]) -> f64 {
        let delta: Vec<f64> = z.iter().zip(&self.mean).map(|(a, b)| a - b).collect();
        dot(&delta, &self.solve(&delta)).max(0.0)
    }

    /// The log likelihood of a whitened recording, up to a constant shared by every class and
    /// pose: `−(χ² + log det Σ)/2`.
    pub fn log_likelihood(&self, z: &[f64]) -> f64 {
        -0.5 * (self.chi2(z) + self.logdet)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The dense covariance `I + R·Rᵀ/m` of runs about their mean.
    fn dense(runs: &[Vec<f64>]) -> (DVector<f64>, DMatrix<f64>) {
        let m = runs.len();
        let dim = runs[0].len();
        let mean = DVector::from_fn(dim, |i, _| {
            runs.iter().map(|v| v[i]).sum::<f64>() / m as f64
        });
        let cov = DMatrix::from_fn(dim, dim, |i, j| {
            runs.iter()
                .map(|v| (v[i] - mean[i]) * (v[j] - mean[j]))
                .sum::<f64>()
                / m as f64
                + f64::from(i == j)
        });
        (mean, cov)
    }

    #[test]
    fn the_likelihood_is_the_dense_normals_through_the_small_factor() {
        let mut rng = vibrissa_core::rng::Rng::new(5);
        let runs: Vec<Vec<f64>> = (0..7)
            .map(|_| {
                (0..12)
                    .map(|i| 2.0 * rng.normal() + 0.1 * i as f64)
                    .collect()
            })
            .collect();
        let z: Vec<f64> = (0..12).map(|_| rng.normal()).collect();
        let f = Forced::from_runs(runs.clone()).unwrap();
        let (mean, cov) = dense(&runs);
        let d = DVector::from_column_slice(&z) - &mean;
        let chol = cov.clone().cholesky().unwrap();
        let chi2 = d.dot(&chol.solve(&d));
        let logdet = 2.0 * chol.l().diagonal().iter().map(|x| x.ln()).sum::<f64>();
        assert!(
            (f.chi2(&z) - chi2).abs() < 1e-9 * chi2,
            "{} {chi2}",
            f.chi2(&z)
        );
        assert!((f.log_likelihood(&z) + 0.5 * (chi2 + logdet)).abs() < 1e-9);
        // Σ⁻¹v against the dense solve.
        let v: Vec<f64> = (0..12).map(|i| (i as f64).sin()).collect();
        let want = chol.solve(&DVector::from_column_slice(&v));
        for (a, b) in f.solve(&v).iter().zip(want.iter()) {
            assert!((a - b).abs() < 1e-10);
        }
    }

    #[test]
    fn swings_the_forces_make_weigh_less_than_the_same_difference_elsewhere() {
        // Runs that swing along the first axis only.
        let runs: Vec<Vec<f64>> = [-3.0, -1.0, 1.0, 3.0]
            .iter()
            .map(|a| vec![*a, 0.0, 0.0])
            .collect();
        let f = Forced::from_runs(runs).unwrap();
        let along = f.chi2(&[2.0, 0.0, 0.0]);
        let across = f.chi2(&[0.0, 2.0, 0.0]);
        // Variance along the swing: 1 + (9 + 1 + 1 + 9)/4 = 6.
        assert!((along - 4.0 / 6.0).abs() < 1e-12, "{along}");
        assert!((across - 4.0).abs() < 1e-12, "{across}");
        // One run: white noise about it.
        let one = Forced::from_runs(vec![vec![1.0, 1.0]]).unwrap();
        assert_eq!(one.chi2(&[2.0, 3.0]), 5.0);
        assert_eq!(one.log_likelihood(&[2.0, 3.0]), -2.5);
        assert!(Forced::from_runs(Vec::new()).is_none());
    }

    #[test]
    fn whitening_divides_each_channel_by_its_noise_and_lays_whiskers_end_to_end() {
        let w = vec![
            vec![vec![1.0, 2.0], vec![3.0], vec![4.0], vec![5.0], vec![6.0]],
            vec![vec![10.0], vec![], vec![], vec![], vec![20.0]],
        ];
        let s = [1.0, 3.0, 2.0, 5.0, 2.0];
        assert_eq!(
            whitened(&w, &s),
            vec![1.0, 2.0, 1.0, 2.0, 1.0, 3.0, 10.0, 10.0]
        );
    }
}
