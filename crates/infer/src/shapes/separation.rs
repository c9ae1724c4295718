//! How far apart the classes of a shape family lie: for a run of one class, the pose of every
//! other class whose noise-free run comes nearest it, and that distance in units of the sensor
//! noise.
//!
//! An estimator can only tell two classes apart by what their recordings differ by. If a box at
//! some pose draws, on the whiskers read, the series a triangle at another pose draws to within
//! a noise level, no estimator names that triangle right reliably. For two point hypotheses
//! whose series differ by a whitened distance `Δ` (each sample's difference over its channel's
//! noise σ, squared and summed over samples, channels and whiskers, its root taken) under white
//! Gaussian noise, the best test errs with probability `Φ(−Δ/2)`; and a classifier among many
//! errs on a run at least as often as it would against that run's nearest rival alone. So
//! `1 − mean over runs of max_k Φ(−Δ_k/2)` estimates, from above, the share of runs that any
//! classifier reading those whiskers names right under that noise — from above because the
//! search finds a local nearest pose (a nearer one may exist), white noise alone is assumed
//! (random forces make the recordings less informative) and the true class's pose is taken as
//! known (an estimator must find it too).
//!
//! The nearest pose is searched with the simulator ([`super::refine`]) from the runs of an
//! evenly spread set of noise-free runs of the class that lie nearest the run.

use super::family::{ShapeFamily, ShapeSample};
use super::forced::{dot, whitened, Forced};
use super::refine::{refine, Refined};
use crate::error::Result;
use crate::experiment::Noise;
use rayon::prelude::*;

/// Starts of the search per class: the class's noise-free runs nearest the run.
const STARTS: usize = 3;
/// Rounds of the search from each start.
const ROUNDS: usize = 8;

/// One run against every class.
#[derive(Debug, Clone)]
pub struct Separation {
    /// The run's class.
    pub class: usize,
    /// Per class: the whitened distance `Δ` from the run to the nearest noise-free run of that
    /// class found (0 for its own class, whose true pose is known).
    pub distance: Vec<f64>,
    /// Per class: the nearest run's pose (the run's own for its class).
    pub pose: Vec<Vec<f64>>,
    /// Per class: the distance to the nearest of the evenly spread runs, before the search.
    pub start_distance: Vec<f64>,
    /// Per class: the distance `Δ` to the same nearest run with the random forces' response
    /// counted as noise too (its covariance from runs of the true pose with random forces
    /// alone); equal to `distance` without random forces.
    pub distance_with_forces: Vec<f64>,
}

impl Separation {
    /// The class (not the run's own) nearest the run, and its distance.
    pub fn rival(&self) -> (usize, f64) {
        self.distance
            .iter()
            .enumerate()
            .filter(|(k, _)| *k != self.class)
            .map(|(k, d)| (k, *d))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or((self.class, f64::INFINITY))
    }

    /// `max_k Φ(−Δ_k/2)` over the other classes: how often at least the best test between the
    /// run and its nearest rival errs.
    pub fn least_error(&self) -> f64 {
        normal_tail(self.rival().1 / 2.0)
    }

    /// [`Separation::least_error`] with the random forces' response counted as noise.
    pub fn least_error_with_forces(&self) -> f64 {
        let d = self
            .distance_with_forces
            .iter()
            .enumerate()
            .filter(|(k, _)| *k != self.class)
            .map(|(_, d)| *d)
            .fold(f64::INFINITY, f64::min);
        normal_tail(d / 2.0)
    }
}

/// `Φ(−x)`, the standard normal's upper tail beyond `x`.
pub fn normal_tail(x: f64) -> f64 {
    0.5 * libm::erfc(x / std::f64::consts::SQRT_2)
}

