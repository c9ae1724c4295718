//! The sensors' gains and offsets as unknowns of the filter, marginalised within each particle.
//!
//! A recorded channel is `y = g·x + o + e`: the model's value `x`, the sensor's gain `g` and
//! offset `o`, and Gaussian noise `e`. Given a particle's path (its `x` at every sample), `y` is
//! linear in `(g, o)`, so a Gaussian belief over the gains and offsets can be carried by each
//! particle and updated exactly by every sample (a Kalman update of a static state): the
//! particle's weight is the predictive density of the sample with the gains and offsets
//! integrated out (Rao–Blackwellisation), and no particle has to guess them.
//!
//! Independent blocks: each joint angle (`theta01`, `theta12`) on its own, whose scale depends on
//! the recording's chain (a joint angle is curvature times joint spacing) and on how the angles were
//! measured, and the base wrench (`m0`, `fx`, `fy`), whose gains share one scale (the whisker's
//! stiffness, which a nominal file gets wrong, moves all three together) besides each sensor's
//! own gain. The ratios within the wrench (the contact's lever arm) stay informative.

use super::config::Config;
use super::gains::AngleGains;
use super::posterior::SensorPosterior;
use crate::method::Estimate;
use serde::Serialize;

/// Prior spread of the sensors' gains and offsets around the scenario's values (all zero: they
/// are known, the filter's behaviour without this module).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct SensorSpread {
    /// Standard deviation of each joint angle's gain, relative to its nominal gain.
    pub angle_gain: f64,
    /// Standard deviation of the scale shared by the three base-wrench gains, relative.
    pub wrench_scale: f64,
    /// Standard deviation of each base-wrench sensor's own gain, relative (beside the scale).
    pub wrench_gain: f64,
    /// Standard deviation of each offset, in units of the channel's observation noise.
    pub offset: f64,
}

impl SensorSpread {
    /// The spread the filter assumes beside alternative whiskers ([`Config::alternatives`],
    /// which carry the whisker's stiffness and with it the wrench's scale): the angle gains free
    /// within about a factor of two (recordings of another chain or another angle tracker), the
    /// wrench's common scale and each sensor's gain ±5%, offsets a few noise levels.
    pub fn rough() -> SensorSpread {
        SensorSpread {
            angle_gain: 0.5,
            wrench_scale: 0.05,
            wrench_gain: 0.05,
            offset: 5.0,
        }
    }

    /// Whether every gain and offset is known.
    pub fn is_fixed(&self) -> bool {
        self.angle_gain == 0.0
            && self.wrench_scale == 0.0
            && self.wrench_gain == 0.0
            && self.offset == 0.0
    }

    /// Whether every spread is finite and not negative.
    pub fn is_valid(&self) -> bool {
        [
            self.angle_gain,
            self.wrench_scale,
            self.wrench_gain,
            self.offset,
        ]
        .iter()
        .all(|s| s.is_finite() && *s >= 0.0)
    }
}

/// A Gaussian over `K` gains followed by their `K` offsets (`N = 2K`).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Block<const N: usize> {
    mean: [f64; N],
    cov: [[f64; N]; N],
}

impl<const N: usize> Block<N> {
    /// Takes the sample `y` of the block's channel `j` whose model value is `x` with observation
    /// variance `var`: returns `(z², s/var)`, the squared residual in units of its predictive
    /// variance `s` and that variance's ratio to `var` (at least 1). The log predictive density,
    /// less the constant of a known-gain Gaussian (−½ ln 2πσ², so that it reduces to −½ z² when
    /// the gains are known), is `−½ (z² + ln(s/var))`.
    #[allow(clippy::needless_range_loop)] // one index over the mean, the gain and a triangle
    fn take(&mut self, j: usize, x: f64, y: f64, var: f64) -> (f64, f64) {
        let k = N / 2;
        let ph: [f64; N] = std::array::from_fn(|i| self.cov[i][j] * x + self.cov[i][k + j]);
        let s = (x * ph[j] + ph[k + j] + var).max(var);
        let r = y - (self.mean[j] * x + self.mean[k + j]);
        // The Kalman gain, ph / s; the covariance falls by ph·phᵀ / s, computed once per pair so
        // that it stays exactly symmetric.
        let inv_s = 1.0 / s;
        let gain: [f64; N] = std::array::from_fn(|i| ph[i] * inv_s);
        for i in 0..N {
            self.mean[i] += gain[i] * r;
            for c in i..N {
                let v = self.cov[i][c] - gain[i] * ph[c];
                self.cov[i][c] = v;
                self.cov[c][i] = v;
            }
            self.cov[i][i] = self.cov[i][i].max(0.0);
        }
        (r * r * inv_s, s / var)
    }
}

