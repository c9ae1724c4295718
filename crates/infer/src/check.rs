//! Model checking: whether a recording is plausible under its scenario at an estimate.
//!
//! The scenario is simulated at the estimate (every unknown at its posterior mean, no noise) at
//! the recording's timing, and each channel's residual (recorded − simulated) is compared with
//! the sensor noise the estimate used. If the scenario explains the recording, what is left is
//! the sensor noise: its spread is about one noise level and it is uncorrelated from sample to
//! sample. A model that does not fit leaves a residual that is larger than the noise and smooth
//! (a lag-1 autocorrelation near 1). The spread is measured robustly (1.4826 times the median
//! absolute residual), so that a few samples at a contact event that the simulation places a
//! time step early or late (spikes in the base forces) do not count as a misfit, while a motion
//! that is off over much of the recording does.
//!
//! Two allowances keep the check from crying wolf on recordings that the scenario does explain:
//! the noise level it compares with is at least [`FLOOR`] of the channel's range over the
//! recording or the simulation, whichever is larger (nearly clean recordings would otherwise fail on the estimate's own error and on the
//! simulator's resolution), and a channel fails only when its residual's spread exceeds
//! [`LIMIT`] times that level.

use crate::error::{Error, Result};
use crate::experiment::{Noise, CHANNELS};
use crate::family::Family;
use serde::Serialize;

/// Robust spread of the residual, in units of the noise level, above which a channel is not
/// explained.
pub const LIMIT: f64 = 2.0;

/// Least noise level a residual is compared with, as a fraction of the channel's range.
pub const FLOOR: f64 = 0.005;

/// The check of one channel.
#[derive(Debug, Clone, Serialize)]
pub struct ChannelCheck {
    /// The channel's name (`theta01`, …).
    pub channel: &'static str,
    /// RMS of the residual, SI.
    pub rms: f64,
    /// Robust spread of the residual (1.4826 × its median absolute value), SI.
    pub spread: f64,
    /// The noise level it is compared with (the estimate's, at least [`FLOOR`] of the range), SI.
    pub noise: f64,
    /// `spread / noise`: about 1 when the scenario explains the channel.
    pub ratio: f64,
    /// Lag-1 autocorrelation of the residual: about 0 for sensor noise, near 1 for a misfit.
    pub lag1: f64,
    /// Whether the residual is within [`LIMIT`] noise levels.
    pub explained: bool,
}

/// The check of one recording.
#[derive(Debug, Clone, Serialize)]
pub struct Check {
    /// One entry per checked channel.
    pub channels: Vec<ChannelCheck>,
    /// Whether every channel is explained.
    pub explained: bool,
    /// The simulation at the estimate, channel-major over [`CHANNELS`] (for figures), started
    /// at the lead-in that fits best when one is allowed.
    #[serde(skip)]
    pub simulated: Vec<Vec<f64>>,
    /// The lead-in before the approach at which the simulation fits the recording best, s, when
    /// one is allowed (see [`check`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lead_in: Option<f64>,
}

impl Check {
    /// The channel that is worst explained (largest ratio), if any channel was checked.
    pub fn worst(&self) -> Option<&ChannelCheck> {
        self.channels
            .iter()
            .max_by(|a, b| a.ratio.total_cmp(&b.ratio))
    }
}

