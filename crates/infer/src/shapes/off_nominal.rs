//! How far a shape estimator's reading of a recording can be trusted when the recording lies
//! farther from everything it can simulate than its own held-out runs do (its misfit ratio
//! `r` > 1), fitted on held-out runs of whiskers it does not simulate.
//!
//! Scaling the evidence's temperature by `r` widens the class posterior where the distances grow,
//! but another whisker's recording, read through one whisker, often lies close to a run of the
//! wrong pose or class: wrong, yet not far. How often a reading at a given misfit is wrong is
//! measured instead, on noisy runs of whiskers drawn from the randomisation prior (the whisker's
//! modulus, density, damping, taper, follicle, chain and sensor gains drawn around the nominal,
//! or around a calibrated whisker within its fit's errors): the class posterior `p` becomes
//! `(1 − α)·p + α/K` with `α = 1 − (1 − α₀)·(r/r₀)^(−κ)` above a threshold `r₀` (nothing below
//! it), `r₀`, `α₀` and `κ` the values whose log loss, averaged over those runs and the estimator's
//! own held-out runs, is lowest, with `r₀` at least the misfit ratio of 90% of the own held-out runs (a
//! reading that lies as near as those is left as it is: where the misfits of the two kinds of
//! runs overlap, spreading would cost the whisker the estimator simulates what it buys another
//! whisker). A pose interval widens by `r^δ`, `δ` the least power (from ½, the reduced-χ² rule)
//! at which the intervals of the drawn whiskers' runs named right hold 90% of their errors (the
//! intervals' width at `r` = 1 is then the split-conformal one of the own held-out runs' errors
//! divided by `r^δ`, so that they stay calibrated on the own whisker).

/// Powers of the misfit ratio by which a pose interval may widen, tried from the least.
pub(super) const POWERS: [f64; 7] = [0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0];

/// Share of the errors that the widened intervals of the drawn whiskers' runs must hold.
const COVERAGE: f64 = 0.9;

/// Values of `κ` tried: 0 to 4 in steps of 0.05.
fn powers() -> impl Iterator<Item = f64> {
    (0..=80).map(|k| 0.05 * k as f64)
}

/// Shares `α₀` tried: 0 to 0.95 in steps of 0.05.
fn steps() -> impl Iterator<Item = f64> {
    (0..=19).map(|k| 0.05 * k as f64)
}

/// Thresholds `r₀` tried, in units of the own held-out runs' 90% quantile of the misfit ratio.
const THRESHOLDS: [f64; 8] = [1.0, 1.25, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0];

/// Share of the own held-out runs whose misfit ratio the least threshold lies above.
const OWN_UNTOUCHED: f64 = 0.9;

/// How far a reading is trusted: `1 − (1 − α₀)·(r/r₀)^(−κ)` of a class posterior at misfit
/// ratio `r` > `r₀` is spread evenly. The default trusts every reading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Trust {
    /// `r₀`, at least 1.
    pub threshold: f64,
    /// `α₀`, in [0, 1).
    pub step: f64,
    /// `κ`, at least 0.
    pub power: f64,
}

impl Default for Trust {
    fn default() -> Trust {
        Trust {
            threshold: 1.0,
            step: 0.0,
            power: 0.0,
        }
    }
}

/// The share of the class posterior spread evenly at misfit ratio `ratio` under `trust`.
pub(super) fn even_share(ratio: f64, trust: Trust) -> f64 {
    let over = ratio / trust.threshold;
    if over > 1.0 {
        1.0 - (1.0 - trust.step) * over.powf(-trust.power)
    } else {
        0.0
    }
}

/// The class posterior `p` of a recording at misfit ratio `ratio`, with [`even_share`] of it
/// spread evenly.
pub(super) fn trusted(p: &[f64], ratio: f64, trust: Trust) -> Vec<f64> {
    let a = even_share(ratio, trust);
    let k = p.len() as f64;
    p.iter().map(|q| (1.0 - a) * q + a / k).collect()
}

