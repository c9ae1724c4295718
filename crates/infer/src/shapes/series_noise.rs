//! The noise of one whisker's recording as a Gaussian over the whole series, and the whitening
//! it implies.
//!
//! What the world adds to a noise-free run is not white: the random forces set the whisker
//! ringing, so the force channels' errors last for many samples and move together with the
//! angles'. A likelihood that treats every sample as independent counts one ringing episode as
//! many independent pieces of evidence. This module estimates the covariance of the noise over
//! one whisker's series (its channels end to end, each already divided by its noise level) from
//! residuals (noisy runs minus their noise-free twins), shrinks it towards its diagonal by the
//! Ledoit–Wolf rule (the shrinkage is fitted to the residuals, not chosen), and whitens by the
//! inverse of its Cholesky factor.

use nalgebra::DMatrix;

/// The noise covariance over one whisker's series and its whitening (see the module's
/// documentation).
#[derive(Debug, Clone)]
pub struct SeriesNoise {
    /// `L⁻¹`, with `L Lᵀ` the covariance: `W x` has unit covariance.
    whiten: DMatrix<f64>,
    /// The shrinkage towards the diagonal that the residuals called for, in [0, 1].
    shrinkage: f64,
}

impl SeriesNoise {
    /// From residual series (the rows of `r`, each `channels` channels of equal length laid out
    /// time-major, column `t·channels + c` for channel `c` at sample `t`, every channel in
    /// units of its noise level). A channel whose residuals are smaller
    /// than its noise level on average (a level raised to its floor, or a clean recording's)
    /// gets white noise added on its diagonal up to that level, so that the covariance of
    /// residuals that are all zero is the identity. `None` if `r` is empty or its width is not
    /// a multiple of `channels`.
    pub fn fit(r: &DMatrix<f64>, channels: usize) -> Option<SeriesNoise> {
        let (n, b) = r.shape();
        if n == 0 || b == 0 || channels == 0 || b % channels != 0 {
            return None;
        }
        let rt = r.transpose();
        let s = (&rt * r) / n as f64;
        // Ledoit–Wolf: the variance of each off-diagonal entry's estimate against the entries'
        // squared size.
        let r2 = r.map(|x| x * x);
        let p = (r2.transpose() * &r2) / n as f64;
        let (mut var_off, mut size_off) = (0.0, 0.0);
        for j in 0..b {
            for i in 0..b {
                if i != j {
                    var_off += (p[(i, j)] - s[(i, j)] * s[(i, j)]) / n as f64;
                    size_off += s[(i, j)] * s[(i, j)];
                }
            }
        }
        let shrinkage = if size_off > 0.0 {
            (var_off / size_off).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let mut c = &s * (1.0 - shrinkage);
        for i in 0..b {
            c[(i, i)] = s[(i, i)];
        }
        for ch in 0..channels {
            let span = (ch..b).step_by(channels);
            let mean = span.clone().map(|i| c[(i, i)]).sum::<f64>() / (b / channels) as f64;
            let add = (1.0 - mean).max(0.0);
            for i in span {
                c[(i, i)] += add + 1e-9;
            }
        }
        let l = crate::linalg::cholesky(c)?.unpack();
        let whiten = l.solve_lower_triangular(&DMatrix::identity(b, b))?;
        Some(SeriesNoise { whiten, shrinkage })
    }

    /// `L⁻¹`: multiplying a series (a column) by it whitens it. It is lower triangular, so the
    /// whitened series up to sample `t` depends on the recording up to `t` only: the sum of its
    /// squares up to `t` is the Gaussian log likelihood of the recording so far (up to a
    /// constant), an online likelihood.
    pub fn whitening(&self) -> &DMatrix<f64> {
        &self.whiten
    }

    /// The shrinkage towards the diagonal, in [0, 1].
    pub fn shrinkage(&self) -> f64 {
        self.shrinkage
    }

    /// The length of the series it whitens.
    pub fn width(&self) -> usize {
        self.whiten.nrows()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vibrissa_core::rng::Rng;

    /// Residuals of two channels of 40 samples: a ringing common to both (an AR(2) process)
    /// plus white noise, each channel's variance above 1 (its level) on average.
    fn ringing(n: usize, rng: &mut Rng) -> DMatrix<f64> {
        let samples = 40;
        let mut r = DMatrix::zeros(n, 2 * samples);
        for k in 0..n {
            let (mut a, mut b) = (0.0, 0.0);
            for t in 0..samples {
                let x = 1.6 * a - 0.8 * b + rng.normal();
                (b, a) = (a, x);
                r[(k, 2 * t)] = x + rng.normal();
                r[(k, 2 * t + 1)] = -0.5 * x + rng.normal();
            }
        }
        r
    }

    #[test]
    fn fresh_ringing_residuals_come_out_white() {
        let mut rng = Rng::new(3);
        let noise = SeriesNoise::fit(&ringing(4000, &mut rng), 2).unwrap();
        assert!(noise.shrinkage() < 0.1, "{}", noise.shrinkage());
        // Residuals it was not fitted on, whitened: unit variance, no correlation left.
        let fresh = ringing(4000, &mut rng);
        let u = &fresh * noise.whitening().transpose();
        let cov = (u.transpose() * &u) / fresh.nrows() as f64;
        let b = cov.nrows();
        let diag: f64 = (0..b).map(|i| cov[(i, i)]).sum::<f64>() / b as f64;
        assert!((diag - 1.0).abs() < 0.1, "mean variance {diag}");
        let worst = (0..b)
            .flat_map(|i| (0..b).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| cov[(i, j)].abs())
            .fold(0.0, f64::max);
        assert!(worst < 0.15, "largest correlation left {worst}");
        // Before whitening neighbouring samples were strongly correlated.
        let raw = (fresh.transpose() * &fresh) / fresh.nrows() as f64;
        assert!(raw[(20, 22)] / (raw[(20, 20)] * raw[(22, 22)]).sqrt() > 0.5);
    }

    #[test]
    fn residuals_that_are_zero_give_the_identity_and_bad_shapes_nothing() {
        let noise = SeriesNoise::fit(&DMatrix::zeros(10, 6), 3).unwrap();
        assert_eq!(noise.shrinkage(), 1.0);
        let w = noise.whitening();
        for i in 0..6 {
            for j in 0..6 {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((w[(i, j)] - want).abs() < 1e-6, "{i} {j}: {}", w[(i, j)]);
            }
        }
        assert!(SeriesNoise::fit(&DMatrix::zeros(10, 7), 3).is_none());
        assert!(SeriesNoise::fit(&DMatrix::zeros(0, 6), 3).is_none());
    }
}