/// Checks `recording` (channel-major over [`CHANNELS`], at `family`'s timing: see
/// [`Family::with_timing`]) against `family` simulated at `estimate` (one value per unknown),
/// on `channels`, with the sensor noise `noise` (SI, per channel of [`CHANNELS`]). With `lead`
/// above 0 the recording may start up to `lead` samples before the approach: the simulation is
/// started at the whole number of samples in [0, lead] that fits the recording best (at rest
/// before it).
pub fn check(
    family: &Family,
    recording: &[Vec<f64>],
    estimate: &[f64],
    noise: &[f64; 5],
    channels: &[usize],
    lead: usize,
) -> Result<Check> {
    if let Some(bad) = estimate.iter().find(|x| !x.is_finite()) {
        return Err(Error::Observation(format!(
            "cannot check a recording at a non-finite estimate ({bad})"
        )));
    }
    let simulated = family.simulate(estimate, &Noise::NONE, 0)?.series;
    let (simulated, lead_in) = if lead > 0 {
        let shift = best_shift(recording, &simulated, noise, channels, lead);
        (
            delayed(&simulated, shift),
            Some(shift as f64 / family.sample_rate()),
        )
    } else {
        (simulated, None)
    };
    let mut out = Vec::with_capacity(channels.len());
    for &c in channels {
        let (Some(y), Some(s)) = (recording.get(c), simulated.get(c)) else {
            continue;
        };
        let pairs: Vec<(f64, f64)> = y
            .iter()
            .zip(s)
            .filter(|(y, s)| y.is_finite() && s.is_finite())
            .map(|(&y, &s)| (y, s))
            .collect();
        if pairs.len() < 3 {
            continue;
        }
        let residual: Vec<f64> = pairs.iter().map(|(y, s)| y - s).collect();
        // The floor follows the larger of the recording's and the simulation's ranges, so that a
        // channel that is constant in the recording (a dead sensor) still gets a finite ratio.
        let range = |pick: fn(&(f64, f64)) -> f64| {
            let (lo, hi) = pairs
                .iter()
                .map(pick)
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
                    (lo.min(x), hi.max(x))
                });
            hi - lo
        };
        let level = noise[c].max(FLOOR * range(|p| p.0).max(range(|p| p.1)));
        let rms = (residual.iter().map(|e| e * e).sum::<f64>() / residual.len() as f64).sqrt();
        let mut abs: Vec<f64> = residual.iter().map(|e| e.abs()).collect();
        let mid = abs.len() / 2;
        let spread = 1.4826 * *abs.select_nth_unstable_by(mid, f64::total_cmp).1;
        let ratio = if level > 0.0 {
            spread / level
        } else if spread == 0.0 {
            0.0
        } else {
            f64::INFINITY
        };
        out.push(ChannelCheck {
            channel: CHANNELS[c],
            rms,
            spread,
            noise: level,
            ratio,
            lag1: lag1(&residual),
            explained: ratio <= LIMIT,
        });
    }
    if out.is_empty() {
        return Err(Error::Observation(
            "no channel to check: every checked channel is missing or has fewer than 3 numbers"
                .into(),
        ));
    }
    let explained = out.iter().all(|c| c.explained);
    Ok(Check {
        channels: out,
        explained,
        simulated,
        lead_in,
    })
}

/// Share of a batch's recordings that the scenario must fail to explain ([`unexplained`])
/// before the discriminative methods, unless told otherwise, estimate again on whiskers drawn
/// around it (`vibrissa estimate` on a scenario that is neither calibrated nor randomised). On
/// recordings of the scenario's own whisker with 0.5–3% noise, 0–20% were unexplained (`knn`'s
/// estimates, the coarsest); on stand-in whiskers of other chains and materials 70–100%, on
/// the other engine's set 65–80%.
pub const MISMATCH_SHARE: f64 = 0.4;

/// Runs of the scenario itself, at a batch's noise, that [`beyond_chance`] weighs a batch's
/// unexplained recordings against.
pub const NULL_RUNS: usize = 40;

/// Significance of [`beyond_chance`]: the chance that a batch of the scenario's own recordings
/// is called defiant by it.
pub const NULL_ALPHA: f64 = 0.01;

/// Whether `defied` unexplained recordings of `looked` are more than the scenario's own runs
/// leave unexplained (`null` of `runs`, simulated at the batch's noise and estimated alike), beyond
/// chance: Fisher's exact test, one-sided, at [`NULL_ALPHA`]. Under heavy noise the check
/// catches another whisker's recordings less often (a wrong whisker hides in the noise), so a
/// fixed share ([`MISMATCH_SHARE`]) may not be reached by a batch that still stands out clearly
/// from what the scenario's own recordings give.
pub fn beyond_chance(defied: usize, looked: usize, null: usize, runs: usize) -> bool {
    if looked == 0 || runs == 0 || defied * runs <= null * looked {
        return false;
    }
    // P(X ≥ defied) for X hypergeometric: `looked` drawn from `looked + runs`, of which
    // `defied + null` are unexplained.
    let ln_choose = |n: usize, k: usize| -> f64 {
        (0..k)
            .map(|i| ((n - i) as f64).ln() - ((i + 1) as f64).ln())
            .sum()
    };
    let (total, hits) = (looked + runs, defied + null);
    let denominator = ln_choose(total, looked);
    let tail: f64 = (defied..=hits.min(looked))
        .map(|x| (ln_choose(hits, x) + ln_choose(total - hits, looked - x) - denominator).exp())
        .sum();
    tail < NULL_ALPHA
}

