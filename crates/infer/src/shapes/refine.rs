//! A class's run nearest a recording, searched with the simulator.
//!
//! The bank and its fit between runs (`between`) only guess how close a class can come to a
//! recording: the bank is sparse, and the tangent plane through a few of its runs is straight
//! where the runs' surface is not. Here the class's own noise-free simulation is asked instead,
//! by a Levenberg–Marquardt search over the pose: from the best run known so far, one simulation
//! per pose unknown, a small step along it, gives the Jacobian of the principal components with
//! respect to the pose; a damped Gauss–Newton step from it proposes the next pose, which is kept
//! when its simulation lies nearer the recording. Every run simulated on the way is a real run of
//! the class, so the nearest of them is an honest member of the class's evidence (unlike the
//! plane's point, which no simulation has checked).
//!
//! The pose is searched in units of each unknown's range and kept within the ranges.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

/// The finite-difference step of the Jacobian, as a share of each unknown's range.
const STEP: f64 = 0.02;
/// Damping tried first, relative to the Gauss–Newton matrix's diagonal.
const LAMBDA_START: f64 = 1e-3;
/// Damped steps tried per round before the round gives up.
const TRIES: usize = 3;

/// A simulated run near another: the signed step taken, its pose (in units of the ranges) and
/// its components.
type Probe = (f64, Vec<f64>, Vec<f64>);

/// The nearest run found.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Refined {
    /// Its squared distance to the recording (in the components' units).
    pub d2: f64,
    /// Its pose.
    pub pose: Vec<f64>,
    /// Runs it simulated (those that could be).
    pub runs: usize,
}