/// One particle's belief over the five channels' gains and offsets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct SensorBelief {
    /// `theta01` and `theta12`, each its own gain and offset (no prior or sample couples them).
    angles: [Block<2>; 2],
    /// `m0`, `fx`, `fy`: gains, then offsets.
    wrench: Block<6>,
}

impl SensorBelief {
    /// The prior of `config`: its sensors' gains and offsets, spread by its
    /// [`Config::sensor_spread`].
    pub(super) fn prior(config: &Config) -> SensorBelief {
        let spread = config.sensor_spread;
        let (g, o, sigma) = (config.sensor_gain, config.sensor_offset, config.sigma);
        let angle_gains = AngleGains::of(config);
        let angles = std::array::from_fn(|j| Block {
            mean: [angle_gains.mean[j], o[j]],
            cov: [
                [angle_gains.var[j], 0.0],
                [0.0, (spread.offset * sigma[j]).powi(2)],
            ],
        });
        let mut wrench = Block {
            mean: [g[2], g[3], g[4], o[2], o[3], o[4]],
            cov: [[0.0; 6]; 6],
        };
        for i in 0..3 {
            for j in 0..3 {
                let own = if i == j {
                    spread.wrench_gain.powi(2)
                } else {
                    0.0
                };
                wrench.cov[i][j] = g[2 + i] * g[2 + j] * (spread.wrench_scale.powi(2) + own);
            }
            wrench.cov[3 + i][3 + i] = (spread.offset * sigma[2 + i]).powi(2);
        }
        SensorBelief { angles, wrench }
    }

    /// The joint angles' gains over the particles' `beliefs` with normalised weights `w`: for
    /// each, the mixture of the particles' normals matched to one (its mean and variance).
    pub(super) fn angle_gains(beliefs: &[SensorBelief], w: &[f64]) -> AngleGains {
        let (mut m1, mut m2) = ([0.0f64; 2], [0.0f64; 2]);
        for (b, &wi) in beliefs.iter().zip(w) {
            for j in 0..2 {
                let block = &b.angles[j];
                m1[j] += wi * block.mean[0];
                m2[j] += wi * (block.cov[0][0] + block.mean[0] * block.mean[0]);
            }
        }
        AngleGains {
            mean: m1,
            var: [0, 1].map(|j| (m2[j] - m1[j] * m1[j]).max(0.0)),
        }
    }

    /// Takes a sample: `x` the particle's model values, `y` the recorded ones, `seen` which
    /// channels to use, `sigma` their observation noise. Returns the log-likelihood with the
    /// gains and offsets integrated out over the belief, which it then updates.
    pub(super) fn take(
        &mut self,
        x: &[f64; 5],
        y: &[f64; 5],
        seen: &[bool; 5],
        sigma: &[f64; 5],
    ) -> f64 {
        // One logarithm for the five channels' variance ratios (each at least 1 and bounded by
        // the prior's spread, so that their product stays finite).
        let (mut z2, mut ratio) = (0.0, 1.0);
        for c in 0..5 {
            if seen[c] {
                let var = sigma[c] * sigma[c];
                let (z, r) = if c < 2 {
                    self.angles[c].take(0, x[c], y[c], var)
                } else {
                    self.wrench.take(c - 2, x[c], y[c], var)
                };
                z2 += z;
                ratio *= r;
            }
        }
        -0.5 * (z2 + ratio.ln())
    }

