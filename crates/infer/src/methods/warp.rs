//! Least-squares fit of a landmark-registered interpolation between the template runs
//! (`template-warp`): the templates' series are aligned at landmarks of the contact before they
//! are mixed, so that a candidate's series is one moved bump rather than two half bumps.

use crate::error::{Error, Result};
use crate::experiment::{Sample, CHANNELS, THETA12};
use crate::features::{channel_scales, coverage_factor, flatten};
use crate::method::{Budget, Estimate, Method, Training};

/// First landmark: |theta12| (smoothed) first reaches this fraction of its peak.
const RISE_FRACTION: f64 = 0.2;
/// Time unit of the registered axis after the last landmark, s (the ringing runs in real time).
const RING_UNIT: f64 = 0.010;
/// Half-width of the moving average that smooths theta12 before the landmarks are found.
const SMOOTH: usize = 2;
/// Lattice of the coarse search: steps per unknown.
const LATTICE: [usize; 2] = [16, 13];

/// Landmark registration and least squares.
///
/// Each run's theta12 (smoothed by a 5-sample moving average) gives two landmarks: `t₁`, where
/// |theta12| first reaches 20% of its peak (the contact's rise), and `t₂`, the first zero
/// crossing after it (a quarter period after the whisker slips off the box). The time axis is
/// mapped to a registered axis `τ` piecewise linearly: `[0, t₁] → [0, 1]`, `[t₁, t₂] → [1, 2]`,
/// and after `t₂` in real time (`τ = 2 + (t − t₂)/10 ms`), since the free ringing after slip-off
/// has the whisker's own period whatever `d` and `v`.
///
/// The landmarks of a candidate `(d, v)` are interpolated from the templates' as the box's
/// travel `v·tₖ`, which depends mostly on `d` (contact geometry) and only mildly on `v`; the
/// candidate's series at registered time `τ` mixes the templates' series at `τ` with the same
/// interpolation weights. Weights are piecewise linear in `√(L − d)` (L = 30 mm, the whisker's
/// length: slip-off needs the projected length to shrink by `L − d`, which makes the travel
/// to slip-off grow about as `√(L − d)`) and quadratic in `v` (Lagrange through the three
/// speeds of `e2`: the series change with speed at an uneven rate, and a piecewise-linear mix
/// pulls fast runs near d = 30 mm to lower speeds).
///
/// The estimate minimises `Σ w_c (m(d, v) − o)²` over all five channels, each divided by its
/// standard deviation over the templates and weighted by `w_c`, the inverse of its mean squared
/// residual where the corner templates' model meets the other templates (scaled to average 1:
/// the channels that the interpolation represents poorly, mostly fx and fy, count less): a
/// lattice search (16 × 13; a finer lattice finds
/// deeper but wrong minima where the interpolation is poorest, near d = 30 mm) then a pattern
/// search. Its std is the Laplace approximation `σ̂²·(JᵀJ)⁻¹` from a finite-difference Hessian,
/// scaled per unknown so that the corner templates alone cover the other templates (90%).
#[derive(Debug, Clone)]
pub struct Warp {
    /// Channel scales, `[CHANNELS]`.
    scales: Vec<f64>,
    /// Grid distances, m, increasing.
    d_nodes: Vec<f64>,
    /// Grid speeds, m/s, increasing (one for `e1`).
    v_nodes: Vec<f64>,
    /// Normalised series at the nodes: `[v_nodes][d_nodes][CHANNELS][SAMPLES]`.
    nodes: Vec<Vec<Vec<Vec<f64>>>>,
    /// Landmarks as travel `v·tₖ`, m: `[v_nodes][d_nodes][2]`.
    travel: Vec<Vec<[f64; 2]>>,
    /// Unknowns: 1 (`e1`) or 2 (`e2`).
    unknowns: usize,
    /// Std factors per unknown from the calibration.
    factors: Vec<f64>,
    /// Weight of each channel's squared residuals, `[CHANNELS]`.
    channel_weights: Vec<f64>,
    /// Timing of the runs: sample rate (Hz) and samples per run.
    rate: f64,
    /// Samples per run.
    samples: usize,
    /// The object's speed when it is not an unknown, m/s.
    speed: f64,
    /// The whisker's length, m (distances are interpolated in `√(L − d)`).
    length: f64,
}

