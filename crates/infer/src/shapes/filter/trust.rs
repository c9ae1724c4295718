//! How far `shape-pf` trusts a recording that lies farther than its held-out runs, learnt from
//! noisy runs of whiskers drawn from the family's randomisation prior
//! ([`crate::shapes::off_nominal`]): the share of the class posterior spread evenly at a
//! given misfit, and the power of the misfit by which the pose's intervals widen.

use super::{last_log_z, posterior, Calibration, Reading};
use crate::experiment::Noise;
use crate::method::Z90;
use crate::shapes::family::{ShapeFamily, ShapeSample};

/// Seed of the drawn whiskers' runs.
const DRAWN_SEED: u64 = 0x0ff_a0e2;

/// A held-out run as the filters read it.
#[derive(Debug, Clone)]
pub(super) struct HeldReading {
    /// Its class and pose.
    pub class: usize,
    pub params: Vec<f64>,
    /// Each class's log marginal likelihood of the whole run (very low for a class that lost
    /// every particle).
    pub scores: Vec<f64>,
    /// Its misfit ratio.
    pub ratio: f64,
    /// Its own class's posterior mean and standard deviation of each unknown.
    pub mean: Vec<f64>,
    pub std: Vec<f64>,
}

impl HeldReading {
    /// The held-out run `s` as `reading` read it.
    pub(super) fn new(s: &ShapeSample, reading: &Reading) -> Self {
        let own = &reading.runs[s.class];
        HeldReading {
            class: s.class,
            params: s.params.clone(),
            scores: last_log_z(&reading.runs),
            ratio: reading.misfit(),
            mean: own.mean.clone(),
            std: own.std.clone(),
        }
    }
}

/// Per class, the factor by which its pose's standard deviations widen so that 90% of the
/// held-out runs' intervals, each also widened by its misfit ratio to the power `power`, hold
/// their truths (at least 1).
pub(super) fn widening(held: &[HeldReading], classes: usize, power: f64) -> Vec<f64> {
    (0..classes)
        .map(|c| {
            let mut z: Vec<f64> = held
                .iter()
                .filter(|h| h.class == c)
                .flat_map(|h| {
                    let scale = h.ratio.powf(power);
                    h.params
                        .iter()
                        .zip(h.mean.iter().zip(&h.std))
                        .filter(|(_, (m, sd))| m.is_finite() && **sd > 0.0)
                        .map(move |(t, (m, sd))| ((t - m) / (sd * scale)).abs())
                })
                .collect();
            z.sort_by(f64::total_cmp);
            match z.get(((0.9 * z.len() as f64).ceil() as usize).saturating_sub(1)) {
                Some(q) => (q / Z90).max(1.0),
                None => 1.0,
            }
        })
        .collect()
}

/// The class posteriors of held-out runs under `calibration` at their own misfits.
pub(super) fn held_posteriors(held: &[HeldReading], calibration: Calibration) -> Vec<Vec<f64>> {
    held.iter()
        .map(|h| posterior(&h.scores, calibration.at_misfit(h.ratio)))
        .collect()
}

/// Noisy runs of whiskers drawn from `family`'s randomisation prior, one at each held-out
/// run's pose: its noise-free run plus that held-out run's own noise (its recording minus the
/// family's noise-free run at the same pose, so sensor noise and the response to random forces
/// as the recordings show them). Empty when the family cannot be randomised or a run cannot
/// be simulated.
pub(super) fn drawn_runs(family: &ShapeFamily, held: &[&ShapeSample]) -> Vec<ShapeSample> {
    let Ok(drawn) = family.randomised_if(true) else {
        return Vec::new();
    };
    let draws: Vec<(usize, Vec<f64>)> = held.iter().map(|s| (s.class, s.params.clone())).collect();
    let simulate = |f: &ShapeFamily| {
        f.simulate_completed(&draws, &Noise::NONE, DRAWN_SEED, &|| {})
            .ok()
            .filter(|(runs, _)| runs.len() == draws.len())
            .map(|(runs, _)| runs)
    };
    let (Some(twins), Some(mut other)) = (simulate(family), simulate(&drawn)) else {
        return Vec::new();
    };
    for ((o, twin), s) in other.iter_mut().zip(&twins).zip(held) {
        for ((w, wt), ws) in o.whiskers.iter_mut().zip(&twin.whiskers).zip(&s.whiskers) {
            for ((c, ct), cs) in w.iter_mut().zip(wt).zip(ws) {
                for ((x, a), b) in c.iter_mut().zip(ct).zip(cs) {
                    *x += b - a;
                }
            }
        }
    }
    other
}
