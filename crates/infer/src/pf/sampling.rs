//! Sampling maths of the filter: truncated normals, systematic resampling, the Liu–West move of
//! the resampled object states and reflection into a prior's range.

use super::config::{Config, Prior};
use super::transition::{param, start_delay, ObjState, Y};
use crate::mixture::normal_cdf;
use vibrissa_core::rng::Rng;

/// Density at `x` of a normal truncated to the prior's range.
pub(super) fn truncated_density(x: f64, mean: f64, std: f64, p: &Prior) -> f64 {
    if !p.is_free() {
        return 1.0;
    }
    let mass = normal_cdf((p.hi - mean) / std) - normal_cdf((p.lo - mean) / std);
    let z = (x - mean) / std;
    (-0.5 * z * z).exp() / (std * (2.0 * std::f64::consts::PI).sqrt()) / mass.max(1e-300)
}

/// A draw from a normal truncated to the prior's range (rejection, then uniform as a fallback).
pub(super) fn truncated_normal(rng: &mut Rng, mean: f64, std: f64, p: &Prior) -> f64 {
    if !p.is_free() {
        return p.lo;
    }
    for _ in 0..1000 {
        let x = mean + std * rng.normal();
        if x >= p.lo && x <= p.hi {
            return x;
        }
    }
    p.lo + (p.hi - p.lo) * rng.uniform()
}

/// Systematic resampling: parent index of every new particle.
pub(crate) fn systematic(w: &[f64], u0: f64) -> Vec<usize> {
    let n = w.len();
    let mut parents = Vec::with_capacity(n);
    let mut cum = w[0];
    let mut i = 0;
    for j in 0..n {
        let u = (j as f64 + u0) / n as f64;
        while u > cum && i + 1 < n {
            i += 1;
            cum += w[i];
        }
        parents.push(i);
    }
    parents
}

/// Smallest standard deviation of the cloud that a Liu–West move assumes, as a fraction of each
/// unknown's prior range: a cloud that has collapsed onto one value (all weight on one particle)
/// still moves, so the filter can leave a wrong mode.
const COV_FLOOR: f64 = 2e-3;

/// The Liu–West move of resampled object states: each moves towards the weighted mean of the
/// cloud of arrived boxes by the shrinkage `a` ([`Config::shrink`]) and is jittered with the
/// cloud's covariance times `1 − a²`, so the cloud keeps its mean and spread.
pub(super) struct LiuWest {
    /// The free unknowns' indices.
    free: Vec<usize>,
    mean: [f64; 5],
    /// Lower Cholesky factor of the cloud's covariance (floored).
    chol: [[f64; 5]; 5],
    a: f64,
    gap: f64,
}

#[allow(clippy::needless_range_loop)]
impl LiuWest {
    /// The move for a cloud `objs` weighted `w`; `None` when nothing moves (no free unknown, no
    /// shrinkage, or no box has arrived).
    pub(super) fn new(
        config: &Config,
        objs: &[ObjState],
        w: &[f64],
        free: &[usize],
        arrived: &[bool],
    ) -> Option<LiuWest> {
        // Moved coordinates: the free unknowns (d, v, t0, size, mu), summarised over the
        // weighted cloud of the particles whose box has arrived (the others are redrawn anyway).
        let m = free.len();
        let a = config.shrink;
        if m == 0 || a >= 1.0 {
            return None;
        }
        let gap = config.gap;
        let mass: f64 = w
            .iter()
            .zip(arrived)
            .filter(|(_, a)| **a)
            .map(|(w, _)| w)
            .sum();
        if mass <= 0.0 {
            return None;
        }
        let w: Vec<f64> = w
            .iter()
            .zip(arrived)
            .map(|(w, a)| if *a { w / mass } else { 0.0 })
            .collect();
        let mut mean = [0.0f64; 5];
        for (o, &wi) in objs.iter().zip(&w) {
            for (j, &c) in free.iter().enumerate() {
                mean[j] += wi * param(o, c, gap);
            }
        }
        let mut cov = [[0.0f64; 5]; 5];
        for (o, &wi) in objs.iter().zip(&w) {
            for j in 0..m {
                for l in 0..m {
                    cov[j][l] += wi
                        * (param(o, free[j], gap) - mean[j])
                        * (param(o, free[l], gap) - mean[l]);
                }
            }
        }
        // Cholesky with a small floor on the diagonal (a collapsed cloud still moves a little).
        let mut chol = [[0.0f64; 5]; 5];
        for j in 0..m {
            let span = config.priors[free[j]].hi - config.priors[free[j]].lo;
            cov[j][j] = cov[j][j].max(COV_FLOOR * COV_FLOOR * span * span);
        }
        for j in 0..m {
            for l in 0..=j {
                let mut s = cov[j][l];
                for r in 0..l {
                    s -= chol[j][r] * chol[l][r];
                }
                chol[j][l] = if j == l {
                    s.max(0.0).sqrt()
                } else if chol[l][l] > 0.0 {
                    s / chol[l][l]
                } else {
                    0.0
                };
            }
        }
        Some(LiuWest {
            free: free.to_vec(),
            mean,
            chol,
            a,
            gap,
        })
    }