    /// The posterior of the gains and offsets over the particles' `beliefs` with normalised
    /// weights `w`: a mixture of Gaussians, summarised by its mean, standard deviation and the
    /// central 90% interval of a normal of that spread.
    pub(super) fn mixture(beliefs: &[SensorBelief], w: &[f64]) -> SensorPosterior {
        let (mut m1, mut m2) = ([0.0f64; 10], [0.0f64; 10]);
        for (b, &wi) in beliefs.iter().zip(w) {
            let (g, o) = b.means();
            let (vg, vo) = (b.gain_variances(), b.offset_variances());
            for c in 0..5 {
                m1[c] += wi * g[c];
                m2[c] += wi * (vg[c] + g[c] * g[c]);
                m1[5 + c] += wi * o[c];
                m2[5 + c] += wi * (vo[c] + o[c] * o[c]);
            }
        }
        let est = |k: usize| {
            let std = (m2[k] - m1[k] * m1[k]).max(0.0).sqrt();
            Estimate::normal(m1[k], std)
        };
        SensorPosterior {
            gain: std::array::from_fn(est),
            offset: std::array::from_fn(|c| est(5 + c)),
        }
    }

    /// Mean gain and offset of each channel (in [`crate::experiment::CHANNELS`] order).
    pub(super) fn means(&self) -> ([f64; 5], [f64; 5]) {
        let [a0, a1] = self.angles.map(|b| b.mean);
        let w = &self.wrench.mean;
        (
            [a0[0], a1[0], w[0], w[1], w[2]],
            [a0[1], a1[1], w[3], w[4], w[5]],
        )
    }

    /// Variance of each channel's gain.
    pub(super) fn gain_variances(&self) -> [f64; 5] {
        let [a0, a1] = self.angles.map(|b| b.cov);
        let w = &self.wrench.cov;
        [a0[0][0], a1[0][0], w[0][0], w[1][1], w[2][2]]
    }

    /// Variance of each channel's offset.
    pub(super) fn offset_variances(&self) -> [f64; 5] {
        let [a0, a1] = self.angles.map(|b| b.cov);
        let w = &self.wrench.cov;
        [a0[1][1], a1[1][1], w[3][3], w[4][4], w[5][5]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(spread: SensorSpread) -> Config {
        let mut c = Config::e2([0.01, 0.01, 1e-6, 1e-4, 1e-4], 10, 1);
        c.sensor_spread = spread;
        c
    }

    #[test]
    fn known_gains_give_the_plain_gaussian_log_likelihood() {
        let mut c = config(SensorSpread::default());
        c.sensor_gain = [1.1, 0.9, 1.0, 1.2, 0.8];
        c.sensor_offset = [0.01, 0.0, 1e-6, 0.0, 2e-4];
        let mut b = SensorBelief::prior(&c);
        let x = [0.03, -0.02, 2e-5, 1e-3, -4e-4];
        let y = [0.05, -0.01, 2.5e-5, 1.1e-3, -3e-4];
        let ll = b.take(&x, &y, &[true; 5], &c.sigma);
        let want: f64 = (0..5)
            .map(|i| {
                let z = (y[i] - c.sensor_gain[i] * x[i] - c.sensor_offset[i]) / c.sigma[i];
                -0.5 * z * z
            })
            .sum();
        assert!((ll - want).abs() < 1e-9 * want.abs(), "{ll} vs {want}");
    }

    #[test]
    fn the_sequential_updates_give_the_exact_marginal_likelihood() {
        // With the gains and offsets Gaussian, a channel's samples are jointly Gaussian:
        // y ~ N(H·m0, H·P0·Hᵀ + σ²·I) with H's rows (x_t, 1). The sum of the sequential log
        // predictive densities must be that density (less the constant n/2·ln 2πσ² that the
        // filter leaves out of every sample).
        let spread = SensorSpread {
            wrench_scale: 0.3,
            ..SensorSpread::rough()
        };
        let c = config(spread);
        let mut b = SensorBelief::prior(&c);
        let n = 12;
        let x: Vec<f64> = (0..n).map(|k| 2e-5 * (0.4 * k as f64).sin()).collect();
        let y: Vec<f64> = x
            .iter()
            .enumerate()
            .map(|(k, x)| 0.8 * x + 3e-7 + 1e-6 * (1.7 * k as f64).cos())
            .collect();
        let mut ours = 0.0;
        for k in 0..n {
            let mut xs = [0.0; 5];
            let mut ys = [0.0; 5];
            (xs[2], ys[2]) = (x[k], y[k]);
            ours += b.take(&xs, &ys, &[false, false, true, false, false], &c.sigma);
        }
        let prior = SensorBelief::prior(&c).wrench;
        let (var_g, var_o, sigma) = (prior.cov[0][0], prior.cov[3][3], c.sigma[2]);
        let h = nalgebra::DMatrix::from_fn(n, 2, |i, j| if j == 0 { x[i] } else { 1.0 });
        let p0 = nalgebra::DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![var_g, var_o]));
        let cov = &h * p0 * h.transpose() + nalgebra::DMatrix::identity(n, n) * (sigma * sigma);
        let mean = &h * nalgebra::DVector::from_vec(vec![prior.mean[0], prior.mean[3]]);
        let r = nalgebra::DVector::from_vec(y.clone()) - mean;
        let chol = cov.cholesky().expect("positive definite");
        let log_det = 2.0 * chol.l().diagonal().iter().map(|d| d.ln()).sum::<f64>();
        let quad = r.dot(&chol.solve(&r));
        let two_pi = 2.0 * std::f64::consts::PI;
        let exact = -0.5 * (quad + log_det + n as f64 * two_pi.ln());
        let shifted = ours - 0.5 * n as f64 * (two_pi * sigma * sigma).ln();
        assert!(
            (shifted - exact).abs() < 1e-8 * exact.abs().max(1.0),
            "{shifted} vs {exact}"
        );
    }