impl Default for Warp {
    fn default() -> Self {
        Warp::new()
    }
}

/// Piecewise-linear interpolation weights over increasing `nodes` at `x` (clamped).
fn hat_weights(nodes: &[f64], x: f64) -> Vec<(usize, f64)> {
    if nodes.len() == 1 {
        return vec![(0, 1.0)];
    }
    let n = nodes.len();
    let mut i = 0;
    while i + 2 < n && x > nodes[i + 1] {
        i += 1;
    }
    let u = ((x - nodes[i]) / (nodes[i + 1] - nodes[i])).clamp(0.0, 1.0);
    vec![(i, 1.0 - u), (i + 1, u)]
}

/// Quadratic (Lagrange) interpolation weights over increasing `nodes` at `x` (clamped): through
/// the three consecutive nodes centred nearest `x`; piecewise linear with fewer than three.
fn quadratic_weights(nodes: &[f64], x: f64) -> Vec<(usize, f64)> {
    let n = nodes.len();
    if n < 3 {
        return hat_weights(nodes, x);
    }
    let x = x.clamp(nodes[0], nodes[n - 1]);
    let mid = (1..n - 1)
        .min_by(|&a, &b| (nodes[a] - x).abs().total_cmp(&(nodes[b] - x).abs()))
        .expect("three nodes");
    (mid - 1..=mid + 1)
        .map(|i| {
            let w: f64 = (mid - 1..=mid + 1)
                .filter(|&k| k != i)
                .map(|k| (x - nodes[k]) / (nodes[i] - nodes[k]))
                .product();
            (i, w)
        })
        .collect()
}

/// The distance coordinate the weights are linear in, for a whisker of length `length`.
fn d_coord(d: f64, length: f64) -> f64 {
    (length - d).max(0.0).sqrt()
}

/// Landmarks `[t₁, t₂]` of one run sampled at `rate` Hz, s.
fn landmarks(series: &[Vec<f64>], rate: f64) -> [f64; 2] {
    let th = &series[THETA12];
    let n = th.len();
    let sm: Vec<f64> = (0..n)
        .map(|k| {
            let lo = k.saturating_sub(SMOOTH);
            let hi = (k + SMOOTH).min(n - 1);
            th[lo..=hi].iter().sum::<f64>() / (hi - lo + 1) as f64
        })
        .collect();
    let peak = sm
        .iter()
        .copied()
        .fold(0.0, |a: f64, x| if x.abs() > a.abs() { x } else { a });
    let dt = 1.0 / rate;
    if peak == 0.0 {
        return [dt, 2.0 * dt];
    }
    let sg = peak.signum();
    let level = RISE_FRACTION * peak.abs();
    let mut t1 = dt;
    let mut k1 = 0;
    for k in 1..n {
        if sg * sm[k] >= level {
            let (a, b) = (sg * sm[k - 1], sg * sm[k]);
            let f = if b > a { (level - a) / (b - a) } else { 1.0 };
            t1 = (k as f64 - 1.0 + f.clamp(0.0, 1.0)) * dt;
            k1 = k;
            break;
        }
    }
    let mut t2 = (n - 1) as f64 * dt;
    for k in k1.max(1)..n {
        if sg * sm[k] <= 0.0 && sg * sm[k - 1] > 0.0 {
            let (a, b) = (sm[k - 1], sm[k]);
            let f = a / (a - b);
            t2 = (k as f64 - 1.0 + f.clamp(0.0, 1.0)) * dt;
            break;
        }
    }
    [t1.max(0.1 * dt), t2.max(t1 + 0.5 * dt)]
}

/// Registered time of `t` for landmarks `lm`.
fn to_reg(t: f64, lm: [f64; 2]) -> f64 {
    if t < lm[0] {
        t / lm[0]
    } else if t < lm[1] {
        1.0 + (t - lm[0]) / (lm[1] - lm[0])
    } else {
        2.0 + (t - lm[1]) / RING_UNIT
    }
}

/// Real time of registered time `tau` for landmarks `lm`.
fn from_reg(tau: f64, lm: [f64; 2]) -> f64 {
    if tau < 1.0 {
        tau * lm[0]
    } else if tau < 2.0 {
        lm[0] + (tau - 1.0) * (lm[1] - lm[0])
    } else {
        lm[1] + (tau - 2.0) * RING_UNIT
    }
}