/// Class posteriors of held-out recordings, their true classes and misfit ratios.
#[derive(Clone, Copy)]
pub(super) struct Readings<'a> {
    pub probs: &'a [Vec<f64>],
    pub truth: &'a [usize],
    pub ratio: &'a [f64],
}

impl Readings<'_> {
    /// Mean log loss of the posteriors after [`trusted`] with `trust` (NaN for none).
    pub(super) fn log_loss(&self, trust: Trust) -> f64 {
        let n = self.probs.len();
        let sum: f64 = self
            .probs
            .iter()
            .zip(self.truth)
            .zip(self.ratio)
            .map(|((p, &c), &r)| {
                let a = even_share(r, trust);
                -((1.0 - a) * p[c] + a / p.len() as f64).max(1e-300).ln()
            })
            .sum();
        sum / n as f64
    }
}

/// The trust with the lowest mean of the two sets' mean log losses, its threshold a multiple
/// of the `own` runs' 90% quantile of the misfit ratio (on ties the lowest, then the least share
/// and power). Full trust when either set is empty or nothing does better.
pub(super) fn fit_trust(own: &Readings, drawn: &Readings) -> Trust {
    if own.probs.is_empty() || drawn.probs.is_empty() {
        return Trust::default();
    }
    let mut best = (
        0.5 * (own.log_loss(Trust::default()) + drawn.log_loss(Trust::default())),
        Trust::default(),
    );
    let least = own_bound(own.ratio);
    for threshold in THRESHOLDS.map(|t| t * least) {
        for step in steps() {
            for power in powers() {
                let t = Trust {
                    threshold,
                    step,
                    power,
                };
                let loss = 0.5 * (own.log_loss(t) + drawn.log_loss(t));
                if loss < best.0 {
                    best = (loss, t);
                }
            }
        }
    }
    best.1
}

/// The misfit ratio below which 90% of the `ratio`s lie (1 when there are none).
pub(super) fn own_bound(ratio: &[f64]) -> f64 {
    let mut sorted: Vec<f64> = ratio.iter().copied().filter(|r| r.is_finite()).collect();
    sorted.sort_by(|a, b| a.total_cmp(b));
    sorted
        .get(((OWN_UNTOUCHED * sorted.len() as f64).ceil() as usize).saturating_sub(1))
        .copied()
        .unwrap_or(1.0)
        .max(1.0)
}

/// The least of [`POWERS`] at which `coverage(power)` (the share of the drawn whiskers' errors
/// that the intervals widened by that power hold; `None` when there are too few to tell) reaches
/// 90%, the greatest when none does, and the least when none can tell.
pub(super) fn widen_power(coverage: impl Fn(f64) -> Option<f64>) -> f64 {
    let mut told = false;
    for p in POWERS {
        match coverage(p) {
            Some(c) if c >= COVERAGE => return p,
            Some(_) => told = true,
            None => {}
        }
    }
    if told {
        POWERS[POWERS.len() - 1]
    } else {
        POWERS[0]
    }
}

/// The median of the finite values of `v` (NaN when there is none).
pub(super) fn median(v: &[f64]) -> f64 {
    let mut f: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if f.is_empty() {
        return f64::NAN;
    }
    f.sort_by(|a, b| a.total_cmp(b));
    let n = f.len();
    if n % 2 == 1 {
        f[n / 2]
    } else {
        0.5 * (f[n / 2 - 1] + f[n / 2])
    }
}

