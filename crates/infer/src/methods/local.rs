//! Two-stage estimate: a global kernel ridge regression, refined by a ridge regression on the
//! principal components of the training runs whose parameters lie nearest the first estimate,
//! with their series optionally registered to the first estimate's box travel, repeated about
//! the refined estimate where that helps.

use super::krr::Krr;
use crate::error::{Error, Result};
use crate::experiment::{Sample, CHANNELS};
use crate::features::{channel_scales, coverage_factor_at, flatten};
use crate::method::{Budget, Estimate, Method, Training};
use nalgebra::DMatrix;
use rayon::prelude::*;

/// Neighbourhood sizes tried.
const NEIGHBOURS: [usize; 3] = [20, 30, 45];
/// Principal components tried.
const COMPONENTS: [usize; 5] = [4, 8, 12, 18, 25];
/// Ridges tried, as fractions of the leading component's variance.
const RIDGES: [f64; 5] = [1e-6, 1e-5, 1e-4, 1e-3, 1e-2];
/// Share of held-out errors that the 90% intervals are widened to hold (above 0.9: the
/// held-out runs lie inside the range more often than the grid's edge runs do).
const QUANTILE: f64 = 0.93;
/// Neighbourhood shapes tried: whether the series are registered in travel, and the speed's
/// weight in the distance to the first estimate (`e1` uses the first only).
const SHAPES: [(bool, f64); 4] = [(false, 1.0), (true, 1.0), (false, 0.3), (true, 0.3)];
/// Most passes of the local regression tried.
const MAX_PASSES: usize = 3;
/// Every `HOLD`-th training run is held out while the hyper-parameters are chosen.
const HOLD: usize = 5;

/// One unknown's refinement settings.
#[derive(Debug, Clone, Copy, Default)]
struct Head {
    /// Neighbours.
    neighbours: usize,
    /// Components.
    components: usize,
    /// Ridge fraction.
    ridge: f64,
    /// Whether the neighbours' series are registered in travel.
    registered: bool,
    /// Weight of the speed in the distance that picks the neighbours (below 1: runs at the
    /// estimated distance, over a wider span of speeds).
    speed_weight: f64,
    /// Factor from the neighbourhood's leave-one-out spread to the std.
    factor: f64,
    /// Whether the first stage's estimate is kept (it did better on the held-out runs).
    first: bool,
    /// Local regressions in turn, each about the previous one's estimate of this unknown.
    passes: usize,
}

/// A global kernel ridge regression (first estimate) refined locally: the training runs nearest
/// the first estimate in normalised parameter space (the speed's distance optionally weighted
/// down, so that the neighbours share the estimated distance over a wider span of speeds), their
/// series optionally resampled so that the box's travel matches the observation's under the
/// first estimate's speed, reduced to their leading principal components and regressed linearly
/// (ridge) on each unknown; optionally repeated about the refined estimate. Neighbourhood size
/// and shape, components, ridge, registration and passes are chosen per unknown on every fifth
/// training run (both stages fitted on the rest); the std is the neighbourhood's leave-one-out
/// spread, scaled so that 90% intervals cover 93% of the held-out errors.
#[derive(Debug, Clone, Default)]
pub struct LocalKrr {
    /// First stage.
    global: Krr,
    /// Channel scales.
    scales: Vec<f64>,
    /// Training runs' normalised series, `[runs][CHANNELS][SAMPLES]`.
    series: Vec<Vec<Vec<f64>>>,
    /// Training runs' unknowns scaled to [0, 1], `[runs][unknowns]`.
    y: Vec<Vec<f64>>,
    /// Training runs' speeds, m/s (1 where the family has no speed).
    speeds: Vec<f64>,
    /// Which unknown is the object's speed `v`, if one is.
    v_index: Option<usize>,
    /// The speed when it is not an unknown (the family's fixed `v`, else 1).
    fixed_speed: f64,
    /// Unknowns' ranges.
    ranges: Vec<[f64; 2]>,
    /// Per unknown.
    heads: Vec<Head>,
}

/// `series` (channel-major, normalised) sampled at times scaled by `r` (held at the last sample).
fn register(series: &[Vec<f64>], r: f64) -> Vec<f64> {
    let samples = series.first().map_or(0, |ch| ch.len());
    let mut out = Vec::with_capacity(series.len() * samples);
    for ch in series {
        for k in 0..samples {
            let t = (k as f64 * r).min((samples - 1) as f64);
            let i = (t.floor() as usize).min(samples.saturating_sub(2));
            let f = t - i as f64;
            out.push(ch[i] * (1.0 - f) + ch[i + 1] * f);
        }
    }
    out
}

