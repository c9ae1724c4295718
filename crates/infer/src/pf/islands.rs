//! The filter run as independent islands: the particles split among a few filters with their
//! own random streams, whose posteriors are merged with equal weights.
//!
//! The object's unknowns are static, so a single filter's cloud keeps only the values its
//! particles started with, moved a little after each resampling: when a strike's contact
//! weighs the particles sharply, most of the cloud descends from a handful of them, and where
//! it settles depends on the seed by as much as the posterior is wide. One filter's interval
//! cannot show that; the spread between islands does. On the calibrated files of sixteen
//! stand-in whiskers (20 noisy strikes each), one filter of 4000 particles read the distance to
//! 0.211 mm with its 90% intervals holding 90.0% (70–100% by whisker); three islands of 1333
//! read it to 0.202 mm, holding 92.2% (80–100%), for the same particle steps.

use super::config::Config;
use super::filter::run_one;
use super::gains::AngleGains;
use super::posterior::{Observations, Posterior, SensorPosterior, TraceRow};
use crate::error::{Error, Result};
use crate::mixture::mixture;
use crate::Estimate;

/// Islands the particles of [`super::Pf`] are split among by default.
pub const ISLANDS: usize = 3;

/// The islands of a filter whose user named none: [`ISLANDS`], but one where a batch is pooled
/// ([`super::pool`]). Pooling searches for the batch's whisker by each whisker's evidence over
/// the recordings; on two stand-ins (20 strikes each, `--randomise`) three islands moved the
/// pooled distance error from 0.54 and 0.22 mm to 0.78 and 0.47 mm, so a pooled batch keeps one
/// filter.
pub fn default_islands(pooled: bool) -> usize {
    if pooled {
        1
    } else {
        ISLANDS
    }
}

/// Fewest particles of an island: the count from which the likelihood's tempering
/// ([`super::temper_for`]) no longer depends on the particles, so that an island is a filter
/// whose tempering was chosen for it.
pub const MIN_ISLAND_PARTICLES: usize = 1000;

/// How many islands `config` runs: [`Config::islands`], but no more than leave every island
/// [`MIN_ISLAND_PARTICLES`] and one particle for each whisker it entertains.
pub fn island_count(config: &Config) -> usize {
    let least = MIN_ISLAND_PARTICLES.max(1 + config.alternatives.len());
    config.islands.min(config.particles / least).max(1)
}

/// The particles of island `k` of `n`: an equal share, the remainder to the first islands.
fn island_particles(total: usize, n: usize, k: usize) -> usize {
    total / n + usize::from(k < total % n)
}

