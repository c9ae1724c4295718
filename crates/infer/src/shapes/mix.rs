//! `shape-mix`: `shape-bank` and `shape-pf` read the same recording and their class posteriors
//! are pooled.
//!
//! The two estimators err differently: the bank compares the recording with noise-free runs of
//! every class (and searches the nearest with the simulator), the filter follows each class's
//! pose sample by sample through a coarser chain. Their class posteriors are pooled
//! log-linearly, `p ∝ p_bank^a · p_pf^b`, and a share `ε` of the even split is mixed in: the
//! exponents `a` and `b` (each of [`EXPONENTS`], at most 1: the pool never sharpens either) and
//! `ε` (of [`FLOORS`], at least ½%, so that one estimator's confident mistake cannot drive the
//! truth's probability to nothing) those under which training runs that neither estimator saw
//! are read with the least log loss. An exponent below 1 tempers an estimator whose
//! probabilities, beside the other's, say more than they know (both read the same data, so a
//! plain product counts it twice).
//!
//! The pose of the pooled posterior's most probable class is the even mixture of the two
//! estimators' poses of that class (its mean the mean of theirs; its variance the mean of
//! their variances plus the square of half their difference), so an interval widens where the
//! two disagree. The misfit reported is the larger of the two.

use super::bank::{CleanRuns, ShapeBank};
use super::estimator::{argmax, ShapeEstimate};
use super::family::{ShapeFamily, ShapeSample};
use super::filter::ShapePf;
use crate::error::{Error, Result};
use crate::Estimate;
use rayon::prelude::*;
use std::collections::HashSet;

/// Training runs per class set aside (not seen by either estimator) to fit the exponents.
const HELD_OUT: usize = 20;
/// Exponents tried for each estimator's class posterior.
pub(super) const EXPONENTS: [f64; 5] = [0.0, 0.25, 0.5, 0.75, 1.0];
/// Shares of the even split tried as the pooled posterior's floor.
pub(super) const FLOORS: [f64; 6] = [0.005, 0.01, 0.02, 0.05, 0.1, 0.2];
/// Least probability a pooled class posterior's log is taken of.
const TINY: f64 = 1e-300;

/// `shape-bank` and `shape-pf` on the same recordings, their class posteriors pooled.
pub struct ShapeMix {
    bank: ShapeBank,
    pf: ShapePf,
    /// The exponents of the bank's and the filter's class posterior, and the floor.
    pooling: Pooling,
    /// The held-out runs' mean log loss under the pooled posterior, and how many there were.
    held_out: (f64, usize),
}

impl ShapeMix {
    /// The estimator's name.
    pub const NAME: &'static str = "shape-mix";

    /// Fits `shape-bank` (on `training` and the noise-free `clean` runs) and `shape-pf` (on
    /// `training`, with `particles` per class), each without [`HELD_OUT`] runs per class, then
    /// the exponents on those.
    pub fn fit(
        family: &ShapeFamily,
        training: &[ShapeSample],
        clean: &CleanRuns,
        particles: usize,
    ) -> Result<Self> {
        let classes = family.classes().len();
        let held = held_out(family, training);
        if held.len() < classes {
            return Err(Error::Fit {
                method: Self::NAME.into(),
                detail: format!(
                    "needs training runs to set aside ({HELD_OUT} per class; {} found)",
                    held.len()
                ),
            });
        }
        let set_aside: HashSet<usize> = held.iter().copied().collect();
        let rest: Vec<ShapeSample> = training
            .iter()
            .enumerate()
            .filter(|(i, _)| !set_aside.contains(i))
            .map(|(_, s)| s.clone())
            .collect();
        // Neither may have seen a held-out run: the bank holds the noise-free twin of every
        // training run, so the held-out runs' twins leave it.
        let key = |s: &ShapeSample| (s.class, s.params.iter().map(|p| p.to_bits()).collect());
        let held_keys: HashSet<(usize, Vec<u64>)> =
            held.iter().map(|&i| key(&training[i])).collect();
        let clean_rest = CleanRuns {
            twins: clean
                .twins
                .iter()
                .filter(|s| !held_keys.contains(&key(s)))
                .cloned()
                .collect(),
            extra: clean.extra.clone(),
        };
        let (bank, pf) = rayon::join(
            || ShapeBank::fit(family, &rest, &clean_rest),
            || ShapePf::fit_with(family, &rest, particles),
        );
        let (bank, pf) = (bank?, pf?);
        let read: Vec<(Vec<f64>, Vec<f64>, usize)> = held
            .par_iter()
            .map(|&i| {
                let s = &training[i];
                let b = bank.predict(&s.whiskers)?;
                let p = pf.predict(&s.whiskers)?;
                Ok((probabilities(&b), probabilities(&p), s.class))
            })
            .collect::<Result<_>>()?;
        let (pooling, loss) = fit_pooling(&read);
        Ok(ShapeMix {
            bank,
            pf,
            pooling,
            held_out: (loss, read.len()),
        })
    }

