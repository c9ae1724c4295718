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

/// A Gaussian over `K` gains followed by their `K` offsets (`N = 2K`). Its covariance is
/// symmetric, so only the upper triangle is kept, row by row (`T = N(N+1)/2` values): a particle's
/// belief is copied at every resampling and updated at every sample, and half a matrix is less
/// to move and to update.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Block<const N: usize, const T: usize> {
    mean: [f64; N],
    cov: [f64; T],
}

impl<const N: usize, const T: usize> Block<N, T> {
    /// `T` is the triangle's size (checked when a block is made, at compile time).
    const TRIANGLE: () = assert!(T == N * (N + 1) / 2, "a block keeps N(N+1)/2 covariances");

    /// Where the covariance of `i` and `c` is kept.
    const fn at(i: usize, c: usize) -> usize {
        let (a, b) = if i <= c { (i, c) } else { (c, i) };
        a * (2 * N + 1 - a) / 2 + (b - a)
    }

    /// A block with `mean` and the covariance `cov(i, c)` (read for `i ≤ c` only).
    fn new(mean: [f64; N], cov: impl Fn(usize, usize) -> f64) -> Self {
        let () = Self::TRIANGLE;
        let mut packed = [0.0; T];
        for i in 0..N {
            for c in i..N {
                packed[Self::at(i, c)] = cov(i, c);
            }
        }
        Block { mean, cov: packed }
    }

    /// The covariance of `i` and `c`.
    fn cov(&self, i: usize, c: usize) -> f64 {
        self.cov[Self::at(i, c)]
    }

    /// Takes the sample `y` of the block's channel `J` whose model value is `x` with observation
    /// variance `var`: returns `(z², s/var)`, the squared residual in units of its predictive
    /// variance `s` and that variance's ratio to `var` (at least 1). The log predictive density,
    /// less the constant of a known-gain Gaussian (−½ ln 2πσ², so that it reduces to −½ z² when
    /// the gains are known), is `−½ (z² + ln(s/var))`. (`J` is a constant so that every place
    /// in the triangle is known when this is compiled.)
    #[inline(always)]
    fn take<const J: usize>(&mut self, x: f64, y: f64, var: f64) -> (f64, f64) {
        let (j, k) = (J, N / 2);
        let ph: [f64; N] = std::array::from_fn(|i| self.cov(i, j) * x + self.cov(i, k + j));
        let s = (x * ph[j] + ph[k + j] + var).max(var);
        let r = y - (self.mean[j] * x + self.mean[k + j]);
        // The Kalman gain, ph / s; the covariance falls by ph·phᵀ / s, each pair once.
        let inv_s = 1.0 / s;
        let gain: [f64; N] = std::array::from_fn(|i| ph[i] * inv_s);
        for (m, g) in self.mean.iter_mut().zip(&gain) {
            *m += g * r;
        }
        let mut n = 0;
        for (i, g) in gain.iter().enumerate() {
            for p in &ph[i..] {
                self.cov[n] -= g * p;
                n += 1;
            }
        }
        for i in 0..N {
            let d = &mut self.cov[Self::at(i, i)];
            *d = d.max(0.0);
        }
        (r * r * inv_s, s / var)
    }
}

/// The block of one joint angle: its gain and offset.
type AngleBlock = Block<2, 3>;
/// The block of the base wrench: `m0`, `fx` and `fy`'s gains, then their offsets.
type WrenchBlock = Block<6, 21>;

/// One particle's belief over the five channels' gains and offsets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct SensorBelief {
    /// `theta01` and `theta12`, each its own gain and offset (no prior or sample couples them).
    angles: [AngleBlock; 2],
    /// `m0`, `fx`, `fy`: gains, then offsets.
    wrench: WrenchBlock,
}

