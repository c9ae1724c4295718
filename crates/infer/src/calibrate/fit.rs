//! The least-squares problem: simulated channels against recorded ones, the sensors' gains and
//! offsets, the Levenberg–Marquardt driver and the Gauss–Newton covariance.

use super::params::{apply, bounds, Param, Reference};
use super::GainHandling;
use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};
use vibrissa_core::rng::Rng;
use vibrissa_core::sim::{self, Response, Scenario};

/// Number of observed channels (theta01, theta12, m0, fx, fy).
pub(super) const CHANNELS: usize = 5;

/// Simulated channels of every run: `[run][channel][sample]`.
pub(super) type Sims = Vec<[Vec<f64>; CHANNELS]>;

/// A finite difference: simulations at one point, at another (`None`: the centre) and the
/// parameter's change from the second to the first.
type Difference = (Sims, Option<Sims>, f64);

/// One labelled recording prepared for fitting.
#[derive(Debug, Clone)]
pub(super) struct Run {
    /// Its name in `truth.csv`.
    pub file: String,
    /// The nominal scenario with its labels, timed like the recording, noise-free, with identity
    /// sensors.
    pub scenario: Scenario,
    /// Recorded channels (`NaN` where a sample is missing; `None` where the recording lacks the
    /// channel): `[channel][sample]`.
    pub y: [Option<Vec<f64>>; CHANNELS],
    /// Samples.
    pub n: usize,
}

/// Everything one fit holds fixed.
pub(super) struct Setup<'a> {
    /// The recordings.
    pub runs: &'a [Run],
    /// Every nonlinear parameter, free or held.
    pub params: &'a [Param],
    /// Constants of the parametrisation.
    pub reference: &'a Reference,
    /// Which parameters are fitted.
    pub free: Vec<bool>,
    /// Values of the held parameters (`None`: nominal).
    pub held: Vec<Option<f64>>,
    /// Channels that some recording has.
    pub channels: Vec<usize>,
    /// Noise standard deviation of each channel (its residuals' weight is 1/σ²).
    pub sigma: [f64; CHANNELS],
    /// Whether each channel's gain is fitted (else held at `nominal`'s).
    pub gain_free: [bool; CHANNELS],
    /// Nominal gains and offsets.
    pub nominal: [Response; CHANNELS],
    /// How gains and offsets are fitted.
    pub handling: GainHandling,
    /// Prior standard deviation of a free gain about its nominal value, relative (0: none).
    pub gain_prior: f64,
    /// Width of the moving average applied to recorded and simulated channels, samples (1: none).
    pub smooth: usize,
    /// The recorded channels as fitted (smoothed by `smooth`): `[run][channel][sample]`.
    pub ys: Vec<[Option<Vec<f64>>; CHANNELS]>,
    /// Robust weights of the samples, `[run][channel][sample]` (empty: every weight 1).
    pub weights: Vec<[Vec<f64>; CHANNELS]>,
    /// Contact substeps of the starting scan's simulations (`None`: the runs' own).
    pub scan_substeps: Option<usize>,
}

/// Tukey's biweight constant, in standard deviations: 95% efficiency for Gaussian noise.
const BIWEIGHT: f64 = 4.685;