    /// The pooled class posterior and its most probable class's pose from one recording
    /// (`[whiskers][CHANNELS][samples]`).
    pub fn predict(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<ShapeEstimate> {
        let (b, p) = rayon::join(
            || self.bank.predict_every_class(whiskers),
            || self.pf.predict_every_class(whiskers),
        );
        let ((b, b_poses), (p, p_poses)) = (b?, p?);
        let pooled = pool(&probabilities(&b), &probabilities(&p), self.pooling);
        let best = argmax(&pooled);
        let misfit = match (b.misfit, p.misfit) {
            (Some(x), Some(y)) => Some(x.max(y)),
            (x, y) => x.or(y),
        };
        Ok(ShapeEstimate {
            class: b
                .class
                .iter()
                .zip(pooled)
                .map(|((name, _), q)| (name.clone(), q))
                .collect(),
            best,
            pose: mixed_pose(&b_poses[best], &p_poses[best]),
            misfit,
        })
    }

    /// The pooled class posterior after every sample (`[samples][classes]`).
    pub fn trace(&self, whiskers: &[Vec<Vec<f64>>]) -> Result<Vec<Vec<f64>>> {
        let (b, p) = rayon::join(|| self.bank.trace(whiskers), || self.pf.trace(whiskers));
        let (b, p) = (b?, p?);
        Ok(b.iter()
            .zip(&p)
            .map(|(b, p)| pool(b, p, self.pooling))
            .collect())
    }

    /// The exponents, the floor, the held-out runs' log loss, and each estimator's settings
    /// (prefixed `bank_` and `pf_`).
    pub fn settings(&self) -> Vec<(String, f64)> {
        let mut s = vec![
            ("exponent_bank".to_string(), self.pooling.exponents[0]),
            ("exponent_pf".to_string(), self.pooling.exponents[1]),
            ("floor".to_string(), self.pooling.floor),
            ("held_out_log_loss".to_string(), self.held_out.0),
            ("held_out_runs".to_string(), self.held_out.1 as f64),
        ];
        s.extend(
            self.bank
                .settings()
                .into_iter()
                .map(|(k, v)| (format!("bank_{k}"), v)),
        );
        s.extend(
            self.pf
                .settings()
                .into_iter()
                .map(|(k, v)| (format!("pf_{k}"), v)),
        );
        s
    }
}

/// The indices of the runs of `training` set aside: per class, the last [`HELD_OUT`] whose
/// pose lies in the class's ranges (the training runs' margins hold poses no recording is
/// meant to show), or the last of any pose if too few do. At most a quarter of a class's runs
/// are taken, so both estimators keep most of them.
fn held_out(family: &ShapeFamily, training: &[ShapeSample]) -> Vec<usize> {
    let mut held = Vec::new();
    for (c, class) in family.classes().iter().enumerate() {
        let ranges = class.family.ranges();
        let runs: Vec<usize> = (0..training.len())
            .filter(|&i| training[i].class == c)
            .collect();
        let take = HELD_OUT.min(runs.len() / 4);
        let inside: Vec<usize> = runs
            .iter()
            .rev()
            .copied()
            .filter(|&i| {
                training[i]
                    .params
                    .iter()
                    .zip(&ranges)
                    .all(|(x, [lo, hi])| (lo..=hi).contains(&x))
            })
            .take(take)
            .collect();
        if inside.len() == take {
            held.extend(inside);
        } else {
            held.extend(runs.iter().rev().take(take));
        }
    }
    held.sort_unstable();
    held
}

/// An estimate's class probabilities, in the family's order.
fn probabilities(e: &ShapeEstimate) -> Vec<f64> {
    e.class.iter().map(|(_, p)| *p).collect()
}

/// How the two class posteriors are pooled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Pooling {
    /// The exponents `[a, b]` of the bank's and the filter's posterior.
    pub exponents: [f64; 2],
    /// The share `ε` of the even split mixed in.
    pub floor: f64,
}

/// The pooled posterior: `(1 − ε)·q + ε/K`, `q ∝ bank^a · pf^b`.
pub(super) fn pool(bank: &[f64], pf: &[f64], pooling: Pooling) -> Vec<f64> {
    let [a, b] = pooling.exponents;
    let log: Vec<f64> = bank
        .iter()
        .zip(pf)
        .map(|(x, y)| a * x.max(TINY).ln() + b * y.max(TINY).ln())
        .collect();
    let top = log.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let w: Vec<f64> = log.iter().map(|l| (l - top).exp()).collect();
    let total: f64 = w.iter().sum();
    let even = pooling.floor / w.len().max(1) as f64;
    w.iter()
        .map(|x| (1.0 - pooling.floor) * x / total + even)
        .collect()
}

