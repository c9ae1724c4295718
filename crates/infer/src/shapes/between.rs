//! Between the bank's runs: how well a class explains a recording at poses the bank did not
//! simulate.
//!
//! The bank is far sparser than the likelihood is narrow, so a recording's nearest bank run of
//! its own class can sit many noise levels away while a run of another class happens to lie
//! closer. Near a recording, a class's runs trace a smooth surface in the space of principal
//! components, one dimension per pose unknown. Its `k` bank runs nearest the recording give that
//! surface's tangent plane by least squares (an affine map from pose to components); the plane's
//! point nearest the recording, its pose kept within the box those runs span, is a run the bank
//! might have held: its squared distance to the recording, and its pose.

use nalgebra::{DMatrix, DVector};

/// A class's best fit between its runs.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Between {
    /// Squared distance from the recording to the fitted plane's nearest point (in the
    /// components' units, those of the bank's squared distances).
    pub d2: f64,
    /// The pose at that point.
    pub pose: Vec<f64>,
}

/// Class `class`'s fit between its `k` bank runs nearest the recording `z` (components), given
/// the recording's squared distances `d2` to every bank run (infinite for runs to leave out),
/// each run's class, pose and components. `None` when the class has fewer than `k` runs within
/// reach, or `k` does not exceed its pose unknowns by two.
pub(super) fn between(
    z: &[f64],
    d2: &[f64],
    class_of: &[usize],
    params: &[Vec<f64>],
    comps: &[Vec<f64>],
    class: usize,
    k: usize,
) -> Option<Between> {
    let mut near: Vec<(f64, usize)> = d2
        .iter()
        .zip(class_of)
        .enumerate()
        .filter(|(_, (d, &c))| c == class && d.is_finite())
        .map(|(i, (d, _))| (*d, i))
        .collect();
    if near.len() < k {
        return None;
    }
    if near.len() > k {
        near.select_nth_unstable_by(k - 1, |a, b| a.0.total_cmp(&b.0));
        near.truncate(k);
    }
    let unknowns = params[near[0].1].len();
    if k < unknowns + 2 {
        return None;
    }
    let dim = z.len();
    // Centred poses, each unknown in units of its spread over the neighbours (an unknown they
    // all share drops out).
    let mean_p: Vec<f64> = (0..unknowns)
        .map(|u| near.iter().map(|&(_, i)| params[i][u]).sum::<f64>() / k as f64)
        .collect();
    let spread: Vec<f64> = (0..unknowns)
        .map(|u| {
            (near
                .iter()
                .map(|&(_, i)| (params[i][u] - mean_p[u]).powi(2))
                .sum::<f64>()
                / k as f64)
                .sqrt()
        })
        .collect();
    let live: Vec<usize> = (0..unknowns).filter(|&u| spread[u] > 0.0).collect();
    let m = live.len();
    let p = DMatrix::from_fn(k, m, |r, j| {
        let u = live[j];
        (params[near[r].1][u] - mean_p[u]) / spread[u]
    });
    let mean_z: Vec<f64> = (0..dim)
        .map(|c| near.iter().map(|&(_, i)| comps[i][c]).sum::<f64>() / k as f64)
        .collect();
    let zc = DMatrix::from_fn(k, dim, |r, c| comps[near[r].1][c] - mean_z[c]);
    // The tangent plane: components ≈ mean + p·J, J = (PᵀP)⁻¹PᵀZ (a whisker of ridge keeps
    // nearly collinear neighbours solvable).
    let mut ptp = p.transpose() * &p;
    for j in 0..m {
        ptp[(j, j)] += 1e-9 * k as f64;
    }
    let ptp_inv = ptp.try_inverse()?;
    let jac = &ptp_inv * (p.transpose() * &zc);
    // The plane's point nearest the recording: (J Jᵀ) x = J r.
    let r = DVector::from_fn(dim, |c, _| z[c] - mean_z[c]);
    let mut jjt = &jac * jac.transpose();
    let trace = (0..m)
        .map(|j| jjt[(j, j)])
        .sum::<f64>()
        .max(f64::MIN_POSITIVE);
    for j in 0..m {
        jjt[(j, j)] += 1e-12 * trace;
    }
    let mut x = jjt.try_inverse()? * (&jac * &r);
    // Within the box the neighbours span: the plane is a fit there and nowhere else.
    for j in 0..m {
        let col = p.column(j);
        let (lo, hi) = (col.min(), col.max());
        x[j] = x[j].clamp(lo, hi);
    }
    let fitted = jac.transpose() * &x;
    let d2 = (0..dim).map(|c| (r[c] - fitted[c]).powi(2)).sum::<f64>();
    let mut pose = mean_p;
    for (j, &u) in live.iter().enumerate() {
        pose[u] += x[j] * spread[u];
    }
    d2.is_finite().then_some(Between { d2, pose })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A made-up class whose components are a smooth function of a two-unknown pose.
    fn comps_of(p: &[f64]) -> Vec<f64> {
        let (a, b) = (p[0], p[1]);
        vec![a, b, 0.3 * a * a, a * b * 0.1, (0.5 * b).sin(), 1.0]
    }

    #[test]
    fn a_pose_between_the_runs_is_found_closer_than_any_run() {
        // A coarse grid of runs of class 0, and one far run of class 1.
        let mut params = Vec::new();
        for i in 0..6 {
            for j in 0..6 {
                params.push(vec![i as f64, j as f64]);
            }
        }
        params.push(vec![20.0, 20.0]);
        let class_of: Vec<usize> = (0..params.len())
            .map(|i| usize::from(i == params.len() - 1))
            .collect();
        let comps: Vec<Vec<f64>> = params.iter().map(|p| comps_of(p)).collect();
        let truth = [2.4, 3.6];
        let z = comps_of(&truth);
        let d2: Vec<f64> = comps
            .iter()
            .map(|c| c.iter().zip(&z).map(|(a, b)| (a - b).powi(2)).sum())
            .collect();
        let nearest = d2[..36].iter().cloned().fold(f64::INFINITY, f64::min);
        let b = between(&z, &d2, &class_of, &params, &comps, 0, 9).unwrap();
        assert!(b.d2 < 0.05 * nearest, "{} vs {nearest}", b.d2);
        assert!((b.pose[0] - truth[0]).abs() < 0.1 && (b.pose[1] - truth[1]).abs() < 0.1);
        // A recording beyond the runs: the pose stays within the neighbours' box.
        let far = comps_of(&[9.0, 2.0]);
        let d2: Vec<f64> = comps
            .iter()
            .map(|c| c.iter().zip(&far).map(|(a, b)| (a - b).powi(2)).sum())
            .collect();
        let b = between(&far, &d2, &class_of, &params, &comps, 0, 9).unwrap();
        assert!(b.pose[0] <= 5.0 + 1e-9, "{:?}", b.pose);
        // Too few runs of the class, or too few neighbours for its unknowns.
        assert!(between(&z, &d2, &class_of, &params, &comps, 1, 9).is_none());
        assert!(between(&z, &d2, &class_of, &params, &comps, 0, 3).is_none());
        // A run left out (infinite distance) is not a neighbour.
        let mut gone = d2.clone();
        gone[..30].iter_mut().for_each(|d| *d = f64::INFINITY);
        assert!(between(&far, &gone, &class_of, &params, &comps, 0, 9).is_none());
    }
}