impl Warp {
    /// Unfitted.
    pub fn new() -> Warp {
        Warp {
            scales: Vec::new(),
            d_nodes: Vec::new(),
            v_nodes: Vec::new(),
            nodes: Vec::new(),
            travel: Vec::new(),
            unknowns: 0,
            factors: Vec::new(),
            channel_weights: vec![1.0; CHANNELS.len()],
            rate: 1000.0,
            samples: 151,
            speed: 0.6,
            length: 0.030,
        }
    }

    /// Unfitted, for runs of `family` (the experiment box with unknowns `d` or `d, v`).
    fn for_family(family: &crate::Family) -> Result<Warp> {
        if !family.is_box_family() {
            return Err(Error::Fit {
                method: "template-warp".into(),
                detail: format!(
                    "warps time by the experiment box's speed: it needs a family with                      experiment = \"e1\" or \"e2\" and unknowns d or d, v (not {})",
                    family.unknowns().join(", ")
                ),
            });
        }
        Ok(Warp {
            rate: family.sample_rate(),
            samples: family.samples(),
            speed: family.speed_of(&[]).unwrap_or(0.6),
            length: family.whisker().length,
            ..Warp::new()
        })
    }

    /// Builds the grid from `samples` (which must fill a rectangle of parameters).
    fn build(&mut self, samples: &[Sample], unknowns: usize) -> Result<()> {
        let fail = |detail: String| Error::Fit {
            method: "template-warp".into(),
            detail,
        };
        let (ds, vs) = super::interp::grid_axes(samples, unknowns, self.speed, "template-warp")?;
        let channels: Vec<usize> = (0..CHANNELS.len()).collect();
        self.scales = channel_scales(samples, &channels);
        let mut nodes = vec![vec![Vec::new(); ds.len()]; vs.len()];
        let mut travel = vec![vec![[0.0; 2]; ds.len()]; vs.len()];
        for s in samples {
            let i = ds.iter().position(|d| (d - s.params[0]).abs() < 1e-9);
            let j = if unknowns == 2 {
                vs.iter().position(|v| (v - s.params[1]).abs() < 1e-9)
            } else {
                Some(0)
            };
            let (Some(i), Some(j)) = (i, j) else {
                return Err(fail("a run off the grid".into()));
            };
            let x = flatten(&s.series, &channels, &self.scales)?;
            nodes[j][i] = x.chunks(self.samples).map(|c| c.to_vec()).collect();
            let lm = landmarks(&s.series, self.rate);
            travel[j][i] = [vs[j] * lm[0], vs[j] * lm[1]];
        }
        if nodes.iter().flatten().any(|n| n.is_empty()) {
            return Err(fail("a grid node without a run".into()));
        }
        self.d_nodes = ds;
        self.v_nodes = vs;
        self.nodes = nodes;
        self.travel = travel;
        self.unknowns = unknowns;
        self.factors = vec![1.0; unknowns];
        Ok(())
    }

    /// Interpolation weights `(j, i, w)` at `(d, v)`.
    fn weights(&self, d: f64, v: f64) -> Vec<(usize, usize, f64)> {
        let dc: Vec<f64> = self
            .d_nodes
            .iter()
            .map(|&x| d_coord(x, self.length))
            .collect();
        // d_coord decreases with d: interpolate over the reversed nodes.
        let rev: Vec<f64> = dc.iter().rev().copied().collect();
        let wd = hat_weights(&rev, d_coord(d, self.length));
        let wv = quadratic_weights(&self.v_nodes, v);
        let nd = self.d_nodes.len();
        let mut out = Vec::with_capacity(4);
        for &(j, a) in &wv {
            for &(ir, b) in &wd {
                if a * b != 0.0 {
                    out.push((j, nd - 1 - ir, a * b));
                }
            }
        }
        out
    }

    /// Sum of squared residuals of the model at `(d, v)` against the normalised `x`, each
    /// channel's weighted.
    fn sse(&self, x: &[Vec<f64>], d: f64, v: f64) -> f64 {
        self.channel_sse(x, d, v)
            .iter()
            .zip(&self.channel_weights)
            .map(|(e, w)| e * w)
            .sum()
    }