impl Setup<'_> {
    /// Weight of sample `k` of channel `c` in run `r`.
    fn weight(&self, r: usize, c: usize, k: usize) -> f64 {
        self.weights
            .get(r)
            .and_then(|w| w[c].get(k))
            .copied()
            .unwrap_or(1.0)
    }

    /// Sets every channel's noise level to a robust estimate from the residuals of `sims` with
    /// `resp` (1.4826 times their median absolute value, at least `floor[c]`), and every
    /// sample's weight to Tukey's biweight of its residual in those units: a sample more than
    /// 4.7σ off (a contact event the model places a time step earlier or later, a glitch)
    /// stops pulling the fit. Returns the largest relative change of a noise level.
    pub fn reweight(
        &mut self,
        sims: &Sims,
        resp: &[Response; CHANNELS],
        floor: &[f64; CHANNELS],
    ) -> f64 {
        let sims = self.view(sims).into_owned();
        let mut change = 0.0f64;
        let mut weights: Vec<[Vec<f64>; CHANNELS]> =
            vec![std::array::from_fn(|_| Vec::new()); self.runs.len()];
        for &c in &self.channels {
            let residuals: Vec<Vec<f64>> = self
                .ys
                .iter()
                .zip(&sims)
                .map(|(ys, sim)| match &ys[c] {
                    Some(y) => sim[c]
                        .iter()
                        .zip(y)
                        .map(|(&s, &y)| resp[c].apply(s) - y)
                        .collect(),
                    None => Vec::new(),
                })
                .collect();
            let mut abs: Vec<f64> = residuals
                .iter()
                .flatten()
                .filter(|e| e.is_finite())
                .map(|e| e.abs())
                .collect();
            if abs.is_empty() {
                continue;
            }
            abs.sort_by(f64::total_cmp);
            let sigma = (1.4826 * abs[abs.len() / 2]).max(floor[c]);
            change = change.max((sigma / self.sigma[c] - 1.0).abs());
            self.sigma[c] = sigma;
            for (r, e) in residuals.iter().enumerate() {
                weights[r][c] = e
                    .iter()
                    .map(|e| {
                        let u = e / (BIWEIGHT * sigma);
                        if u.abs() < 1.0 {
                            (1.0 - u * u).powi(2)
                        } else {
                            0.0
                        }
                    })
                    .collect();
            }
        }
        self.weights = weights;
        change
    }

    /// Indices of the free parameters.
    pub fn free_indices(&self) -> Vec<usize> {
        (0..self.params.len()).filter(|&i| self.free[i]).collect()
    }

    /// Fits channels smoothed by a centred moving average of `width` samples from now on.
    pub fn set_smoothing(&mut self, width: usize) {
        self.smooth = width.max(1);
        self.ys = self
            .runs
            .iter()
            .map(|r| std::array::from_fn(|c| r.y[c].as_ref().map(|y| smooth(y, self.smooth))))
            .collect();
    }

    /// `sims` as fitted (smoothed like the recordings).
    fn view<'s>(&self, sims: &'s Sims) -> std::borrow::Cow<'s, Sims> {
        if self.smooth <= 1 {
            std::borrow::Cow::Borrowed(sims)
        } else {
            std::borrow::Cow::Owned(
                sims.iter()
                    .map(|run| std::array::from_fn(|c| smooth(&run[c], self.smooth)))
                    .collect(),
            )
        }
    }

    /// Every parameter's value from the free ones `z` (in order).
    pub fn full_x(&self, z: &[f64]) -> Vec<Option<f64>> {
        let mut it = z.iter();
        (0..self.params.len())
            .map(|i| {
                if self.free[i] {
                    it.next().copied()
                } else {
                    self.held[i]
                }
            })
            .collect()
    }

    /// Channels whose gain is fitted.
    pub(super) fn gains(&self) -> Vec<usize> {
        self.channels
            .iter()
            .copied()
            .filter(|&c| self.gain_free[c])
            .collect()
    }

    /// Number of residuals: every recorded sample, then one prior term per free gain.
    pub fn residual_count(&self) -> usize {
        self.data_count() + self.prior_count()
    }

    /// Prior terms: one per free gain when gains have a prior.
    fn prior_count(&self) -> usize {
        if self.gain_prior > 0.0 {
            self.gains().len()
        } else {
            0
        }
    }

    /// Prior standard deviation of channel `c`'s gain, absolute.
    fn prior_sd(&self, c: usize) -> f64 {
        self.gain_prior * self.nominal[c].gain.abs().max(f64::MIN_POSITIVE)
    }

    /// Number of recorded samples over all channels.
    fn data_count(&self) -> usize {
        self.channels
            .iter()
            .map(|&c| {
                self.runs
                    .iter()
                    .filter(|r| r.y[c].is_some())
                    .map(|r| r.n)
                    .sum::<usize>()
            })
            .sum()
    }

    /// Simulates every run at `x` in parallel; `None` if any simulation fails.
    pub fn simulate(&self, x: &[Option<f64>], count: &AtomicUsize) -> Option<Sims> {
        self.runs
            .par_iter()
            .map(|run| {
                simulate_run(
                    run,
                    &apply(&run.scenario, self.params, x, self.reference),
                    count,
                )
            })
            .collect()
    }

    /// [`Setup::simulate`] with contact stepped as the starting scan steps it
    /// ([`Setup::scan_substeps`]).
    pub fn simulate_scan(&self, x: &[Option<f64>], count: &AtomicUsize) -> Option<Sims> {
        let Some(substeps) = self.scan_substeps else {
            return self.simulate(x, count);
        };
        self.runs
            .par_iter()
            .map(|run| {
                let mut scenario = apply(&run.scenario, self.params, x, self.reference);
                scenario.integrator.contact_substeps = substeps;
                simulate_run(run, &scenario, count)
            })
            .collect()
    }

    /// The gains and offsets that fit `sims` best in the weighted least-squares sense, per
    /// channel in closed form (a held gain keeps its nominal value; only the offset is fitted).
    pub fn solve_linear(&self, sims: &Sims) -> [Response; CHANNELS] {
        let mut out = self.nominal;
        let sims = self.view(sims);
        for &c in &self.channels {
            // Sums over every recorded sample of the channel.
            let (mut n, mut s1, mut y1, mut ss, mut sy) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for (r, (ys, sim)) in self.ys.iter().zip(sims.iter()).enumerate() {
                let Some(y) = &ys[c] else { continue };
                for (k, (&s, &y)) in sim[c].iter().zip(y).enumerate() {
                    if y.is_finite() {
                        let w = self.weight(r, c, k);
                        n += w;
                        s1 += w * s;
                        y1 += w * y;
                        ss += w * s * s;
                        sy += w * s * y;
                    }
                }
            }
            if n == 0.0 {
                continue;
            }
            // Normal equations of (gain, offset), the gain's prior added in the channel's
            // weighting (σ² of the channel times the prior's precision).
            let g0 = self.nominal[c].gain;
            let p = if self.gain_prior > 0.0 {
                (self.sigma[c] / self.prior_sd(c)).powi(2)
            } else {
                0.0
            };
            let (a11, b1) = (ss + p, sy + p * g0);
            let det = n * a11 - s1 * s1;
            let gain = if self.gain_free[c] && det > 1e-12 * n * a11 {
                (n * b1 - s1 * y1) / det
            } else {
                g0
            };
            out[c] = Response {
                gain,
                offset: (y1 - gain * s1) / n,
            };
        }
        out
    }

    /// Weighted residuals `(gain·sim + offset − recorded)/σ` (0 where a sample is missing).
    pub fn residual(&self, sims: &Sims, resp: &[Response; CHANNELS]) -> DVector<f64> {
        let mut e = Vec::with_capacity(self.residual_count());
        let sims = self.view(sims);
        for &c in &self.channels {
            for (r, (ys, sim)) in self.ys.iter().zip(sims.iter()).enumerate() {
                let Some(y) = &ys[c] else { continue };
                for (k, (&s, &y)) in sim[c].iter().zip(y).enumerate() {
                    e.push(if y.is_finite() {
                        self.weight(r, c, k).sqrt() * (resp[c].apply(s) - y) / self.sigma[c]
                    } else {
                        0.0
                    });
                }
            }
        }
        if self.gain_prior > 0.0 {
            for c in self.gains() {
                e.push((resp[c].gain - self.nominal[c].gain) / self.prior_sd(c));
            }
        }
        DVector::from_vec(e)
    }

    /// Unweighted residual RMS of each channel (`None` for channels without data).
    pub fn rms(&self, sims: &Sims, resp: &[Response; CHANNELS]) -> [Option<f64>; CHANNELS] {
        let mut out = [None; CHANNELS];
        let sims = self.view(sims);
        for &c in &self.channels {
            let (mut sum, mut n) = (0.0, 0usize);
            for (ys, sim) in self.ys.iter().zip(sims.iter()) {
                let Some(y) = &ys[c] else { continue };
                for (&s, &y) in sim[c].iter().zip(y) {
                    if y.is_finite() {
                        sum += (resp[c].apply(s) - y).powi(2);
                        n += 1;
                    }
                }
            }
            if n > 0 {
                out[c] = Some((sum / n as f64).sqrt());
            }
        }
        out
    }

    /// Simulations with each free parameter stepped in turn by ± its step (central
    /// differences; one-sided where one side fails to simulate), in parallel over parameters,
    /// sides and runs. Per free parameter: the simulations after and before (`None`: at `z`
    /// itself) and the distance between them.
    pub(super) fn stepped(&self, z: &[f64], count: &AtomicUsize) -> Option<Vec<Difference>> {
        let free = self.free_indices();
        let runs = self.runs.len();
        let tasks: Vec<(usize, f64, usize)> = (0..free.len())
            .flat_map(|j| [1.0, -1.0].map(|side| (j, side)))
            .flat_map(|(j, side)| (0..runs).map(move |r| (j, side, r)))
            .collect();
        let sims: Vec<Option<[Vec<f64>; CHANNELS]>> = tasks
            .par_iter()
            .map(|&(j, side, r)| self.stepped_run(z, free[j], j, r, side, count))
            .collect();
        let side = |j: usize, k: usize| -> Option<Sims> {
            let at = (2 * j + k) * runs;
            sims[at..at + runs].iter().cloned().collect()
        };
        free.iter()
            .enumerate()
            .map(|(j, &i)| {
                let h = self.params[i].step;
                // A side beyond a bound would be simulated at the bound: one-sided there.
                let (lo, hi) = bounds(self.params[i].kind);
                let up = (z[j] + h <= hi).then(|| side(j, 0)).flatten();
                let down = (z[j] - h >= lo).then(|| side(j, 1)).flatten();
                match (up, down) {
                    (Some(a), Some(b)) => Some((a, Some(b), 2.0 * h)),
                    (Some(a), None) => Some((a, None, h)),
                    (None, Some(b)) => Some((b, None, -h)),
                    (None, None) => None,
                }
            })
            .collect()
    }

    /// Run `r` simulated with free parameter `j` (parameter `i`) stepped by `sign`·step.
    fn stepped_run(
        &self,
        z: &[f64],
        i: usize,
        j: usize,
        r: usize,
        sign: f64,
        count: &AtomicUsize,
    ) -> Option<[Vec<f64>; CHANNELS]> {
        let mut zs = z.to_vec();
        zs[j] += sign * self.params[i].step;
        let x = self.full_x(&zs);
        let run = &self.runs[r];
        simulate_run(
            run,
            &apply(&run.scenario, self.params, &x, self.reference),
            count,
        )
    }

    /// The Jacobian of the weighted residuals with the gains and offsets held at `resp`, with
    /// respect to the free parameters, then the free gains, then every channel's offset.
    pub fn jacobian_full(
        &self,
        z: &[f64],
        sims: &Sims,
        resp: &[Response; CHANNELS],
        count: &AtomicUsize,
    ) -> Option<DMatrix<f64>> {
        let stepped = self.stepped(z, count)?;
        let e = self.residual(sims, resp);
        let gains = self.gains();
        let cols = stepped.len() + gains.len() + self.channels.len();
        let mut jac = DMatrix::zeros(e.len(), cols);
        for (j, (a, b, h)) in stepped.iter().enumerate() {
            let eb = b
                .as_ref()
                .map_or_else(|| e.clone(), |b| self.residual(b, resp));
            jac.set_column(j, &((self.residual(a, resp) - eb) / *h));
        }
        let lin = self.linear_columns(sims);
        for (k, &c) in gains.iter().enumerate() {
            jac.set_column(stepped.len() + k, &lin[c].0);
        }
        for (k, &c) in self.channels.iter().enumerate() {
            jac.set_column(stepped.len() + gains.len() + k, &lin[c].1);
        }
        Some(jac)
    }

    /// Columns of the residuals' derivatives with respect to each channel's gain and offset.
    fn linear_columns(&self, sims: &Sims) -> Vec<(DVector<f64>, DVector<f64>)> {
        let m = self.residual_count();
        let mut out = vec![(DVector::zeros(m), DVector::zeros(m)); CHANNELS];
        let mut row = 0;
        let sims = self.view(sims);
        for &c in &self.channels {
            for (r, (ys, sim)) in self.ys.iter().zip(sims.iter()).enumerate() {
                let Some(y) = &ys[c] else { continue };
                for (k, (&s, &y)) in sim[c].iter().zip(y).enumerate() {
                    if y.is_finite() {
                        let w = self.weight(r, c, k).sqrt();
                        out[c].0[row] = w * s / self.sigma[c];
                        out[c].1[row] = w / self.sigma[c];
                    }
                    row += 1;
                }
            }
        }
        if self.gain_prior > 0.0 {
            for c in self.gains() {
                out[c].0[row] = 1.0 / self.prior_sd(c);
                row += 1;
            }
        }
        out
    }
}