/// The seed of island `k`: the configuration's own for the first, so that one island is the
/// single filter bit for bit.
fn island_seed(seed: u64, k: usize) -> u64 {
    if k == 0 {
        seed
    } else {
        seed ^ (k as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
    }
}

/// The settings of each island of `config`: its share of the particles, its own seed (the
/// first island keeps `config`'s), one island each.
pub fn island_configs(config: &Config) -> Vec<Config> {
    let n = island_count(config);
    (0..n)
        .map(|k| Config {
            particles: island_particles(config.particles, n, k),
            seed: island_seed(config.seed, k),
            islands: 1,
            ..config.clone()
        })
        .collect()
}

/// Runs the filter over `obs`, as [`island_count`] islands merged ([`merge`]), calling
/// `progress` with the fraction done (with several islands, which run side by side, only at the
/// start and the end).
pub fn run(
    config: &Config,
    obs: &Observations,
    progress: &mut dyn FnMut(f64),
) -> Result<Posterior> {
    use rayon::prelude::*;
    config.check()?;
    let islands = island_configs(config);
    if let [one] = &islands[..] {
        return run_one(one, obs, progress);
    }
    progress(0.0);
    let parts = islands
        .par_iter()
        .map(|island| run_one(island, obs, &mut |_| {}))
        .collect::<Result<Vec<_>>>()?;
    progress(1.0);
    merge(parts)
}

/// The equal-weight merge of posteriors of one recording filtered independently: per sample,
/// each unknown's summary is the mixture of the islands' ([`mixture`]) and the effective sample
/// size their sum; the counts are summed; the evidence is the islands' mean (each island's is
/// an estimate of the same marginal likelihood); the sensors' and the whisker's summaries are
/// mixed like the unknowns'; the joint angles' gains matched to one normal each.
pub fn merge(parts: Vec<Posterior>) -> Result<Posterior> {
    let mismatch = |what: &str| {
        Err(Error::Observation(format!(
            "merging the filter's islands: they differ in {what}"
        )))
    };
    let mut iter = parts.into_iter();
    let Some(first) = iter.next() else {
        return mismatch("number (none to merge)");
    };
    let rest: Vec<Posterior> = iter.collect();
    if rest.is_empty() {
        return Ok(first);
    }
    for p in &rest {
        if p.unknowns != first.unknowns {
            return mismatch("unknowns");
        }
        if p.trace.len() != first.trace.len() {
            return mismatch("samples");
        }
        if p.whisker_log_evidence.len() != first.whisker_log_evidence.len() {
            return mismatch("whiskers");
        }
    }
    let all: Vec<&Posterior> = std::iter::once(&first).chain(&rest).collect();
    let n = all.len() as f64;
    let mix = |pick: &dyn Fn(&Posterior) -> Option<Estimate>| -> Option<Estimate> {
        let parts: Option<Vec<Estimate>> = all.iter().map(|p| pick(p)).collect();
        mixture(&parts?)
    };
    let trace = (0..first.trace.len())
        .map(|k| {
            let row = &first.trace[k];
            TraceRow {
                t: row.t,
                ess: all.iter().map(|p| p.trace[k].ess).sum(),
                estimates: (0..row.estimates.len())
                    .map(|u| mix(&|p| p.trace[k].estimates.get(u).copied()).expect("parts"))
                    .collect(),
            }
        })
        .collect();
    let sensors = first.sensors.as_ref().and_then(|_| {
        let per = |gain: bool, c: usize| {
            mix(&|p| {
                p.sensors
                    .as_ref()
                    .map(|s| if gain { s.gain[c] } else { s.offset[c] })
            })
        };
        let gain: Option<Vec<Estimate>> = (0..5).map(|c| per(true, c)).collect();
        let offset: Option<Vec<Estimate>> = (0..5).map(|c| per(false, c)).collect();
        Some(SensorPosterior {
            gain: gain?.try_into().ok()?,
            offset: offset?.try_into().ok()?,
        })
    });
    let angle_gains = all
        .iter()
        .map(|p| p.angle_gains)
        .collect::<Option<Vec<AngleGains>>>()
        .map(|g| {
            let mean: [f64; 2] =
                std::array::from_fn(|j| g.iter().map(|a| a.mean[j]).sum::<f64>() / n);
            let var = std::array::from_fn(|j| {
                g.iter()
                    .map(|a| a.var[j] + (a.mean[j] - mean[j]).powi(2))
                    .sum::<f64>()
                    / n
            });
            AngleGains { mean, var }
        });
    let whisker = first
        .whisker
        .iter()
        .filter_map(|(key, _)| {
            let e = mix(&|p| p.whisker.iter().find(|(k, _)| k == key).map(|(_, e)| *e))?;
            Some((*key, e))
        })
        .collect();
    let whisker_log_evidence = (0..first.whisker_log_evidence.len())
        .map(|h| log_mean_exp(all.iter().map(|p| p.whisker_log_evidence[h])))
        .collect();
    Ok(Posterior {
        unknowns: first.unknowns.clone(),
        trace,
        skipped: first.skipped,
        resamples: all.iter().map(|p| p.resamples).sum(),
        diverged: all.iter().map(|p| p.diverged).sum(),
        refused_moves: all.iter().map(|p| p.refused_moves).sum(),
        steps: all.iter().map(|p| p.steps).sum(),
        ringing_share: all.iter().map(|p| p.ringing_share).sum::<f64>() / n,
        log_evidence: log_mean_exp(all.iter().map(|p| p.log_evidence)),
        rate_widening: first.rate_widening,
        sensors,
        angle_gains,
        whisker,
        whisker_log_evidence,
    })
}

/// `ln(mean(exp(x)))`, `-inf` when every term is.
fn log_mean_exp(x: impl Iterator<Item = f64> + Clone) -> f64 {
    let n = x.clone().count() as f64;
    let top = x.clone().fold(f64::NEG_INFINITY, f64::max);
    if top == f64::NEG_INFINITY || n == 0.0 {
        return f64::NEG_INFINITY;
    }
    top + (x.map(|v| (v - top).exp()).sum::<f64>() / n).ln()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_particles_are_shared_out_and_every_island_holds_each_whisker() {
        let parts: Vec<usize> = (0..3).map(|k| island_particles(4000, 3, k)).collect();
        assert_eq!(parts, [1334, 1333, 1333]);
        let mut c = Config::e2([1e-3; 5], 4000, 1);
        c.islands = 3;
        assert_eq!(island_count(&c), 3);
        c.particles = 2999;
        assert_eq!(island_count(&c), 2, "every island keeps 1000 particles");
        c.particles = 1999;
        assert_eq!(island_count(&c), 1);
        c.particles = 4000;
        c.alternatives = vec![c.whisker.clone(); 1499];
        assert_eq!(
            island_count(&c),
            2,
            "every island holds each of 1500 whiskers"
        );
        assert_eq!(island_seed(7, 0), 7);
        assert_ne!(island_seed(7, 1), island_seed(7, 2));
    }

    #[test]
    fn log_mean_exp_averages_evidence_and_keeps_a_lost_whisker_lost() {
        let v = log_mean_exp([0.0f64, 2f64.ln()].into_iter());
        assert!((v - 1.5f64.ln()).abs() < 1e-12);
        assert_eq!(
            log_mean_exp([f64::NEG_INFINITY; 2].into_iter()),
            f64::NEG_INFINITY
        );
        assert!((log_mean_exp([f64::NEG_INFINITY, 0.0].into_iter()) - 0.5f64.ln()).abs() < 1e-12);
    }
}