    /// One move of the object state `o` at time `t`, drawn from `rng`. A box that has gone
    /// (`cleared`) takes the move as it is. One that may still touch its whisker keeps its
    /// height where it is (the whisker state stays consistent with it): its speed and distance
    /// move, its start delay follows from the height and the speed.
    pub(super) fn draw(
        &self,
        config: &Config,
        o: &ObjState,
        cleared: bool,
        t: f64,
        rng: &mut Rng,
    ) -> ObjState {
        let (m, a, gap) = (self.free.len(), self.a, self.gap);
        let h = (1.0 - a * a).sqrt();
        let mut o = *o;
        let mut z = [0.0f64; 5];
        z[..m].iter_mut().for_each(|x| *x = rng.normal());
        let (t0_old, y_now) = (start_delay(&o, gap), o[Y] + o[1] * t);
        // Every unknown's value before the move (t0 depends on the speed, which moves first).
        let mut before = [0.0f64; 5];
        for (b, &c) in before.iter_mut().zip(&self.free) {
            *b = param(&o, c, gap);
        }
        let mut t0_new = t0_old;
        for j in 0..m {
            let c = self.free[j];
            let noise: f64 = (0..=j).map(|l| self.chol[j][l] * z[l]).sum();
            let x = reflect(
                a * before[j] + (1.0 - a) * self.mean[j] + h * noise,
                &config.priors[c],
            );
            if c == Y {
                // While the box may still touch its whisker, its height is part of the contact
                // state: it stays where it is, and t0 follows from it and the speed.
                if cleared {
                    t0_new = x;
                }
            } else {
                o[c] = x;
            }
        }
        o[Y] = if cleared {
            -gap - o[1] * t0_new
        } else {
            y_now - o[1] * (t0_new - t0_old) - o[1] * t
        };
        o
    }
}

/// `x` reflected into the prior's range.
fn reflect(x: f64, p: &Prior) -> f64 {
    let (lo, hi) = (p.lo, p.hi);
    if hi <= lo {
        return lo;
    }
    let span = hi - lo;
    let mut y = (x - lo).rem_euclid(2.0 * span);
    if y > span {
        y = 2.0 * span - y;
    }
    lo + y
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_distribution_function_at_known_points() {
        // Tabulated values of the standard normal distribution function.
        for (z, p) in [
            (0.0, 0.5),
            (1.644_853_626_951_472, 0.95),
            (-1.959_963_984_540_054, 0.025),
            (-3.0, 1.349_898_031_630_094_6e-3),
            (-8.0, 6.220_960_574_271_785e-16),
        ] {
            let got = normal_cdf(z);
            assert!((got - p).abs() <= 1e-13 * p, "Phi({z}) = {got}, not {p}");
        }
    }

    #[test]
    fn systematic_resampling_keeps_proportions() {
        let w = [0.5, 0.25, 0.0, 0.25];
        let p = systematic(&w, 0.5);
        assert_eq!(p.len(), 4);
        assert_eq!(p.iter().filter(|&&i| i == 0).count(), 2);
        assert_eq!(p.iter().filter(|&&i| i == 2).count(), 0);
    }

    #[test]
    fn reflection_stays_in_range() {
        let p = Prior::uniform(1.0, 2.0);
        for x in [-3.3, 0.5, 1.5, 2.5, 7.1] {
            let y = reflect(x, &p);
            assert!((1.0..=2.0).contains(&y), "{x} -> {y}");
        }
        assert!((reflect(2.25, &p) - 1.75).abs() < 1e-12);
    }

    #[test]
    fn truncated_density_integrates_to_one() {
        let p = Prior::uniform(0.0, 1.0);
        let n = 20000;
        let s: f64 = (0..n)
            .map(|i| truncated_density((i as f64 + 0.5) / n as f64, 0.9, 0.2, &p) / n as f64)
            .sum();
        assert!((s - 1.0).abs() < 1e-4, "{s}");
    }
}