impl SensorBelief {
    /// The prior of `config`: its sensors' gains and offsets, spread by its
    /// [`Config::sensor_spread`].
    pub(super) fn prior(config: &Config) -> SensorBelief {
        let spread = config.sensor_spread;
        let (g, o, sigma) = (config.sensor_gain, config.sensor_offset, config.sigma);
        let angle_gains = AngleGains::of(config);
        let angles = std::array::from_fn(|j| {
            let var = [angle_gains.var[j], (spread.offset * sigma[j]).powi(2)];
            AngleBlock::new([angle_gains.mean[j], o[j]], |i, c| {
                if i == c {
                    var[i]
                } else {
                    0.0
                }
            })
        });
        let wrench = WrenchBlock::new([g[2], g[3], g[4], o[2], o[3], o[4]], |i, c| {
            if c < 3 {
                let own = if i == c {
                    spread.wrench_gain.powi(2)
                } else {
                    0.0
                };
                g[2 + i] * g[2 + c] * (spread.wrench_scale.powi(2) + own)
            } else if i == c {
                (spread.offset * sigma[c - 1]).powi(2)
            } else {
                0.0
            }
        });
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
                m2[j] += wi * (block.cov(0, 0) + block.mean[0] * block.mean[0]);
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
        let mut add = |(z, r): (f64, f64)| {
            z2 += z;
            ratio *= r;
        };
        let var = |c: usize| sigma[c] * sigma[c];
        let [a0, a1] = &mut self.angles;
        let w = &mut self.wrench;
        if seen[0] {
            add(a0.take::<0>(x[0], y[0], var(0)));
        }
        if seen[1] {
            add(a1.take::<0>(x[1], y[1], var(1)));
        }
        if seen[2] {
            add(w.take::<0>(x[2], y[2], var(2)));
        }
        if seen[3] {
            add(w.take::<1>(x[3], y[3], var(3)));
        }
        if seen[4] {
            add(w.take::<2>(x[4], y[4], var(4)));
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
            let (vg, vo) = b.variances();
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

    /// Variance of each channel's gain and of its offset (as [`SensorBelief::means`]).
    pub(super) fn variances(&self) -> ([f64; 5], [f64; 5]) {
        let [a0, a1] = &self.angles;
        let w = &self.wrench;
        let of = |k: usize| [a0.cov(k, k), a1.cov(k, k)];
        let ([g0, g1], [o0, o1]) = (of(0), of(1));
        (
            [g0, g1, w.cov(0, 0), w.cov(1, 1), w.cov(2, 2)],
            [o0, o1, w.cov(3, 3), w.cov(4, 4), w.cov(5, 5)],
        )
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

    /// The update on the whole square matrix, each pair's new value written to both halves.
    #[allow(clippy::needless_range_loop)]
    fn square_take<const N: usize>(
        mean: &mut [f64; N],
        cov: &mut [[f64; N]; N],
        j: usize,
        x: f64,
        y: f64,
        var: f64,
    ) -> (f64, f64) {
        let k = N / 2;
        let ph: [f64; N] = std::array::from_fn(|i| cov[i][j] * x + cov[i][k + j]);
        let s = (x * ph[j] + ph[k + j] + var).max(var);
        let r = y - (mean[j] * x + mean[k + j]);
        let inv_s = 1.0 / s;
        let gain: [f64; N] = std::array::from_fn(|i| ph[i] * inv_s);
        for i in 0..N {
            mean[i] += gain[i] * r;
            for c in i..N {
                let v = cov[i][c] - gain[i] * ph[c];
                cov[i][c] = v;
                cov[c][i] = v;
            }
            cov[i][i] = cov[i][i].max(0.0);
        }
        (r * r * inv_s, s / var)
    }

    #[test]
    fn the_packed_triangle_updates_as_the_whole_matrix_to_the_bit() {
        let c = config(SensorSpread {
            wrench_scale: 0.3,
            ..SensorSpread::rough()
        });
        let mut b = SensorBelief::prior(&c).wrench;
        let mut mean = b.mean;
        let mut cov: [[f64; 6]; 6] = std::array::from_fn(|i| std::array::from_fn(|k| b.cov(i, k)));
        let mut rng = vibrissa_core::rng::Rng::new(7);
        for t in 0..3000 {
            let j = t % 3;
            // Model values and samples of several scales, a few of them zero.
            let scale = [2e-5, 1e-3, 5e-4][j] * if t % 97 == 0 { 0.0 } else { 1.0 };
            let x = scale * rng.normal();
            let y = 0.9 * x + scale * 0.1 * rng.normal();
            let var = c.sigma[2 + j].powi(2);
            let ours = match j {
                0 => b.take::<0>(x, y, var),
                1 => b.take::<1>(x, y, var),
                _ => b.take::<2>(x, y, var),
            };
            let theirs = square_take(&mut mean, &mut cov, j, x, y, var);
            assert_eq!(ours.0.to_bits(), theirs.0.to_bits(), "z² at {t}");
            assert_eq!(ours.1.to_bits(), theirs.1.to_bits(), "ratio at {t}");
            for i in 0..6 {
                assert_eq!(b.mean[i].to_bits(), mean[i].to_bits(), "mean {i} at {t}");
                for (k, whole) in cov[i].iter().enumerate() {
                    assert_eq!(b.cov(i, k).to_bits(), whole.to_bits(), "cov {i} {k} at {t}");
                }
            }
        }
        // The angles' blocks too.
        let mut a = SensorBelief::prior(&c).angles[1];
        let mut mean = a.mean;
        let mut cov: [[f64; 2]; 2] = std::array::from_fn(|i| std::array::from_fn(|k| a.cov(i, k)));
        for t in 0..500 {
            let x = 0.05 * rng.normal();
            let y = 0.4 * x + 0.01 * rng.normal();
            let ours = a.take::<0>(x, y, 1e-4);
            let theirs = square_take(&mut mean, &mut cov, 0, x, y, 1e-4);
            assert_eq!(ours.0.to_bits(), theirs.0.to_bits(), "angle z² at {t}");
            assert_eq!(
                a.cov(0, 1).to_bits(),
                cov[1][0].to_bits(),
                "angle cov at {t}"
            );
            assert_eq!(a.mean[0].to_bits(), mean[0].to_bits(), "angle gain at {t}");
        }
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
        let (var_g, var_o, sigma) = (prior.cov(0, 0), prior.cov(3, 3), c.sigma[2]);
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
        assert!(b.variances().0[3] < (0.3f64.powi(2) + 0.05f64.powi(2)));
    }
}