/// The pooling (exponents of [`EXPONENTS`], floor of [`FLOORS`]) under which the runs `read`
/// (each the bank's and the filter's class posterior and the true class) have the least mean
/// log loss, and that loss. Ties go to the first found (the bank's exponent in the outer loop,
/// then the filter's, then the floor).
pub(super) fn fit_pooling(read: &[(Vec<f64>, Vec<f64>, usize)]) -> (Pooling, f64) {
    let mut best = (
        Pooling {
            exponents: [1.0, 1.0],
            floor: FLOORS[0],
        },
        f64::INFINITY,
    );
    for &a in &EXPONENTS {
        for &b in &EXPONENTS {
            for &floor in &FLOORS {
                let pooling = Pooling {
                    exponents: [a, b],
                    floor,
                };
                let loss = read
                    .iter()
                    .map(|(pb, pp, truth)| -pool(pb, pp, pooling)[*truth].ln())
                    .sum::<f64>()
                    / read.len().max(1) as f64;
                if loss < best.1 {
                    best = (pooling, loss);
                }
            }
        }
    }
    best
}

/// The even mixture of two poses of one class, unknown by unknown (an unknown only one of them
/// gives is kept as it is).
pub(super) fn mixed_pose(
    a: &[(String, Estimate)],
    b: &[(String, Estimate)],
) -> Vec<(String, Estimate)> {
    a.iter()
        .map(|(name, x)| {
            let mixed = match b.iter().find(|(n, _)| n == name) {
                Some((_, y)) => {
                    let mean = 0.5 * (x.mean + y.mean);
                    let half = 0.5 * (x.mean - y.mean);
                    let var = 0.5 * (x.std * x.std + y.std * y.std) + half * half;
                    Estimate::normal(mean, var.sqrt())
                }
                None => *x,
            };
            (name.clone(), mixed)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pooling(a: f64, b: f64, floor: f64) -> Pooling {
        Pooling {
            exponents: [a, b],
            floor,
        }
    }

    #[test]
    fn the_pool_is_the_normalised_weighted_product_with_a_floor() {
        let bank = [0.7, 0.2, 0.1];
        let pf = [0.2, 0.6, 0.2];
        let p = pool(&bank, &pf, pooling(1.0, 1.0, 0.0));
        let raw = [0.14, 0.12, 0.02];
        let total: f64 = raw.iter().sum();
        for (x, r) in p.iter().zip(raw) {
            assert!((x - r / total).abs() < 1e-12);
        }
        // An exponent of 0 leaves the other estimator alone.
        let only_pf = pool(&bank, &pf, pooling(0.0, 1.0, 0.0));
        for (x, y) in only_pf.iter().zip(pf) {
            assert!((x - y).abs() < 1e-12);
        }
        // The floor mixes in the even split.
        let floored = pool(&bank, &pf, pooling(1.0, 1.0, 0.3));
        for (x, r) in floored.iter().zip(raw) {
            assert!((x - (0.7 * r / total + 0.1)).abs() < 1e-12);
        }
        // A class one estimator rules out entirely keeps the floor's share.
        let p = pool(&[1.0, 0.0], &[0.5, 0.5], pooling(1.0, 1.0, 0.01));
        assert!((p[1] - 0.005).abs() < 1e-12 && (p.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn the_pooling_follows_the_estimator_that_is_right() {
        // The bank is always right and fairly sure; the filter is right half the time.
        let mut read = Vec::new();
        for k in 0..20 {
            let truth = k % 2;
            let mut bank = vec![0.2, 0.2];
            bank[truth] = 0.8;
            let pf = if k % 4 < 2 {
                bank.clone()
            } else {
                vec![bank[1], bank[0]]
            };
            read.push((bank, pf, truth));
        }
        let (p, loss) = fit_pooling(&read);
        assert_eq!(p.exponents, [1.0, 0.0], "the filter tells nothing here");
        assert_eq!(p.floor, FLOORS[0]);
        let plain = read.iter().map(|(p, _, t)| -p[*t].ln()).sum::<f64>() / read.len() as f64;
        assert!(loss <= plain + 5e-3 && loss > 0.0, "{loss} {plain}");
        // One run on which both are sure and wrong raises the floor.
        read.push((vec![1e-9, 1.0 - 1e-9], vec![1e-9, 1.0 - 1e-9], 0));
        let (q, _) = fit_pooling(&read);
        assert!(q.floor > FLOORS[0], "{q:?}");
    }

    #[test]
    fn mixed_poses_widen_where_they_disagree() {
        let a = vec![("x".to_string(), Estimate::normal(1.0, 0.1))];
        let b = vec![
            ("x".to_string(), Estimate::normal(1.0, 0.1)),
            ("v".to_string(), Estimate::normal(2.0, 0.1)),
        ];
        let m = mixed_pose(&a, &b);
        assert_eq!(m.len(), 1);
        assert!((m[0].1.mean - 1.0).abs() < 1e-12 && (m[0].1.std - 0.1).abs() < 1e-12);
        let c = vec![("x".to_string(), Estimate::normal(1.6, 0.1))];
        let m = mixed_pose(&a, &c);
        assert!((m[0].1.mean - 1.3).abs() < 1e-12);
        assert!((m[0].1.std - (0.01f64 + 0.09).sqrt()).abs() < 1e-12);
    }
}