    /// Sum of squared residuals of the model at `(d, v)` against the normalised `x`, per channel.
    fn channel_sse(&self, x: &[Vec<f64>], d: f64, v: f64) -> Vec<f64> {
        let w = self.weights(d, v);
        let mut s = [0.0; 2];
        for &(j, i, wt) in &w {
            s[0] += wt * self.travel[j][i][0];
            s[1] += wt * self.travel[j][i][1];
        }
        let lm = [s[0] / v, s[1] / v];
        let (rate, samples) = (self.rate, self.samples);
        let dt = 1.0 / rate;
        let mut total = vec![0.0; x.len()];
        let mut pos: Vec<(usize, f64)> = Vec::with_capacity(w.len());
        for k in 0..samples {
            let tau = to_reg(k as f64 * dt, lm);
            pos.clear();
            for &(j, i, _) in &w {
                let t = from_reg(tau, self.node_landmarks(j, i));
                let p = (t * rate).clamp(0.0, (samples - 1) as f64);
                let ii = (p.floor() as usize).min(samples - 2);
                pos.push((ii, p - ii as f64));
            }
            for (c, xc) in x.iter().enumerate() {
                let mut m = 0.0;
                for (&(j, i, wt), &(ii, f)) in w.iter().zip(&pos) {
                    let y = &self.nodes[j][i][c];
                    m += wt * (y[ii] * (1.0 - f) + y[ii + 1] * f);
                }
                let r = m - xc[k];
                total[c] += r * r;
            }
        }
        total
    }

    /// Landmarks of node `(j, i)`, s.
    fn node_landmarks(&self, j: usize, i: usize) -> [f64; 2] {
        let v = self.v_nodes[j];
        [self.travel[j][i][0] / v, self.travel[j][i][1] / v]
    }

    /// Best fit to the normalised observation, without calibration: `(params, std)`.
    fn fit_raw(&self, x: &[Vec<f64>]) -> (Vec<f64>, Vec<f64>) {
        let (d0, d1) = (self.d_nodes[0], *self.d_nodes.last().expect("nodes"));
        let (v0, v1) = (self.v_nodes[0], *self.v_nodes.last().expect("nodes"));
        let two = self.unknowns == 2;
        let nv = if two { LATTICE[1] } else { 1 };
        let mut best = (f64::INFINITY, d0, v0);
        for b in 0..nv {
            let v = if two {
                v0 + (v1 - v0) * b as f64 / (nv - 1) as f64
            } else {
                v0
            };
            for a in 0..LATTICE[0] {
                let d = d0 + (d1 - d0) * a as f64 / (LATTICE[0] - 1) as f64;
                let e = self.sse(x, d, v);
                if e < best.0 {
                    best = (e, d, v);
                }
            }
        }
        // Pattern search from the lattice's best point.
        let (mut e, mut d, mut v) = best;
        let mut hd = (d1 - d0) / (LATTICE[0] - 1) as f64;
        let mut hv = if two {
            (v1 - v0) / (LATTICE[1] - 1) as f64
        } else {
            0.0
        };
        for _ in 0..40 {
            let mut moved = false;
            let steps: &[(f64, f64)] = if two {
                &[(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)]
            } else {
                &[(1.0, 0.0), (-1.0, 0.0)]
            };
            for &(sd, sv) in steps {
                let dn = (d + sd * hd).clamp(d0, d1);
                let vn = (v + sv * hv).clamp(v0, v1);
                let en = self.sse(x, dn, vn);
                if en < e {
                    (e, d, v) = (en, dn, vn);
                    moved = true;
                }
            }
            if !moved {
                hd *= 0.5;
                hv *= 0.5;
            }
        }
        // Laplace: cov = σ̂²·(JᵀJ)⁻¹ = 2σ̂²·H⁻¹ with H the Hessian of the sum of squares.
        let n = (CHANNELS.len() * self.samples) as f64;
        let s2 = e / (n - self.unknowns as f64).max(1.0);
        let hd = 2e-4;
        let dd2 = |f: &dyn Fn(f64) -> f64, x0: f64, h: f64| {
            (f(x0 + h) - 2.0 * f(x0) + f(x0 - h)) / (h * h)
        };
        let h_dd = dd2(&|dx| self.sse(x, dx, v), d, hd).abs().max(1e-300);
        if !two {
            return (vec![d], vec![(2.0 * s2 / h_dd).sqrt()]);
        }
        let hv = 0.01;
        let h_vv = dd2(&|vx| self.sse(x, d, vx), v, hv).abs().max(1e-300);
        let h_dv = (self.sse(x, d + hd, v + hv)
            - self.sse(x, d + hd, v - hv)
            - self.sse(x, d - hd, v + hv)
            + self.sse(x, d - hd, v - hv))
            / (4.0 * hd * hv);
        let det = h_dd * h_vv - h_dv * h_dv;
        let (var_d, var_v) = if det > 0.0 {
            (2.0 * s2 * h_vv / det, 2.0 * s2 * h_dd / det)
        } else {
            (2.0 * s2 / h_dd, 2.0 * s2 / h_vv)
        };
        (vec![d, v], vec![var_d.sqrt(), var_v.sqrt()])
    }

