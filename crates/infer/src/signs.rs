//! Channels recorded with the opposite sign to the contract's.
//!
//! The contract measures the joint angles counter-clockwise positive and `m0`, `fx`, `fy` as
//! what the base applies to the whisker. A rig that measures an angle clockwise, a sensor wired
//! the other way, or the wrench that the whisker applies to the base (the same numbers negated)
//! gives channels of the right size that a discriminative method reads as some other strike:
//! the other engine's 26.3-mm strike with its joint angles negated read 28.0 mm, with its
//! wrench negated 30.0 mm and 0.65 m/s instead of 1.26, with no word beyond the checks that
//! any foreign whisker fails.
//!
//! Each recording is read again with a channel (or the two angles, or the three wrench
//! channels) negated, and the scenario is simulated at each reading. How well a simulation
//! follows a recording in shape is the sum over the method's channels of their correlations
//! with it: a measure of sign and timing that a whisker other than the scenario's (which
//! changes the sizes) leaves nearly alone. Negated, a channel recorded the other way turns
//! from anticorrelated to correlated and the sum rises by up to twice its correlation; a
//! channel recorded in the contract's sign, negated, makes the sum fall, but for channels that
//! the noise hides, whose reading may move either way. A rise of more than [`FLIP_MARGIN`] is
//! warned of. On the other engine's strike read by `krr-invariant` the sums rose by 1.9
//! (`theta01` negated), 2.6 (the angles), 3.7 (`m0`) and 3.7 (the wrench); over 20-strike sets
//! of stand-in whiskers and the other engine's strikes at 0.5–10% noise and 333 Hz to 1 kHz,
//! read by `krr-invariant` and `knn`, no sound strike rose by more than 1.2. With the force
//! components alone tried as well, a negated `fx` rose by 1.49 while sound strikes rose by up to
//! 0.90 (`fy` at 10% noise): too close to tell apart, so they are not tried ([`hypotheses`]).

use crate::batch::Estimates;
use crate::check::{check, Check};
use crate::experiment::CHANNELS;
use crate::recording::Recording;
use crate::trained::Trained;
use crate::{Family, Result};

/// How much the sum of a recording's correlations with the scenario's simulation must rise with
/// some channels negated before they are taken for channels recorded with the opposite sign.
pub const FLIP_MARGIN: f64 = 1.2;

/// Recordings named in a warning before the rest are counted.
const NAMED: usize = 3;

/// The channel sets tried negated: each joint angle and the base moment alone, the two joint
/// angles together and the base wrench's channels together (those of them in `needs`, where
/// more than one). The force components alone are not tried: which way they point depends on
/// the whisker (on a stand-in whisker's near strikes, read on the scenario's own whisker, `fy`
/// ran against the scenario's in 4 of 20 strikes, and negated it fitted far better).
fn hypotheses(needs: &[usize]) -> Vec<Vec<usize>> {
    let mut out: Vec<Vec<usize>> = needs
        .iter()
        .filter(|&&c| c <= 2)
        .map(|&c| vec![c])
        .collect();
    for group in [&[0, 1][..], &[2, 3, 4]] {
        let g: Vec<usize> = group
            .iter()
            .copied()
            .filter(|c| needs.contains(c))
            .collect();
        if g.len() > 1 {
            out.push(g);
        }
    }
    out
}

/// How well the simulation of a check follows `values` in shape: the sum over `needs` of each
/// channel's correlation with the simulation (finite samples; 0 for a channel too short or
/// flat to correlate).
fn agreement(c: &Check, values: &[Vec<f64>], needs: &[usize]) -> f64 {
    needs
        .iter()
        .map(|&k| correlation(&values[k], &c.simulated[k]))
        .sum()
}

/// Pearson's correlation of the finite pairs of `a` and `b`; 0 where either has no spread.
fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let pairs: Vec<(f64, f64)> = a
        .iter()
        .zip(b)
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .map(|(&x, &y)| (x, y))
        .collect();
    if pairs.len() < 3 {
        return 0.0;
    }
    let n = pairs.len() as f64;
    let (ma, mb) = pairs
        .iter()
        .fold((0.0, 0.0), |(s, t), (x, y)| (s + x / n, t + y / n));
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in &pairs {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    if saa > 0.0 && sbb > 0.0 {
        sab / (saa * sbb).sqrt()
    } else {
        0.0
    }
}

/// One recording's channels that look negated: the set, and the agreement as recorded and
/// negated.
struct Flip {
    recording: usize,
    channels: Vec<usize>,
    as_recorded: f64,
    negated: f64,
}