/// What the check of a batch against its scenario found ([`defies`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Verdict {
    /// Recordings the scenario explains neither at their estimates nor near them.
    pub defied: usize,
    /// Recordings looked at.
    pub looked: usize,
    /// Of [`NULL_RUNS`] of the scenario's own runs, how many were unexplained alike, when that
    /// decided.
    pub own: Option<usize>,
    /// Whether the batch defies the scenario.
    pub defiant: bool,
}

impl Verdict {
    /// What decided, for a warning: "does not explain 9 of the 20 recordings" followed by `at`
    /// (where they were read, e.g. " at their estimates"), and what the scenario's own runs gave
    /// when they were asked.
    pub fn describe(&self, at: &str) -> String {
        let own = self
            .own
            .map(|k| {
                format!(
                    ", more than chance allows against {k} of {NULL_RUNS} of its own runs at \
                     their noise"
                )
            })
            .unwrap_or_default();
        format!(
            "does not explain {} of the {} recordings{at}{own}",
            self.defied, self.looked
        )
    }
}

/// Whether a batch of `looked` recordings, `defied` of which the scenario does not explain
/// ([`unexplained`]), defies it: more than [`MISMATCH_SHARE`] of them, or fewer but more than the
/// scenario's own runs at the batch's noise beyond chance ([`beyond_chance`]; `null` counts those
/// of [`NULL_RUNS`], and is called only when that decides). Own runs that cannot be simulated or
/// read decide nothing: the share alone decides then.
pub fn defies(defied: usize, looked: usize, null: impl FnOnce() -> Result<usize>) -> Verdict {
    let mut verdict = Verdict {
        defied,
        looked,
        own: None,
        defiant: false,
    };
    if looked == 0 || defied == 0 {
        return verdict;
    }
    if defied as f64 > MISMATCH_SHARE * looked as f64 {
        verdict.defiant = true;
    } else if let Ok(own) = null() {
        verdict.own = Some(own);
        verdict.defiant = beyond_chance(defied, looked, own, NULL_RUNS);
    }
    verdict
}

/// Most simulations spent looking for a point near an estimate at which the scenario explains a
/// recording ([`explained_near`]).
pub const NEAR_EVALUATIONS: usize = 60;

/// How many of `recordings` (each at its own timing: see [`Family::for_recording`]) the scenario
/// `family` explains neither at their `estimates` nor near them, within each estimate's 90%
/// interval ([`explained_near`]), with each one's sensor noise and allowed lead-in, on
/// `channels`. A recording that cannot be checked counts as explained.
pub fn unexplained(
    family: &Family,
    recordings: &[&crate::recording::Recording],
    estimates: &[Vec<crate::method::Estimate>],
    noise: &[[f64; 5]],
    channels: &[usize],
    leads: &[usize],
) -> usize {
    use rayon::prelude::*;
    recordings
        .par_iter()
        .zip(estimates)
        .zip(noise)
        .zip(leads)
        .filter(|(((rec, est), level), &lead)| {
            let point: Vec<f64> = est.iter().map(|e| e.mean).collect();
            let within: Vec<[f64; 2]> = est.iter().map(|e| e.ci90).collect();
            family.for_recording(rec).is_ok_and(|timed| {
                !explained_near(&timed, &rec.values, &point, &within, level, channels, lead)
            })
        })
        .count()
}