    fn normalised(&self, obs: &[Vec<f64>]) -> Result<Vec<Vec<f64>>> {
        let channels: Vec<usize> = (0..CHANNELS.len()).collect();
        let x = flatten(obs, &channels, &self.scales)?;
        if x.len() != CHANNELS.len() * self.samples {
            return Err(Error::Observation(format!(
                "template-warp: a series of {} samples; it was fitted on runs of {}",
                x.len() / CHANNELS.len(),
                self.samples
            )));
        }
        Ok(x.chunks(self.samples).map(|c| c.to_vec()).collect())
    }

    /// Channel weights from how well the model predicts `samples` at their own parameters: the
    /// inverse of each channel's mean squared residual, scaled to average 1 (all 1 without
    /// samples).
    fn model_weights(&self, samples: &[Sample]) -> Result<Vec<f64>> {
        let mut ms = vec![0.0; CHANNELS.len()];
        for s in samples {
            let x = self.normalised(&s.series)?;
            let v = s.params.get(1).copied().unwrap_or(self.v_nodes[0]);
            for (m, e) in ms.iter_mut().zip(self.channel_sse(&x, s.params[0], v)) {
                *m += e;
            }
        }
        if samples.is_empty() || ms.iter().any(|m| *m <= 0.0) {
            return Ok(vec![1.0; CHANNELS.len()]);
        }
        let inv: Vec<f64> = ms.iter().map(|m| 1.0 / m).collect();
        let mean = inv.iter().sum::<f64>() / inv.len() as f64;
        Ok(inv.iter().map(|w| w / mean).collect())
    }

    /// Calibration pairs `(error, std)` per unknown for `samples`.
    fn pairs(&self, samples: &[Sample]) -> Result<Vec<Vec<(f64, f64)>>> {
        super::residual_pairs(samples, self.unknowns, |s| {
            Ok(self.fit_raw(&self.normalised(&s.series)?))
        })
    }
}