    #[test]
    fn a_scaled_channel_is_learned_and_explained() {
        // A recording whose theta12 is 0.4 of the model's: the belief's gain goes there, and the
        // log-likelihood of later samples approaches that of a model that knew it.
        let c = config(SensorSpread::rough());
        let mut b = SensorBelief::prior(&c);
        let mut last = 0.0;
        for k in 0..200 {
            let x2 = 0.1 * (k as f64 * 0.1).sin();
            let x = [0.0, x2, 0.0, 0.0, 0.0];
            let y = [0.0, 0.4 * x2, 0.0, 0.0, 0.0];
            last = b.take(&x, &y, &[false, true, false, false, false], &c.sigma);
        }
        let (g, _) = b.means();
        assert!((g[1] - 0.4).abs() < 1e-3, "gain {}", g[1]);
        assert!(last > -0.05, "log-likelihood of an explained sample {last}");
        // A known gain of 1 would have paid dearly for the same sample.
        let fixed = -0.5 * (0.6_f64 * 0.1 / 0.01).powi(2);
        assert!(fixed < -1.0);
    }

    #[test]
    fn the_wrench_scale_moves_all_three_gains_together() {
        let c = config(SensorSpread {
            wrench_scale: 0.3,
            ..SensorSpread::rough()
        });
        let mut b = SensorBelief::prior(&c);
        for k in 0..50 {
            let m0 = 2e-5 * (1.0 + k as f64 * 0.02);
            let x = [0.0, 0.0, m0, 0.0, 0.0];
            let y = [0.0, 0.0, 0.7 * m0, 0.0, 0.0];
            b.take(&x, &y, &[false, false, true, false, false], &c.sigma);
        }
        let (g, _) = b.means();
        assert!((g[2] - 0.7).abs() < 0.01, "m0 gain {}", g[2]);
        // fx and fy were never seen, yet their gains followed m0's through the shared scale.
        assert!(g[3] < 0.8 && g[4] < 0.8, "{g:?}");
        assert!(b.gain_variances()[3] < (0.3f64.powi(2) + 0.05f64.powi(2)));
    }
}