/// The factor `f` such that `|e| ≤ Z90·f·s` holds for a share [`QUANTILE`] of the pairs `(e, s)`.
fn widening(pairs: &[(f64, f64)]) -> f64 {
    coverage_factor_at(pairs, QUANTILE)
}

/// The local regressions' predictions and leave-one-out spreads for one observation.
struct Local {
    /// `[components][ridges][unknowns]` → (prediction, leave-one-out rms), scaled units.
    out: Vec<Vec<Vec<(f64, f64)>>>,
}

/// Ridge principal-component regressions of `y` (`[unknowns][n]`) on the rows of `x`, evaluated
/// at `obs`, for every entry of [`COMPONENTS`] and [`RIDGES`].
fn local_fit(x: &[Vec<f64>], y: &[Vec<f64>], obs: &[f64]) -> Local {
    let n = x.len();
    let dim = obs.len();
    let mut mean = vec![0.0; dim];
    for r in x {
        for (m, v) in mean.iter_mut().zip(r) {
            *m += v / n as f64;
        }
    }
    let c: Vec<Vec<f64>> = x
        .iter()
        .map(|r| r.iter().zip(&mean).map(|(a, m)| a - m).collect())
        .collect();
    let mut g = DMatrix::<f64>::zeros(n, n);
    for i in 0..n {
        for j in 0..=i {
            let v: f64 = c[i].iter().zip(&c[j]).map(|(a, b)| a * b).sum();
            g[(i, j)] = v;
            g[(j, i)] = v;
        }
    }
    let co: Vec<f64> = c
        .iter()
        .map(|r| {
            r.iter()
                .zip(obs)
                .zip(&mean)
                .map(|((a, o), m)| a * (o - m))
                .sum()
        })
        .collect();
    let eig = g.symmetric_eigen();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let lam1 = eig.eigenvalues[order[0]].max(1e-30);
    let ybar: Vec<f64> = y.iter().map(|t| t.iter().sum::<f64>() / n as f64).collect();
    // Per component: λ, u·c, u·y per unknown, and u itself.
    let comps: Vec<(f64, f64, Vec<f64>, Vec<f64>)> = order
        .iter()
        .take(*COMPONENTS.iter().max().expect("nonempty"))
        .filter(|&&k| eig.eigenvalues[k] > 1e-12 * lam1)
        .map(|&k| {
            let u: Vec<f64> = eig.eigenvectors.column(k).iter().copied().collect();
            let uc: f64 = u.iter().zip(&co).map(|(a, b)| a * b).sum();
            let uy: Vec<f64> = y
                .iter()
                .map(|t| u.iter().zip(t).map(|(a, b)| a * b).sum())
                .collect();
            (eig.eigenvalues[k], uc, uy, u)
        })
        .collect();
    let out = COMPONENTS
        .iter()
        .map(|&p| {
            RIDGES
                .iter()
                .map(|&a| {
                    let pen = a * lam1;
                    let used = &comps[..p.min(comps.len())];
                    // Hat diagonal and fitted values.
                    let mut h = vec![1.0 / n as f64; n];
                    let mut fitted: Vec<Vec<f64>> = ybar.iter().map(|&m| vec![m; n]).collect();
                    let mut pred = ybar.clone();
                    for (lam, uc, uy, u) in used {
                        let s = 1.0 / (lam + pen);
                        for (i, ui) in u.iter().enumerate() {
                            h[i] += lam * s * ui * ui;
                        }
                        for (q, f) in fitted.iter_mut().enumerate() {
                            let w = lam * s * uy[q];
                            for (fi, ui) in f.iter_mut().zip(u) {
                                *fi += w * ui;
                            }
                            pred[q] += s * uy[q] * uc;
                        }
                    }
                    (0..y.len())
                        .map(|q| {
                            let ss: f64 = (0..n)
                                .map(|i| {
                                    let e = (y[q][i] - fitted[q][i]) / (1.0 - h[i]).max(1e-6);
                                    e * e
                                })
                                .sum();
                            (pred[q], (ss / n as f64).sqrt())
                        })
                        .collect()
                })
                .collect()
        })
        .collect();
    Local { out }
}