/// Centred moving average of `x` over `width` samples (fewer at the ends), skipping `NaN`s; a
/// sample whose window holds no number stays `NaN`.
fn smooth(x: &[f64], width: usize) -> Vec<f64> {
    if width <= 1 {
        return x.to_vec();
    }
    let half = width / 2;
    let n = x.len();
    // Prefix sums of the finite values and their count.
    let (mut sum, mut cnt) = (vec![0.0; n + 1], vec![0usize; n + 1]);
    for k in 0..n {
        let ok = x[k].is_finite();
        sum[k + 1] = sum[k] + if ok { x[k] } else { 0.0 };
        cnt[k + 1] = cnt[k] + usize::from(ok);
    }
    (0..n)
        .map(|k| {
            let (a, b) = (k.saturating_sub(half), (k + half + 1).min(n));
            let m = cnt[b] - cnt[a];
            if m == 0 || !x[k].is_finite() {
                f64::NAN
            } else {
                (sum[b] - sum[a]) / m as f64
            }
        })
        .collect()
}

/// The observed channels of one simulated run, or `None` if it fails or its length differs.
fn simulate_run(
    run: &Run,
    scenario: &Scenario,
    count: &AtomicUsize,
) -> Option<[Vec<f64>; CHANNELS]> {
    count.fetch_add(1, Ordering::Relaxed);
    let out = sim::run(scenario, &mut |_| {}).ok()?;
    if out.rows.len() < run.n {
        return None;
    }
    let rows = &out.rows[..run.n];
    Some(std::array::from_fn(|c| {
        rows.iter().map(|r| r[c + 1]).collect()
    }))
}