/// Squared distance.
fn dist2(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// The noise-free run of class `k` at `pose`, whitened by `sigma`; `None` if it cannot be
/// simulated.
fn noise_free(family: &ShapeFamily, k: usize, pose: &[f64], sigma: &[f64; 5]) -> Option<Vec<f64>> {
    let (s, _) = family
        .simulate_completed(&[(k, pose.to_vec())], &Noise::NONE, 0, &|| {})
        .ok()?;
    s.first().map(|s| whitened(&s.whiskers, sigma))
}

/// Class `k`'s noise-free run nearest the whitened recording `z`, searched from the `STARTS`
/// runs of `pool` (class, pose, whitened series) of that class nearest it, `ROUNDS` rounds
/// each: the distance to the nearest start and the nearest found. `None` if the pool holds no
/// run of the class.
fn search_class(
    family: &ShapeFamily,
    z: &[f64],
    sigma: &[f64; 5],
    k: usize,
    pool: &[(usize, &[f64], &[f64])],
) -> Option<(f64, Refined)> {
    let ranges = family.classes()[k].family.ranges();
    let mut near: Vec<(f64, usize)> = pool
        .iter()
        .enumerate()
        .filter(|(_, (c, _, _))| *c == k)
        .map(|(i, (_, _, w))| (dist2(z, w), i))
        .collect();
    near.sort_by(|a, b| a.0.total_cmp(&b.0));
    let first = near.first()?.0.sqrt();
    let simulate = |p: &[f64]| noise_free(family, k, p, sigma);
    let best = near
        .iter()
        .take(STARTS)
        .map(|&(_, i)| {
            let (_, p, w) = pool[i];
            refine(z, &ranges, (p, w), None, ROUNDS, &simulate)
        })
        .min_by(|a, b| a.d2.total_cmp(&b.d2))?;
    Some((first, best))
}

/// Every run of `runs` (noise-free runs of `family`, with their true poses) against every class:
/// the nearest noise-free run of each other class, searched from the nearest `STARTS` of
/// `starts_per_class` evenly spread noise-free runs of that class (drawn with `seed`), the
/// distance whitened by the sensor noise `sigma` per channel; and that distance again with the
/// response to random forces of intensity `process` counted as noise, its covariance from
/// `responses` runs of the true pose with those forces alone. `tick` is called once per run.
#[allow(clippy::too_many_arguments)]
pub fn separations(
    family: &ShapeFamily,
    runs: &[ShapeSample],
    sigma: [f64; 5],
    process: f64,
    responses: usize,
    starts_per_class: usize,
    seed: u64,
    tick: &(dyn Fn() + Sync),
) -> Result<Vec<Separation>> {
    if let Some(c) = sigma.iter().position(|s| !(s.is_finite() && *s > 0.0)) {
        return Err(crate::error::Error::Setting(format!(
            "separation: the noise level of channel {c} is {}; expected a positive number",
            sigma[c]
        )));
    }
    let draws = family.even_draws(starts_per_class, seed);
    let (pool, _) = family.simulate_completed(&draws, &Noise::NONE, seed, &|| {})?;
    let series: Vec<Vec<f64>> = pool.iter().map(|s| whitened(&s.whiskers, &sigma)).collect();
    let pool: Vec<(usize, &[f64], &[f64])> = pool
        .iter()
        .zip(&series)
        .map(|(s, w)| (s.class, &s.params[..], &w[..]))
        .collect();
    let classes = family.classes().len();
    runs.par_iter()
        .map(|run| {
            let z = whitened(&run.whiskers, &sigma);
            let forced = Forced::simulate(
                family,
                run.class,
                &run.params,
                &sigma,
                process,
                responses,
                seed ^ 0xf0ce,
            );
            let mut distance_with_forces = vec![0.0; classes];
            let mut distance = vec![0.0; classes];
            let mut pose = vec![run.params.clone(); classes];
            let mut start_distance = vec![0.0; classes];
            for k in (0..classes).filter(|&k| k != run.class) {
                let Some((first, best)) = search_class(family, &z, &sigma, k, &pool) else {
                    distance[k] = f64::INFINITY;
                    start_distance[k] = f64::INFINITY;
                    distance_with_forces[k] = f64::INFINITY;
                    continue;
                };
                start_distance[k] = first;
                distance[k] = best.d2.sqrt();
                distance_with_forces[k] = match (noise_free(family, k, &best.pose, &sigma), &forced)
                {
                    (Some(c), Some(f)) => {
                        let delta: Vec<f64> = z.iter().zip(&c).map(|(a, b)| a - b).collect();
                        dot(&delta, &f.solve(&delta)).max(0.0).sqrt()
                    }
                    _ => distance[k],
                };
                pose[k] = best.pose;
            }
            tick();
            Ok(Separation {
                class: run.class,
                distance,
                pose,
                start_distance,
                distance_with_forces,
            })
        })
        .collect()
}

/// The squared whitened distance (a χ² when `sigma` is the recording's noise) from a recording
/// (`[whiskers][CHANNELS][samples]`) to the nearest noise-free run of `class` found by `rounds`
/// rounds of the search from `pose`, and that run's pose; `None` if the run at `pose` cannot be
/// simulated.
pub fn nearest_from(
    family: &ShapeFamily,
    recording: &[Vec<Vec<f64>>],
    sigma: [f64; 5],
    class: usize,
    pose: &[f64],
    rounds: usize,
) -> Option<(f64, Vec<f64>)> {
    let ranges = family.classes().get(class)?.family.ranges();
    let z = whitened(recording, &sigma);
    let simulate = |p: &[f64]| noise_free(family, class, p, &sigma);
    let start = simulate(pose)?;
    let found = refine(&z, &ranges, (pose, &start), None, rounds, &simulate);
    Some((found.d2, found.pose))
}

/// Every class's nearest noise-free run to a recording (`[whiskers][CHANNELS][samples]`),
/// searched as an estimator without the truth would: from the `STARTS` runs of `pool` (noise-free
/// runs of the family) of that class nearest the recording, `ROUNDS` rounds each, the distance
/// whitened by `sigma`. Per class: the squared distance and the pose (the nearest start's where
/// nothing more could be simulated; `∞` and no pose for a class the pool lacks).
pub fn search_every_class(
    family: &ShapeFamily,
    recording: &[Vec<Vec<f64>>],
    sigma: [f64; 5],
    pool: &[ShapeSample],
) -> Vec<(f64, Vec<f64>)> {
    let z = whitened(recording, &sigma);
    let series: Vec<Vec<f64>> = pool.iter().map(|s| whitened(&s.whiskers, &sigma)).collect();
    let pool: Vec<(usize, &[f64], &[f64])> = pool
        .iter()
        .zip(&series)
        .map(|(s, w)| (s.class, &s.params[..], &w[..]))
        .collect();
    (0..family.classes().len())
        .map(|k| {
            search_class(family, &z, &sigma, k, &pool)
                .map_or((f64::INFINITY, Vec::new()), |(_, f)| (f.d2, f.pose))
        })
        .collect()
}

/// The log likelihood of a recording (`[whiskers][CHANNELS][samples]`) under `class` at
/// `pose` with the random forces of intensity `process` as noise beside the sensor noise
/// `sigma`, their response read off `runs` runs of that pose with the forces alone (seeded by
/// `seed`); up to a constant shared by every class and pose ([`super::forced`]). `None` if no
/// run can be simulated.
#[allow(clippy::too_many_arguments)]
pub fn forced_log_likelihood(
    family: &ShapeFamily,
    recording: &[Vec<Vec<f64>>],
    sigma: [f64; 5],
    class: usize,
    pose: &[f64],
    process: f64,
    runs: usize,
    seed: u64,
) -> Option<f64> {
    let f = Forced::simulate(family, class, pose, &sigma, process, runs, seed)?;
    Some(f.log_likelihood(&whitened(recording, &sigma)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_least_error_is_the_normal_tail_at_half_the_nearest_rivals_distance() {
        let s = Separation {
            class: 1,
            distance: vec![3.0, 0.0, 1.0, 6.0],
            pose: vec![vec![]; 4],
            start_distance: vec![3.0, 0.0, 2.0, 6.0],
            distance_with_forces: vec![1.0, 0.0, 0.5, 6.0],
        };
        assert_eq!(s.rival(), (2, 1.0));
        // Φ(−0.5) = 0.30854
        assert!(
            (s.least_error() - 0.308_537_5).abs() < 1e-6,
            "{}",
            s.least_error()
        );
        assert!((normal_tail(0.0) - 0.5).abs() < 1e-15);
        assert!(normal_tail(10.0) < 1e-20);
        // Two identical series: a coin toss.
        let tie = Separation {
            class: 0,
            distance: vec![0.0, 0.0],
            pose: vec![vec![]; 2],
            start_distance: vec![0.0, 0.0],
            distance_with_forces: vec![0.0, 0.0],
        };
        assert_eq!(tie.least_error(), 0.5);
        assert!((s.least_error_with_forces() - normal_tail(0.25)).abs() < 1e-15);
    }
}