/// A warning for every set of channels that, negated, the scenario's simulation follows
/// better by more than [`FLIP_MARGIN`] ([`agreement`]) in some of `recordings` (named by
/// `names`; with their noise `levels` and lead-ins `leads`), read by the discriminative method
/// `name` as trained by `trained` on `family`, whose readings of the recordings as recorded are
/// `estimates`.
#[allow(clippy::too_many_arguments)]
pub fn sign_warnings(
    family: &Family,
    names: &[String],
    recordings: &[Recording],
    levels: &[[f64; 5]],
    leads: &[usize],
    estimates: &Estimates,
    name: &str,
    seed: u64,
    trained: &mut Trained,
    log: &mut dyn FnMut(String),
) -> Result<Vec<String>> {
    let mut flips = Vec::new();
    for (r, rec) in recordings.iter().enumerate() {
        let (level, lead) = (&levels[r], leads[r]);
        let method = trained.get(family, rec, level, name, seed, lead, log)?;
        let needs = method.channels();
        let timed = family.nominal().for_recording(rec)?;
        let fit = |values: &[Vec<f64>], point: &[f64]| {
            check(&timed, values, point, level, &needs, lead)
                .ok()
                .map(|c| agreement(&c, values, &needs))
        };
        let point: Vec<f64> = estimates[r].0.iter().map(|e| e.mean).collect();
        let Some(as_recorded) = fit(&rec.values, &point) else {
            continue;
        };
        let mut best: Option<(Vec<usize>, f64)> = None;
        for set in hypotheses(&needs) {
            let mut values = rec.values.clone();
            for &c in &set {
                for x in &mut values[c] {
                    *x = -*x;
                }
            }
            let Ok(est) = method.predict(&values) else {
                continue;
            };
            let point: Vec<f64> = est.iter().map(|e| e.mean).collect();
            if let Some(m) = fit(&values, &point) {
                if best.as_ref().is_none_or(|(_, b)| m > *b) {
                    best = Some((set, m));
                }
            }
        }
        if let Some((channels, negated)) = best {
            if negated > as_recorded + FLIP_MARGIN {
                flips.push(Flip {
                    recording: r,
                    channels,
                    as_recorded,
                    negated,
                });
            }
        }
    }
    // One warning per set of channels, naming its recordings.
    let mut sets: Vec<&Vec<usize>> = Vec::new();
    for f in &flips {
        if !sets.contains(&&f.channels) {
            sets.push(&f.channels);
        }
    }
    Ok(sets
        .into_iter()
        .map(|set| {
            let these: Vec<&Flip> = flips.iter().filter(|f| &f.channels == set).collect();
            let mut files: Vec<String> = these
                .iter()
                .take(NAMED)
                .map(|f| {
                    format!(
                        "`{}` ({:.2} → {:.2})",
                        names[f.recording], f.as_recorded, f.negated
                    )
                })
                .collect();
            if these.len() > NAMED {
                files.push(format!("{} more", these.len() - NAMED));
            }
            let channels: Vec<&str> = set.iter().map(|&c| CHANNELS[c]).collect();
            format!(
                "{}: with {} negated, the scenario simulated at the method's reading follows the \
                 recording far better (the channels' correlations with it sum to more): {} \
                 recorded with the opposite sign? (angles are counter-clockwise positive; m0, fx \
                 and fy are what the base applies to the whisker, not what the whisker applies \
                 to the base)",
                files.join(", "),
                channels.join(" and "),
                if set.len() == 1 { "is it" } else { "are they" }
            )
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::batch::estimate_each;
    use crate::experiment::Noise;

    /// Sensor noise of the test's recordings (about 3% of each channel's range on `e2`).
    const LEVEL: [f64; 5] = [1e-3, 3e-3, 4e-7, 2e-5, 2e-5];

    /// Noisy `e2` runs at `points`, as recordings, with the channels of `negated` negated in the
    /// recording `which`.
    fn recordings(points: &[[f64; 2]], which: usize, negated: &[usize]) -> Vec<Recording> {
        let e2 = Family::builtin("e2").unwrap();
        let noise = Noise {
            sensor: LEVEL,
            process: 0.0,
        };
        points
            .iter()
            .enumerate()
            .map(|(k, p)| {
                let mut s = e2.simulate(p, &noise, 10 + k as u64).unwrap();
                if k == which {
                    for &c in negated {
                        s.series[c].iter_mut().for_each(|x| *x = -*x);
                    }
                }
                Recording::at_rate(s.series, e2.sample_rate())
            })
            .collect()
    }

    /// The sign warnings of `krr` on `recs`.
    fn warnings(recs: &[Recording]) -> Vec<String> {
        let e2 = Family::builtin("e2").unwrap();
        let names: Vec<String> = (0..recs.len()).map(|k| format!("r{k}.csv")).collect();
        let (levels, leads) = (vec![LEVEL; recs.len()], vec![0; recs.len()]);
        let mut trained = Trained::default();
        let mut log = |_: String| {};
        let est = estimate_each(
            &e2,
            &names,
            recs,
            &levels,
            &leads,
            "krr",
            1,
            &mut trained,
            &mut log,
        )
        .unwrap();
        sign_warnings(
            &e2,
            &names,
            recs,
            &levels,
            &leads,
            &est,
            "krr",
            1,
            &mut trained,
            &mut log,
        )
        .unwrap()
    }

    #[test]
    fn a_channel_recorded_the_other_way_is_named_and_the_contract_s_signs_are_not() {
        let points = [[0.018, 0.5], [0.024, 1.1], [0.027, 0.8]];
        assert_eq!(warnings(&recordings(&points, 0, &[])), Vec::<String>::new());
        let w = warnings(&recordings(&points, 1, &[0]));
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].starts_with("`r1.csv`") && w[0].contains("with theta01 negated"),
            "{w:?}"
        );
        // The wrench that the whisker applies to the base: the three channels at once.
        let w = warnings(&recordings(&points, 2, &[2, 3, 4]));
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].starts_with("`r2.csv`") && w[0].contains("with m0 and fx and fy negated"),
            "{w:?}"
        );
    }

    #[test]
    fn each_channel_alone_and_the_angles_and_the_wrench_together() {
        assert_eq!(
            hypotheses(&[0, 1, 2, 3, 4]),
            vec![vec![0], vec![1], vec![2], vec![0, 1], vec![2, 3, 4]]
        );
        assert_eq!(hypotheses(&[1]), vec![vec![1]]);
        assert_eq!(
            hypotheses(&[0, 1, 3, 4]),
            vec![vec![0], vec![1], vec![0, 1], vec![3, 4]]
        );
    }
}