/// A finished fit.
pub(super) struct Solution {
    /// Free parameters' values, in order.
    pub z: Vec<f64>,
    /// Simulations at `z`.
    pub sims: Sims,
    /// Gains and offsets at `z`.
    pub resp: [Response; CHANNELS],
    /// Jacobian evaluations (iterations).
    pub iterations: usize,
}

/// Seed of the points at which the roughness is sampled (fixed: a calibration is repeatable).
const ROUGHNESS_SEED: u64 = 0x0C0F;

/// Standard errors and degeneracy at a solution, from the Gauss–Newton Hessian.
pub(super) struct Covariance {
    /// Covariance of the free parameters, then the free gains, then every channel's offset
    /// (a pseudo-inverse where the Jacobian is rank-deficient); with the roughness once
    /// [`add_roughness`] has run.
    pub cov: DMatrix<f64>,
    /// Singular values of the column-normalised Jacobian, relative to the largest, with the
    /// index of the column that dominates each one's right singular vector.
    pub weak: Vec<(f64, usize)>,
    /// The Jacobian of the weighted residuals at the solution.
    jac: DMatrix<f64>,
    /// The weighted residuals at the solution.
    e: DVector<f64>,
    /// `(JᵀJ)⁻¹` (pseudo-inverse).
    inv: DMatrix<f64>,
}