/// Whether `family` explains `recording` ([`check`]) at `point` or near it, within `within`
/// (per unknown, the estimate's 90% interval): a coarse estimator's point may be a millimetre
/// off, and a recording with little noise then defies the scenario there though not a little
/// way off. From `point`, a pattern search over the unknowns (steps of 5% of each one's range,
/// halved down to 0.5%, moving to the first neighbour whose worst channel is better explained,
/// at most [`NEAR_EVALUATIONS`] simulations) looks for a point where every channel is explained,
/// without leaving the interval: under heavy noise a point far from every estimate (a box that
/// only grazes the tip, whose small signal the noise hides) may explain a recording of another
/// whisker, which says nothing of whether the scenario's whisker reads it where the method
/// did. One that cannot be checked counts as explained.
pub fn explained_near(
    family: &Family,
    recording: &[Vec<f64>],
    point: &[f64],
    within: &[[f64; 2]],
    noise: &[f64; 5],
    channels: &[usize],
    lead: usize,
) -> bool {
    let worst = |p: &[f64]| {
        check(family, recording, p, noise, channels, lead)
            .ok()
            .map(|c| (c.explained, c.worst().map_or(0.0, |w| w.ratio)))
    };
    let Some((explained, mut best)) = worst(point) else {
        return true;
    };
    if explained {
        return true;
    }
    let ranges = family.ranges();
    // The box searched: each estimate's interval within its unknown's range (the point itself
    // where the interval is not a proper one).
    let bounds: Vec<[f64; 2]> = ranges
        .iter()
        .zip(point)
        .enumerate()
        .map(|(u, ([lo, hi], &x))| {
            let [a, b] = within.get(u).copied().unwrap_or([x, x]);
            if a <= b {
                [a.max(*lo).min(x), b.min(*hi).max(x)]
            } else {
                [x, x]
            }
        })
        .collect();
    let (mut p, mut step, mut evaluations) = (point.to_vec(), 0.05, 1);
    while step >= 0.005 && evaluations < NEAR_EVALUATIONS {
        let mut moved = false;
        'neighbours: for (u, ([lo, hi], [a, b])) in ranges.iter().zip(&bounds).enumerate() {
            for sign in [1.0, -1.0] {
                let mut q = p.clone();
                q[u] = (q[u] + sign * step * (hi - lo)).clamp(*a, *b);
                if q[u] == p[u] {
                    continue;
                }
                evaluations += 1;
                match worst(&q) {
                    Some((true, _)) => return true,
                    Some((false, r)) if r < best => {
                        (best, p, moved) = (r, q, true);
                        break 'neighbours;
                    }
                    _ => {}
                }
                if evaluations >= NEAR_EVALUATIONS {
                    break 'neighbours;
                }
            }
        }
        if !moved {
            step /= 2.0;
        }
    }
    false
}

/// `series` started `shift` samples later, at its first value before, as long as it was.
fn delayed(series: &[Vec<f64>], shift: usize) -> Vec<Vec<f64>> {
    series
        .iter()
        .map(|x| {
            (0..x.len())
                .map(|k| if k < shift { x[0] } else { x[k - shift] })
                .collect()
        })
        .collect()
}

/// The shift in [0, lead] samples of `simulated` that leaves the least squared residual against
/// `recording` on `channels`, each weighed by its noise (by its range where the noise is 0).
fn best_shift(
    recording: &[Vec<f64>],
    simulated: &[Vec<f64>],
    noise: &[f64; 5],
    channels: &[usize],
    lead: usize,
) -> usize {
    let weight: Vec<(usize, f64)> = channels
        .iter()
        .filter(|&&c| recording.get(c).is_some_and(|y| !y.is_empty()) && c < simulated.len())
        .map(|&c| {
            let range = simulated[c].iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let scale = if noise[c] > 0.0 {
                noise[c]
            } else {
                range.max(1e-300)
            };
            (c, 1.0 / (scale * scale))
        })
        .collect();
    let cost = |shift: usize| -> f64 {
        weight
            .iter()
            .map(|&(c, w)| {
                let (y, s) = (&recording[c], &simulated[c]);
                (0..y.len().min(s.len()))
                    .map(|k| {
                        let sim = if k < shift { s[0] } else { s[k - shift] };
                        let e = y[k] - sim;
                        if e.is_finite() {
                            w * e * e
                        } else {
                            0.0
                        }
                    })
                    .sum::<f64>()
            })
            .sum()
    };
    (0..=lead)
        .min_by(|&a, &b| cost(a).total_cmp(&cost(b)))
        .unwrap_or(0)
}