impl Method for Warp {
    fn name(&self) -> &'static str {
        "template-warp"
    }

    fn budget(&self) -> Budget {
        Budget::Paper
    }

    fn channels(&self) -> Vec<usize> {
        (0..CHANNELS.len()).collect()
    }

    fn fit(&mut self, training: &Training) -> Result<()> {
        let unknowns = training.family.unknowns().len();
        let fresh = Warp::for_family(&training.family)?;
        // Held-out check: the corner templates alone predict the other templates (a coarser
        // grid than the final one, so the factor is cautious).
        let ranges = training.family.ranges();
        let corner = |s: &Sample| {
            s.params
                .iter()
                .zip(&ranges)
                .all(|(p, r)| (p - r[0]).abs() < 1e-9 || (p - r[1]).abs() < 1e-9)
        };
        let (corners, rest): (Vec<Sample>, Vec<Sample>) =
            training.samples.iter().cloned().partition(|s| corner(s));
        let mut coarse = fresh.clone();
        coarse.build(&corners, unknowns)?;
        // Channels that the interpolation predicts poorly (the corner model at the other
        // templates' parameters) weigh less.
        let channel_weights = coarse.model_weights(&rest)?;
        coarse.channel_weights = channel_weights.clone();
        let pairs = coarse.pairs(&rest)?;
        *self = fresh;
        self.build(&training.samples, unknowns)?;
        self.channel_weights = channel_weights;
        self.factors = pairs.iter().map(|p| coverage_factor(p)).collect();
        Ok(())
    }

    fn predict(&self, obs: &[Vec<f64>]) -> Result<Vec<Estimate>> {
        if self.nodes.is_empty() {
            return Err(Error::Fit {
                method: self.name().into(),
                detail: "not fitted".into(),
            });
        }
        let x = self.normalised(obs)?;
        let (p, sd) = self.fit_raw(&x);
        Ok((0..self.unknowns)
            .map(|u| Estimate::normal(p[u], sd[u] * self.factors[u]))
            .collect())
    }

    fn settings(&self) -> Vec<(String, f64)> {
        let mut s = super::interp::grid_settings(&self.d_nodes, &self.v_nodes, &self.factors);
        for (c, w) in CHANNELS.iter().zip(&self.channel_weights) {
            s.push((format!("weight_{c}"), *w));
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn registration_inverts_and_weights_sum_to_one() {
        let lm = [0.004, 0.031];
        for k in 0..151 {
            let t = k as f64 / 1000.0;
            assert!((from_reg(to_reg(t, lm), lm) - t).abs() < 1e-12);
        }
        for x in [0.0, 0.2, 0.9, 1.3, 2.0] {
            let w: f64 = hat_weights(&[0.3, 0.9, 1.5], x).iter().map(|p| p.1).sum();
            assert!((w - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn a_channel_the_model_misses_weighs_less() {
        // A bump whose height grows with d and v on every channel.
        let run = |d: f64, v: f64, offset: f64| Sample {
            series: (0..CHANNELS.len())
                .map(|c| {
                    (0..151)
                        .map(|k| {
                            let t = k as f64 - 20.0;
                            let bump = (1.0 + d * 10.0 + v) * (-t * t / 50.0).exp();
                            bump + if c == 3 { offset } else { 0.0 }
                        })
                        .collect()
                })
                .collect(),
            params: vec![d, v],
        };
        let corners: Vec<Sample> = [(0.015, 0.3), (0.015, 1.5), (0.030, 0.3), (0.030, 1.5)]
            .iter()
            .map(|&(d, v)| run(d, v, 0.0))
            .collect();
        let mut w = Warp::new();
        w.build(&corners, 2).unwrap();
        let weights = w.model_weights(&[run(0.023, 0.9, 0.5)]).unwrap();
        assert!((weights.iter().sum::<f64>() - CHANNELS.len() as f64).abs() < 1e-9);
        for (c, x) in weights.iter().enumerate() {
            if c != 3 {
                assert!(weights[3] < 0.5 * x, "{weights:?}");
            }
        }
    }

    #[test]
    fn quadratic_weights_reproduce_a_parabola() {
        let nodes = [0.3, 0.9, 1.5];
        let f = |v: f64| 2.0 - 3.0 * v + 1.7 * v * v;
        for v in [0.3, 0.45, 0.6, 0.9, 1.2, 1.37, 1.5] {
            let w = quadratic_weights(&nodes, v);
            let sum: f64 = w.iter().map(|p| p.1).sum();
            let interp: f64 = w.iter().map(|&(i, a)| a * f(nodes[i])).sum();
            assert!((sum - 1.0).abs() < 1e-12);
            assert!((interp - f(v)).abs() < 1e-12, "{v}: {interp} vs {}", f(v));
        }
        // Two nodes: piecewise linear.
        assert_eq!(
            quadratic_weights(&[0.0, 1.0], 0.25),
            hat_weights(&[0.0, 1.0], 0.25)
        );
    }

    #[test]
    fn landmarks_find_the_rise_and_the_zero_crossing() {
        // A ramp to 1 from 5 ms, held to 40 ms, then a cosine from +1 through zero at 45 ms.
        let th: Vec<f64> = (0..151)
            .map(|k| {
                let t = k as f64;
                if t < 5.0 {
                    0.0
                } else if t < 15.0 {
                    (t - 5.0) / 10.0
                } else if t < 40.0 {
                    1.0
                } else {
                    (std::f64::consts::PI * (t - 40.0) / 10.0).cos()
                }
            })
            .collect();
        let mut series = vec![vec![0.0; 151]; CHANNELS.len()];
        series[THETA12] = th;
        let [t1, t2] = landmarks(&series, 1000.0);
        assert!((t1 - 0.007).abs() < 5e-4, "{t1}");
        assert!((t2 - 0.045).abs() < 5e-4, "{t2}");
    }
}