impl LocalKrr {
    /// An unfitted two-stage regression.
    pub fn new() -> LocalKrr {
        LocalKrr::default()
    }

    /// Scaled unknowns of the first estimate.
    fn scaled(&self, est: &[Estimate]) -> Vec<f64> {
        est.iter()
            .zip(&self.ranges)
            .map(|(e, [lo, hi])| ((e.mean - lo) / (hi - lo)).clamp(0.0, 1.0))
            .collect()
    }

    /// Indices of `pool`'s runs nearest `p0` (scaled unknowns), nearest first.
    fn nearest(&self, pool: &[usize], p0: &[f64], k: usize, speed_weight: f64) -> Vec<usize> {
        let mut d: Vec<(f64, usize)> = pool
            .iter()
            .map(|&i| {
                let s: f64 = self.y[i]
                    .iter()
                    .zip(p0)
                    .enumerate()
                    .map(|(q, (a, b))| {
                        let w = if Some(q) == self.v_index {
                            speed_weight
                        } else {
                            1.0
                        };
                        (w * (a - b)).powi(2)
                    })
                    .sum();
                (s, i)
            })
            .collect();
        d.sort_by(|a, b| a.0.total_cmp(&b.0));
        d.into_iter().take(k).map(|(_, i)| i).collect()
    }

    /// Unknown `q`'s local regression under `h` at `obs` (normalised, flattened) among `pool`,
    /// starting from the first estimate `p0` (scaled) with speed `v0`: (estimate, leave-one-out
    /// spread), scaled units, after `h.passes` passes.
    fn refined(
        &self,
        pool: &[usize],
        p0: &[f64],
        v0: f64,
        obs: &[f64],
        q: usize,
        h: &Head,
    ) -> (f64, f64) {
        let c = COMPONENTS
            .iter()
            .position(|&p| p == h.components)
            .unwrap_or(0);
        let d = RIDGES.iter().position(|&r| r == h.ridge).unwrap_or(0);
        let (mut p, mut v) = (p0.to_vec(), v0);
        let mut out = (p0[q], 0.0);
        for _ in 0..h.passes.max(1) {
            let l = self.locals(
                pool,
                &p,
                v,
                obs,
                h.neighbours,
                (h.registered, h.speed_weight),
            );
            out = l.out[c][d][q];
            p[q] = out.0.clamp(0.0, 1.0);
            if Some(q) == self.v_index {
                let [lo, hi] = self.ranges[q];
                v = lo + (hi - lo) * p[q];
            }
        }
        out
    }

    /// Local fits at `obs` (normalised, flattened) around the first estimate `p0` (scaled) with
    /// speed `v0`, among `pool`, for `k` neighbours and either registration.
    fn locals(
        &self,
        pool: &[usize],
        p0: &[f64],
        v0: f64,
        obs: &[f64],
        k: usize,
        (reg, speed_weight): (bool, f64),
    ) -> Local {
        let idx = self.nearest(pool, p0, k, speed_weight);
        let x: Vec<Vec<f64>> = idx
            .iter()
            .map(|&i| {
                let r = if reg { v0 / self.speeds[i] } else { 1.0 };
                register(&self.series[i], r)
            })
            .collect();
        let y: Vec<Vec<f64>> = (0..self.ranges.len())
            .map(|q| idx.iter().map(|&i| self.y[i][q]).collect())
            .collect();
        local_fit(&x, &y, obs)
    }
}