/// How many times farther a recording whose nearest run lies at squared distance `near` is
/// than the held-out runs' median `reference`: at least 1 (a recording nearer than usual is
/// not read more sharply), and 1 when either is not a positive finite number.
pub(super) fn misfit_ratio(near: f64, reference: f64) -> f64 {
    let r = near / reference;
    if r.is_finite() && r > 1.0 {
        r
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nothing_is_spread_at_a_ratio_of_one_and_the_posterior_still_sums_to_one() {
        let t = |threshold: f64, power: f64| Trust {
            threshold,
            step: 0.0,
            power,
        };
        assert_eq!(even_share(1.0, t(1.0, 2.0)), 0.0);
        assert_eq!(even_share(0.5, t(1.0, 2.0)), 0.0);
        assert_eq!(even_share(9.0, t(1.0, 0.0)), 0.0);
        assert_eq!(even_share(3.0, t(4.0, 2.0)), 0.0);
        assert!((even_share(4.0, t(1.0, 0.5)) - 0.5).abs() < 1e-12);
        assert!((even_share(8.0, t(2.0, 0.5)) - 0.5).abs() < 1e-12);
        let p = trusted(&[0.7, 0.2, 0.1, 0.0], 4.0, t(1.0, 0.5));
        assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert!((p[3] - 0.125).abs() < 1e-12 && (p[0] - 0.35 - 0.125).abs() < 1e-12);
        assert_eq!(trusted(&[0.7, 0.3], 1.0, t(1.0, 3.0)), vec![0.7, 0.3]);
        // A step: half spread just above the threshold, more beyond.
        let stepped = Trust {
            threshold: 2.0,
            step: 0.5,
            power: 1.0,
        };
        assert_eq!(even_share(2.0, stepped), 0.0);
        assert!((even_share(2.0 + 1e-12, stepped) - 0.5).abs() < 1e-9);
        assert!((even_share(8.0, stepped) - 0.875).abs() < 1e-12);
    }

    #[test]
    fn trust_falls_with_the_misfit_only_as_far_as_the_drawn_whiskers_readings_are_wrong() {
        // Own runs: right and sure, near a ratio of 1.
        let own_p: Vec<Vec<f64>> = (0..40).map(|_| vec![0.94, 0.02, 0.02, 0.02]).collect();
        let own_t = vec![0; 40];
        let own_r: Vec<f64> = (0..40).map(|i| 1.0 + 0.02 * i as f64).collect();
        let own = Readings {
            probs: &own_p,
            truth: &own_t,
            ratio: &own_r,
        };
        // Drawn whiskers' runs far off (ratio 8), as sure, right in only a quarter of them.
        let far_r = vec![8.0; 40];
        let far_t: Vec<usize> = (0..40).map(|i| usize::from(i % 4 != 0)).collect();
        let far = Readings {
            probs: &own_p,
            truth: &far_t,
            ratio: &far_r,
        };
        let k = fit_trust(&own, &far);
        assert!(k.power > 0.0 || k.step > 0.5, "{k:?}");
        // Most of such a posterior is spread evenly, its log loss far below the fully trusted
        // reading's; the own runs (ratios up to 1.8) keep theirs, 90% of them untouched.
        assert!(k.threshold >= 1.7 - 1e-12, "{k:?}");
        assert!(even_share(8.0, k) > 0.6, "{k:?}");
        assert!(far.log_loss(k) < far.log_loss(Trust::default()) - 1.0);
        assert!(own.log_loss(k) < own.log_loss(Trust::default()) + 0.01);
        // Drawn whiskers' runs as right as the own ones: no reason to spread anything.
        let same = Readings {
            probs: &own_p,
            truth: &own_t,
            ratio: &far_r,
        };
        assert_eq!(fit_trust(&own, &same), Trust::default());
        // Without drawn runs, nothing is fitted.
        let none = Readings {
            probs: &[],
            truth: &[],
            ratio: &[],
        };
        assert_eq!(fit_trust(&own, &none), Trust::default());
    }

    #[test]
    fn the_own_bound_and_the_least_power_that_covers() {
        let r: Vec<f64> = (1..=10).map(f64::from).collect();
        assert_eq!(own_bound(&r), 9.0);
        assert_eq!(own_bound(&[]), 1.0);
        assert_eq!(own_bound(&[0.5]), 1.0);
        assert_eq!(
            widen_power(|p| Some(if p >= 1.0 { 0.92 } else { 0.6 })),
            1.0
        );
        assert_eq!(widen_power(|_| Some(0.5)), 2.0);
        assert_eq!(widen_power(|_| None), 0.5);
        assert_eq!(widen_power(|_| Some(0.95)), 0.5);
    }
}