/// The covariance `s²·(JᵀJ)⁻¹` at `sol`, with the Jacobian in [`Setup::jacobian_full`]'s order.
pub(super) fn covariance(setup: &Setup, sol: &Solution, count: &AtomicUsize) -> Result<Covariance> {
    let jac = setup
        .jacobian_full(&sol.z, &sol.sims, &sol.resp, count)
        .ok_or_else(|| Error::Calibration("a simulation failed next to the solution".into()))?;
    let e = setup.residual(&sol.sims, &sol.resp);
    let (m, p) = jac.shape();
    // Residual variance per degree of freedom, inflated for correlated residuals: what a fit
    // leaves is rarely white (a model that cannot follow a release event leaves a run of
    // same-signed residuals), and n correlated residuals carry the information of fewer
    // independent ones. With r the lag-1 autocorrelation of the residuals (an AR(1) picture),
    // the variance of a fitted quantity grows by (1 + r)/(1 − r).
    let r = lag1_autocorrelation(e.as_slice()).clamp(0.0, 0.99);
    let s2 = e.norm_squared() / (m.saturating_sub(p)).max(1) as f64 * (1.0 + r) / (1.0 - r);

    // Column-normalised Jacobian: its singular values show degenerate combinations.
    let norms: Vec<f64> = (0..p).map(|j| jac.column(j).norm()).collect();
    let mut scaled = jac.clone();
    for (j, &nj) in norms.iter().enumerate() {
        if nj > 0.0 {
            scaled.column_mut(j).scale_mut(1.0 / nj);
        }
    }
    let svd = scaled.clone().svd(false, true);
    let smax = svd.singular_values.max().max(f64::MIN_POSITIVE);
    let vt = svd
        .v_t
        .clone()
        .ok_or_else(|| Error::Calibration("singular value decomposition failed".into()))?;
    let mut weak: Vec<(f64, usize)> = (0..svd.singular_values.len())
        .map(|k| {
            let row = vt.row(k);
            let dominant = (0..p)
                .max_by(|&a, &b| row[a].abs().total_cmp(&row[b].abs()))
                .unwrap_or(0);
            (svd.singular_values[k] / smax, dominant)
        })
        .collect();
    weak.sort_by(|a, b| a.0.total_cmp(&b.0));
    // Zero columns have no direction at all.
    for (j, &nj) in norms.iter().enumerate() {
        if nj == 0.0 {
            weak.insert(0, (0.0, j));
        }
    }

    // (JᵀJ)⁻¹ in the scaled coordinates, pseudo-inverted past a relative cutoff.
    let jtj = scaled.transpose() * &scaled;
    let eig = jtj.symmetric_eigen();
    let lmax = eig.eigenvalues.max().max(f64::MIN_POSITIVE);
    let mut inv: DMatrix<f64> = DMatrix::zeros(p, p);
    for k in 0..p {
        let l = eig.eigenvalues[k];
        if l > 1e-14 * lmax {
            let v = eig.eigenvectors.column(k);
            inv += (v * v.transpose()) / l;
        }
    }
    // Back to the unscaled coordinates.
    for a in 0..p {
        for b in 0..p {
            let d = norms[a] * norms[b];
            inv[(a, b)] = if d > 0.0 { inv[(a, b)] / d } else { 0.0 };
        }
    }
    let mut cov = &inv * s2;
    // A zero column's parameter has no information: infinite variance.
    for (j, &nj) in norms.iter().enumerate() {
        if nj == 0.0 {
            cov[(j, j)] = f64::INFINITY;
        }
    }
    Ok(Covariance {
        cov,
        weak,
        jac,
        e,
        inv,
    })
}