/// Lag-1 autocorrelation of `e` about its mean (0 for a constant series).
fn lag1(e: &[f64]) -> f64 {
    let n = e.len() as f64;
    let mean = e.iter().sum::<f64>() / n;
    let var: f64 = e.iter().map(|x| (x - mean).powi(2)).sum();
    if var <= 0.0 {
        return 0.0;
    }
    let cov: f64 = e.windows(2).map(|w| (w[0] - mean) * (w[1] - mean)).sum();
    cov / var
}

#[cfg(test)]
mod tests {
    use super::*;
    use vibrissa_core::rng::Rng;

    fn family() -> Family {
        Family::open("e2", &[]).expect("e2")
    }

    fn noisy(series: &[Vec<f64>], sigma: &[f64; 5], seed: u64) -> Vec<Vec<f64>> {
        let mut rng = Rng::stream(seed, 7);
        series
            .iter()
            .enumerate()
            .map(|(c, x)| x.iter().map(|v| v + sigma[c] * rng.normal()).collect())
            .collect()
    }

    fn ranges(series: &[Vec<f64>]) -> [f64; 5] {
        std::array::from_fn(|c| {
            let (lo, hi) = series[c]
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                    (l.min(*v), h.max(*v))
                });
            hi - lo
        })
    }

    #[test]
    fn a_recording_with_a_lead_in_is_explained_when_one_is_allowed() {
        let f = family();
        let truth = [0.021, 0.7];
        let clean = f.simulate(&truth, &Noise::NONE, 0).expect("sim").series;
        let r = ranges(&clean);
        let sigma: [f64; 5] = std::array::from_fn(|c| 0.03 * r[c]);
        // 20 samples of rest first, as long as the run.
        let late = noisy(&delayed(&clean, 20), &sigma, 4);
        let all: Vec<usize> = (0..5).collect();
        let c = check(&f, &late, &truth, &sigma, &all, 30).expect("check");
        assert!(c.explained, "{:?}", c.channels);
        assert!((c.lead_in.unwrap() - 0.020).abs() < 1e-9, "{:?}", c.lead_in);
        let c = check(&f, &late, &truth, &sigma, &all, 0).expect("check");
        assert!(!c.explained && c.lead_in.is_none());
    }

    #[test]
    fn a_recording_of_the_scenario_is_explained_at_its_truth() {
        let f = family();
        let truth = [0.021, 0.7];
        let clean = f.simulate(&truth, &Noise::NONE, 0).expect("sim").series;
        let r = ranges(&clean);
        let sigma: [f64; 5] = std::array::from_fn(|c| 0.03 * r[c]);
        let rec = noisy(&clean, &sigma, 3);
        let all: Vec<usize> = (0..5).collect();
        let c = check(&f, &rec, &truth, &sigma, &all, 0).expect("check");
        assert!(c.explained, "{:?}", c.channels);
        for ch in &c.channels {
            assert!((ch.ratio - 1.0).abs() < 0.2, "{ch:?}");
            assert!(ch.lag1.abs() < 0.3, "{ch:?}");
        }
    }

    #[test]
    fn a_wrong_scenario_is_not_explained() {
        // The recording's whisker is 30% stiffer than the scenario's.
        let f = family();
        let stiff = Family::open("e2", &["whisker.youngs_modulus=3.9e9".to_string()]).expect("e2");
        let truth = [0.021, 0.7];
        let clean = stiff.simulate(&truth, &Noise::NONE, 0).expect("sim").series;
        let r = ranges(&clean);
        let sigma: [f64; 5] = std::array::from_fn(|c| 0.03 * r[c]);
        let rec = noisy(&clean, &sigma, 4);
        let all: Vec<usize> = (0..5).collect();
        let c = check(&f, &rec, &truth, &sigma, &all, 0).expect("check");
        assert!(!c.explained, "{:?}", c.channels);
        let worst = c.worst().expect("channels");
        assert!(worst.ratio > LIMIT && worst.lag1 > 0.5, "{worst:?}");
    }

    #[test]
    fn the_search_near_an_estimate_stays_within_its_interval() {
        // A recording of the scenario's own whisker at 20 mm, read as 24 mm with an interval that
        // misses the truth: the scenario explains it, but only outside that interval, so not
        // where the method read it.
        let f = family();
        let clean = f
            .simulate(&[0.02, 0.8], &Noise::NONE, 0)
            .expect("sim")
            .series;
        let r = ranges(&clean);
        let sigma: [f64; 5] = std::array::from_fn(|c| 0.03 * r[c]);
        let rec = noisy(&clean, &sigma, 4);
        let all: Vec<usize> = (0..5).collect();
        let read = [0.024, 0.8];
        let narrow = [[0.0235, 0.0245], [0.75, 0.85]];
        assert!(!explained_near(&f, &rec, &read, &narrow, &sigma, &all, 0));
        let wide = [[0.019, 0.025], [0.7, 0.9]];
        assert!(explained_near(&f, &rec, &read, &wide, &sigma, &all, 0));
        assert!(explained_near(
            &f,
            &rec,
            &read,
            &f.ranges(),
            &sigma,
            &all,
            0
        ));
    }

    #[test]
    fn a_batch_stands_out_from_the_scenario_s_own_runs_beyond_chance() {
        // 9 of 20 unexplained against none of 40 own runs: p = C(40,20)⁻¹·… ≈ 1e-4.
        assert!(beyond_chance(9, 20, 0, 40));
        // As many as the own runs give, or fewer: no.
        assert!(!beyond_chance(8, 20, 16, 40));
        assert!(!beyond_chance(0, 20, 0, 40));
        // A few more than none: within chance.
        assert!(!beyond_chance(2, 20, 0, 40));
        // One recording cannot stand out at 1%: 1 of 1 against 0 of 40 is 1/41.
        assert!(!beyond_chance(1, 1, 0, 40));
        assert!(!beyond_chance(3, 20, 0, 0));
        // The tail against a direct sum: 5 of 20 against 1 of 40 (6 unexplained of 60).
        let c = |n: f64, k: f64| -> f64 {
            (0..k as usize)
                .map(|i| (n - i as f64) / (i as f64 + 1.0))
                .product()
        };
        let p: f64 = (5..=6)
            .map(|x| c(6.0, x as f64) * c(54.0, 20.0 - x as f64) / c(60.0, 20.0))
            .sum();
        assert_eq!(beyond_chance(5, 20, 1, 40), p < NULL_ALPHA, "p = {p}");
        assert!(p > 0.005 && p < 0.02, "p = {p}");
    }

    #[test]
    fn the_scenario_s_own_runs_are_simulated_only_when_they_decide() {
        let never = || -> Result<usize> { panic!("the own runs were not needed") };
        let decided = |v: Verdict| (v.defiant, v.own);
        assert_eq!(decided(defies(0, 20, never)), (false, None));
        assert_eq!(decided(defies(9, 20, never)), (true, None));
        assert_eq!(decided(defies(8, 20, || Ok(0))), (true, Some(0)));
        assert_eq!(decided(defies(8, 20, || Ok(16))), (false, Some(16)));
        // Own runs that fail decide nothing.
        assert_eq!(
            decided(defies(8, 20, || Err(Error::Observation("no".into())))),
            (false, None)
        );
        assert_eq!(
            defies(8, 20, || Ok(0)).describe(" at their estimates"),
            "does not explain 8 of the 20 recordings at their estimates, more than chance allows against 0 of 40 \
             of its own runs at their noise"
        );
        assert_eq!(
            defies(9, 20, never).describe(""),
            "does not explain 9 of the 20 recordings"
        );
    }

    #[test]
    fn nearly_clean_recordings_are_compared_with_the_floor() {
        let f = family();
        let truth = [0.021, 0.7];
        let clean = f.simulate(&truth, &Noise::NONE, 0).expect("sim").series;
        let c = check(&f, &clean, &[0.0211, 0.7], &[0.0; 5], &[0, 1], 0).expect("check");
        for ch in &c.channels {
            assert!(ch.noise > 0.0 && ch.ratio.is_finite(), "{ch:?}");
        }
    }

    #[test]
    fn a_non_finite_estimate_is_refused() {
        let f = family();
        let rec = vec![vec![0.0; 151]; 5];
        let e = check(&f, &rec, &[f64::NAN, 0.7], &[1e-3; 5], &[0], 0).unwrap_err();
        assert!(e.to_string().contains("non-finite"), "{e}");
    }
}