/// Squared distance between two component vectors.
fn dist2(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// The class's run nearest the recording `z` (components) found in `rounds` rounds of the
/// search, starting from the known run at pose `start` with components `start_z`, after first
/// trying the pose `proposal` (the fit between runs', say) if given. `ranges` are the pose
/// unknowns' ranges, `simulate` the components of the class's noise-free run at a pose (`None`
/// where it cannot be simulated).
pub(super) fn refine(
    z: &[f64],
    ranges: &[[f64; 2]],
    start: (&[f64], &[f64]),
    proposal: Option<&[f64]>,
    rounds: usize,
    simulate: &(dyn Fn(&[f64]) -> Option<Vec<f64>> + Sync),
) -> Refined {
    let p = ranges.len();
    let span: Vec<f64> = ranges.iter().map(|[lo, hi]| hi - lo).collect();
    // A pose in units of the ranges (not clamped: a known run may lie beyond them).
    let to_unit = |x: &[f64]| -> Vec<f64> {
        x.iter()
            .zip(ranges)
            .zip(&span)
            .map(|((x, [lo, _]), w)| if *w > 0.0 { (x - lo) / w } else { 0.0 })
            .collect()
    };
    let to_pose = |u: &[f64]| -> Vec<f64> {
        u.iter()
            .zip(ranges)
            .zip(&span)
            .map(|((u, [lo, _]), w)| lo + u * w)
            .collect()
    };
    // The best run so far: its pose in units, components and squared distance.
    let mut best = (to_unit(start.0), start.1.to_vec(), dist2(z, start.1));
    let mut runs = 0;
    if let Some(q) = proposal {
        let u: Vec<f64> = to_unit(q).iter().map(|u| u.clamp(0.0, 1.0)).collect();
        if let Some(c) = simulate(&to_pose(&u)) {
            runs += 1;
            let d = dist2(z, &c);
            if d < best.2 {
                best = (u, c, d);
            }
        }
    }
    let live: Vec<usize> = (0..p).filter(|&j| span[j] > 0.0).collect();
    let mut lambda = LAMBDA_START;
    for _ in 0..rounds {
        if live.is_empty() {
            break;
        }
        // Jacobian by forward (or, at the top of a range, backward) differences.
        let columns: Vec<Option<Probe>> = live
            .par_iter()
            .map(|&j| {
                let mut u = best.0.clone();
                let h = if u[j] + STEP <= 1.0 { STEP } else { -STEP };
                u[j] += h;
                simulate(&to_pose(&u)).map(|c| (h, u, c))
            })
            .collect();
        runs += columns.iter().flatten().count();
        if columns.iter().any(Option::is_none) {
            break;
        }
        let columns: Vec<Probe> = columns.into_iter().flatten().collect();
        let dim = z.len();
        let jac = DMatrix::from_fn(dim, live.len(), |r, k| {
            let (h, _, c) = &columns[k];
            (c[r] - best.1[r]) / h
        });
        let resid = DVector::from_fn(dim, |r, _| z[r] - best.1[r]);
        // A run of the differences may itself be the nearest.
        let nearest_column = columns
            .iter()
            .map(|(_, u, c)| (dist2(z, c), u, c))
            .min_by(|a, b| a.0.total_cmp(&b.0));
        let a = jac.transpose() * &jac;
        let g = jac.transpose() * resid;
        let scale = (0..live.len())
            .map(|k| a[(k, k)])
            .fold(0.0f64, f64::max)
            .max(1e-300);
        let mut moved = false;
        for _ in 0..TRIES {
            let mut m = a.clone();
            for k in 0..live.len() {
                m[(k, k)] += lambda * a[(k, k)] + 1e-12 * scale;
            }
            let Some(step) = m.lu().solve(&g) else {
                lambda *= 10.0;
                continue;
            };
            let mut u = best.0.clone();
            for (k, &j) in live.iter().enumerate() {
                u[j] = (u[j] + step[k]).clamp(0.0, 1.0);
            }
            if u == best.0 {
                break;
            }
            let tried = simulate(&to_pose(&u));
            runs += usize::from(tried.is_some());
            match tried {
                Some(c) if dist2(z, &c) < best.2 => {
                    let d = dist2(z, &c);
                    best = (u, c, d);
                    lambda = (lambda * 0.1).max(1e-9);
                    moved = true;
                    break;
                }
                _ => lambda *= 10.0,
            }
        }
        if let Some((d, u, c)) = nearest_column {
            if d < best.2 {
                best = (u.clone(), c.clone(), d);
                moved = true;
            }
        }
        if !moved {
            break;
        }
    }
    Refined {
        d2: best.2,
        pose: to_pose(&best.0),
        runs,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth, curved map from a two-unknown pose to six components.
    fn curve(p: &[f64]) -> Vec<f64> {
        let (x, y) = (p[0], p[1]);
        vec![
            x,
            2.0 * y,
            (3.0 * x).sin(),
            (x * y).cos(),
            x * x - y,
            (2.0 * y).exp() * 0.1,
        ]
    }

    #[test]
    fn the_search_finds_the_pose_of_a_run_it_did_not_start_from() {
        let ranges = [[0.0, 2.0], [-1.0, 1.0]];
        let truth = [1.3, 0.4];
        let z = curve(&truth);
        let start = [0.9, 0.1];
        let sim = |p: &[f64]| Some(curve(p));
        let found = refine(&z, &ranges, (&start, &curve(&start)), None, 6, &sim);
        assert!(found.d2 < 1e-6 * dist2(&z, &curve(&start)), "{found:?}");
        for (a, b) in found.pose.iter().zip(truth) {
            assert!((a - b).abs() < 1e-3, "{:?} vs {truth:?}", found.pose);
        }
        // Two unknowns: at most a proposal, two differences and three tries per round.
        assert!(found.runs <= 6 * (2 + TRIES), "{}", found.runs);
    }

    #[test]
    fn the_search_stays_in_the_ranges_and_never_ends_farther_than_it_began() {
        let ranges = [[0.0, 1.0], [-1.0, 1.0]];
        // The best pose lies beyond the first range's top.
        let z = curve(&[1.5, 0.2]);
        let start = [0.5, 0.0];
        let start_d2 = dist2(&z, &curve(&start));
        let sim = |p: &[f64]| Some(curve(p));
        let found = refine(
            &z,
            &ranges,
            (&start, &curve(&start)),
            Some(&[3.0, 0.0]),
            4,
            &sim,
        );
        assert!(found.d2 < start_d2);
        assert!((0.0..=1.0).contains(&found.pose[0]) && (-1.0..=1.0).contains(&found.pose[1]));
        // A simulator that fails everywhere leaves the start.
        let none = |_: &[f64]| None;
        let kept = refine(
            &z,
            &ranges,
            (&start, &curve(&start)),
            Some(&[0.7, 0.0]),
            3,
            &none,
        );
        assert_eq!(kept.d2, start_d2);
        assert_eq!(kept.pose, start.to_vec());
        assert_eq!(kept.runs, 0);
    }
}