/// Adds to `cov` (computed at `sol` by [`covariance`]) what the simulations' roughness adds to
/// the fitted values' covariance: `(JᵀJ)⁻¹ M (JᵀJ)⁻¹` with `M` from [`roughness`].
pub(super) fn add_roughness(
    setup: &Setup,
    sol: &Solution,
    cov: &mut Covariance,
    count: &AtomicUsize,
) -> Result<()> {
    let m = roughness(setup, sol, &cov.jac, &cov.e, count)
        .ok_or_else(|| Error::Calibration("a simulation failed next to the solution".into()))?;
    let extra = &cov.inv * m * &cov.inv;
    cov.cov += extra;
    Ok(())
}

/// Lag-1 autocorrelation of `e` (consecutive entries; the joins between recordings and channels
/// are few against the samples and are not treated apart).
fn lag1_autocorrelation(e: &[f64]) -> f64 {
    let ss: f64 = e.iter().map(|x| x * x).sum();
    if e.len() < 3 || ss <= 0.0 {
        return 0.0;
    }
    let lag: f64 = e.windows(2).map(|w| w[0] * w[1]).sum();
    lag / ss
}

/// Points next to the solution at which the simulations' roughness is sampled.
const ROUGHNESS_SAMPLES: usize = 32;

/// What the simulations' roughness adds to the fitted values' covariance, as the matrix
/// `M = Σ_k (Jᵀd_k)(Jᵀd_k)ᵀ / (2K)` of the covariance `(JᵀJ)⁻¹ M (JᵀJ)⁻¹`.
///
/// The simulated channels are not smooth in the parameters: a contact event falls on one time
/// step or the next, and the residual changes by a step of its own. At a solution the fit
/// therefore sees, besides the recordings' noise, a residual that a small change of the
/// parameters redraws. `d_k` is what the linear model `e + J·δ_k` misses of the weighted
/// residuals at `K` points `z + δ_k` next to the solution (every free parameter stepped by
/// ± half its finite-difference step, the signs at random from a fixed seed; gains and offsets
/// held); the difference of two draws has twice the variance of one, hence the 2. `None` when
/// a simulation fails.
fn roughness(
    setup: &Setup,
    sol: &Solution,
    jac: &DMatrix<f64>,
    e: &DVector<f64>,
    count: &AtomicUsize,
) -> Option<DMatrix<f64>> {
    let free = setup.free_indices();
    let q = free.len();
    let p = jac.ncols();
    if q == 0 {
        return Some(DMatrix::zeros(p, p));
    }
    let mut rng = Rng::stream(ROUGHNESS_SEED, 0);
    let points: Vec<Vec<f64>> = (0..ROUGHNESS_SAMPLES)
        .map(|_| {
            free.iter()
                .zip(&sol.z)
                .map(|(&i, &z)| {
                    let sign = if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
                    let (lo, hi) = bounds(setup.params[i].kind);
                    (z + 0.5 * sign * setup.params[i].step).clamp(lo, hi)
                })
                .collect()
        })
        .collect();
    let sims: Vec<Option<Sims>> = points
        .par_iter()
        .map(|z| setup.simulate(&setup.full_x(z), count))
        .collect();
    let mut m = DMatrix::zeros(p, p);
    for (z, sims) in points.iter().zip(&sims) {
        let dz = DVector::from_iterator(q, z.iter().zip(&sol.z).map(|(a, b)| a - b));
        let d = setup.residual(sims.as_ref()?, &sol.resp) - e - jac.columns(0, q) * dz;
        let g = jac.transpose() * d;
        m += &g * g.transpose();
    }
    Some(m / (2.0 * ROUGHNESS_SAMPLES as f64))
}