impl Method for LocalKrr {
    fn name(&self) -> &'static str {
        "krr-local"
    }

    fn budget(&self) -> Budget {
        Budget::Free
    }

    fn channels(&self) -> Vec<usize> {
        (0..CHANNELS.len()).collect()
    }

    fn fit(&mut self, training: &Training) -> Result<()> {
        let s: &[Sample] = &training.samples;
        if s.len() < 2 * NEIGHBOURS[NEIGHBOURS.len() - 1] {
            return Err(Error::Fit {
                method: "krr-local".into(),
                detail: format!(
                    "needs at least {} training runs",
                    2 * NEIGHBOURS[NEIGHBOURS.len() - 1]
                ),
            });
        }
        // The first stage on every run first: when `krr` has just learnt from the same runs, its
        // fit is reused (before the held-out fit below replaces it as the latest).
        self.global.fit(training)?;
        let channels: Vec<usize> = (0..CHANNELS.len()).collect();
        self.scales = channel_scales(s, &channels);
        self.ranges = training.family.ranges();
        self.series = s
            .iter()
            .map(|r| {
                r.series
                    .iter()
                    .zip(&self.scales)
                    .map(|(ch, sc)| ch.iter().map(|x| x / sc).collect())
                    .collect()
            })
            .collect();
        self.y = s
            .iter()
            .map(|r| {
                self.ranges
                    .iter()
                    .enumerate()
                    .map(|(u, [lo, hi])| (r.params[u] - lo) / (hi - lo))
                    .collect()
            })
            .collect();
        self.v_index = training.family.unknowns().iter().position(|k| *k == "v");
        self.fixed_speed = training.family.speed_of(&[]).unwrap_or(1.0);
        self.speeds = s
            .iter()
            .map(|r| training.family.speed_of(&r.params).unwrap_or(1.0))
            .collect();
        let unknowns = self.ranges.len();

        // Both stages fitted on the rest, scored on every HOLD-th run.
        let (fit_i, held_i): (Vec<usize>, Vec<usize>) = (0..s.len()).partition(|i| i % HOLD != 0);
        // Only held-out runs inside the range score (those beyond its edges are fitted on).
        let held_i: Vec<usize> = held_i
            .into_iter()
            .filter(|&i| self.y[i].iter().all(|y| (0.0..=1.0).contains(y)))
            .collect();
        let mut first = Krr::new();
        first.fit(&Training {
            family: training.family.clone(),
            samples: fit_i.iter().map(|&i| s[i].clone()).collect(),
            calibration: Vec::new(),
            noise: training.noise,
        })?;
        let regs: &[(bool, f64)] = if self.v_index.is_some() {
            &SHAPES
        } else {
            &SHAPES[..1]
        };
        // `[held][neighbours][registration]` → Local.
        let scored: Vec<(Vec<Estimate>, Vec<Vec<Local>>)> = held_i
            .par_iter()
            .map(|&h| -> Result<(Vec<Estimate>, Vec<Vec<Local>>)> {
                let est = first.predict(&s[h].series)?;
                let p0 = self.scaled(&est);
                let v0 = self.v_index.map_or(self.fixed_speed, |i| est[i].mean);
                let obs = flatten(&s[h].series, &channels, &self.scales)?;
                let l = NEIGHBOURS
                    .iter()
                    .map(|&k| {
                        regs.iter()
                            .map(|&reg| self.locals(&fit_i, &p0, v0, &obs, k, reg))
                            .collect()
                    })
                    .collect();
                Ok((est, l))
            })
            .collect::<Result<_>>()?;
        self.heads = (0..unknowns)
            .map(|q| {
                let [lo, hi] = self.ranges[q];
                let kept: f64 = held_i
                    .iter()
                    .zip(&scored)
                    .map(|(&h, (e, _))| ((e[q].mean - lo) / (hi - lo) - self.y[h][q]).abs())
                    .sum();
                let mut best = (
                    kept,
                    Head {
                        first: true,
                        ..Head::default()
                    },
                );
                for (a, &k) in NEIGHBOURS.iter().enumerate() {
                    for (b, &(reg, speed_weight)) in regs.iter().enumerate() {
                        for (c, &p) in COMPONENTS.iter().enumerate() {
                            for (d, &r) in RIDGES.iter().enumerate() {
                                let err: f64 = held_i
                                    .iter()
                                    .zip(&scored)
                                    .map(|(&h, (_, l))| {
                                        (l[a][b].out[c][d][q].0.clamp(0.0, 1.0) - self.y[h][q])
                                            .abs()
                                    })
                                    .sum();
                                if err < best.0 {
                                    let pairs: Vec<(f64, f64)> = held_i
                                        .iter()
                                        .zip(&scored)
                                        .map(|(&h, (_, l))| {
                                            let (m, sd) = l[a][b].out[c][d][q];
                                            (m.clamp(0.0, 1.0) - self.y[h][q], sd)
                                        })
                                        .collect();
                                    best = (
                                        err,
                                        Head {
                                            neighbours: k,
                                            components: p,
                                            ridge: r,
                                            registered: reg,
                                            speed_weight,
                                            factor: widening(&pairs),
                                            first: false,
                                            passes: 1,
                                        },
                                    );
                                }
                            }
                        }
                    }
                }
                best.1
            })
            .collect();
        // Further passes, each about the previous estimate, where they help on the held-out runs.
        let obs: Vec<Vec<f64>> = held_i
            .iter()
            .map(|&h| flatten(&s[h].series, &channels, &self.scales))
            .collect::<Result<_>>()?;
        for q in 0..unknowns {
            let head = self.heads[q];
            if head.first {
                continue;
            }
            let mut best_err = f64::INFINITY;
            for passes in 1..=MAX_PASSES {
                let h = Head { passes, ..head };
                let pairs: Vec<(f64, f64)> = held_i
                    .par_iter()
                    .zip(&scored)
                    .zip(&obs)
                    .map(|((&i, (e, _)), x)| {
                        let p0 = self.scaled(e);
                        let v0 = self.v_index.map_or(self.fixed_speed, |i| e[i].mean);
                        let (m, sd) = self.refined(&fit_i, &p0, v0, x, q, &h);
                        (m.clamp(0.0, 1.0) - self.y[i][q], sd)
                    })
                    .collect();
                let err: f64 = pairs.iter().map(|(e, _)| e.abs()).sum();
                if err < best_err {
                    best_err = err;
                    self.heads[q] = Head {
                        factor: widening(&pairs),
                        ..h
                    };
                }
            }
        }
        Ok(())
    }

    fn predict(&self, obs: &[Vec<f64>]) -> Result<Vec<Estimate>> {
        if self.heads.is_empty() {
            return Err(Error::Fit {
                method: "krr-local".into(),
                detail: "not fitted".into(),
            });
        }
        let channels: Vec<usize> = (0..CHANNELS.len()).collect();
        let est = self.global.predict(obs)?;
        let p0 = self.scaled(&est);
        let v0 = self.v_index.map_or(self.fixed_speed, |i| est[i].mean);
        let x = flatten(obs, &channels, &self.scales)?;
        let pool: Vec<usize> = (0..self.series.len()).collect();
        Ok(self
            .heads
            .iter()
            .enumerate()
            .map(|(q, h)| {
                if h.first {
                    return est[q];
                }
                let (m, sd) = self.refined(&pool, &p0, v0, &x, q, h);
                let [lo, hi] = self.ranges[q];
                Estimate::normal(
                    lo + (hi - lo) * m.clamp(0.0, 1.0),
                    h.factor * sd * (hi - lo),
                )
            })
            .collect())
    }

    fn settings(&self) -> Vec<(String, f64)> {
        let mut s = Vec::new();
        for (h, name) in self.heads.iter().zip(["d", "v"]) {
            s.push((format!("neighbours_{name}"), h.neighbours as f64));
            s.push((format!("components_{name}"), h.components as f64));
            s.push((format!("ridge_{name}"), h.ridge));
            s.push((
                format!("registered_{name}"),
                f64::from(u8::from(h.registered)),
            ));
            s.push((format!("speed_weight_{name}"), h.speed_weight));
            s.push((format!("passes_{name}"), h.passes as f64));
            s.push((format!("std_factor_{name}"), h.factor));
            s.push((format!("first_stage_{name}"), f64::from(u8::from(h.first))));
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_small_speed_weight_picks_runs_at_the_estimated_distance_over_more_speeds() {
        // Runs on a 5 × 5 lattice of scaled (d, v).
        let y: Vec<Vec<f64>> = (0..25)
            .map(|k| vec![(k / 5) as f64 * 0.25, (k % 5) as f64 * 0.25])
            .collect();
        let m = LocalKrr {
            y,
            v_index: Some(1),
            ..LocalKrr::default()
        };
        let pool: Vec<usize> = (0..25).collect();
        let p0 = [0.5, 0.5];
        // Equal weights: the centre and its four lattice neighbours, two of them at other d.
        let even = m.nearest(&pool, &p0, 5, 1.0);
        assert_eq!(even[0], 12);
        assert_eq!(even.iter().filter(|&&i| m.y[i][0] != 0.5).count(), 2);
        // Speed weighted by 0.3: all five speeds at d = 0.5 come first.
        let wide = m.nearest(&pool, &p0, 5, 0.3);
        assert!(wide.iter().all(|&i| m.y[i][0] == 0.5), "{wide:?}");
    }
}
