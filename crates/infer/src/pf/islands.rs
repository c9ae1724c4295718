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
//! read it to 0.205 mm, holding 91.9% (75–100%), for the same particle steps (docs/filter.md,
//! "Islands").

use super::config::Config;
use super::filter::{run_one, Filter, Particles};
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

/// The islands in which a pooled batch filters again a recording on which its favourite
/// whisker lost every particle ([`super::pool::refine`]), when the user named none:
/// [`ISLANDS`]. On stand-in 102 of docs/filter.md (20 strikes, 4000 particles) the favourite
/// lost them on three near-base strikes, whose speed the single filter read 2.4 standard
/// deviations high; as three islands, two of them held the truth.
pub fn lost_islands(pooled: bool) -> Option<usize> {
    pooled.then_some(ISLANDS)
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
    let Some(first) = parts.first() else {
        return mismatch("number (none to merge)");
    };
    if parts.len() == 1 {
        return Ok(parts.into_iter().next().expect("one part"));
    }
    for p in &parts[1..] {
        if p.trace.len() != first.trace.len() {
            return mismatch("samples");
        }
    }
    let mut merged = merge_counts(&parts)?;
    merged.trace = (0..first.trace.len())
        .map(|k| merge_rows(&parts.iter().map(|p| &p.trace[k]).collect::<Vec<_>>()))
        .collect::<Result<_>>()?;
    merged.sensors = merge_sensors(&parts.iter().map(|p| p.sensors.clone()).collect::<Vec<_>>());
    Ok(merged)
}

fn mismatch<T>(what: &str) -> Result<T> {
    Err(Error::Observation(format!(
        "merging the filter's islands: they differ in {what}"
    )))
}

/// One sample's rows of the islands merged: each unknown's mixture, the effective sample sizes
/// summed.
fn merge_rows(rows: &[&TraceRow]) -> Result<TraceRow> {
    let Some(&first) = rows.first() else {
        return mismatch("number");
    };
    if rows
        .iter()
        .any(|r| r.estimates.len() != first.estimates.len())
    {
        return mismatch("unknowns");
    }
    let estimates = (0..first.estimates.len())
        .map(|u| {
            let parts: Vec<Estimate> = rows.iter().map(|r| r.estimates[u]).collect();
            mixture(&parts).expect("at least one island")
        })
        .collect();
    Ok(TraceRow {
        t: first.t,
        ess: rows.iter().map(|r| r.ess).sum(),
        estimates,
    })
}

/// The islands' sensor posteriors mixed channel by channel; `None` where any has none.
fn merge_sensors(parts: &[Option<SensorPosterior>]) -> Option<SensorPosterior> {
    let parts: Vec<&SensorPosterior> = parts.iter().map(Option::as_ref).collect::<Option<_>>()?;
    let per = |pick: &dyn Fn(&SensorPosterior) -> Estimate| {
        mixture(&parts.iter().map(|s| pick(s)).collect::<Vec<_>>())
    };
    let gain: Option<Vec<Estimate>> = (0..5).map(|c| per(&|s| s.gain[c])).collect();
    let offset: Option<Vec<Estimate>> = (0..5).map(|c| per(&|s| s.offset[c])).collect();
    Some(SensorPosterior {
        gain: gain?.try_into().ok()?,
        offset: offset?.try_into().ok()?,
    })
}

/// Everything of the islands' posteriors but their trace and sensors, merged: the counts
/// summed, the evidence averaged, the whisker's summaries mixed, the joint angles' gains matched
/// to one normal each.
fn merge_counts(parts: &[Posterior]) -> Result<Posterior> {
    let Some(first) = parts.first() else {
        return mismatch("number");
    };
    for p in &parts[1..] {
        if p.unknowns != first.unknowns {
            return mismatch("unknowns");
        }
        if p.whisker_log_evidence.len() != first.whisker_log_evidence.len() {
            return mismatch("whiskers");
        }
    }
    let n = parts.len() as f64;
    let angle_gains = parts
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
            let each: Option<Vec<Estimate>> = parts
                .iter()
                .map(|p| p.whisker.iter().find(|(k, _)| k == key).map(|(_, e)| *e))
                .collect();
            Some((*key, mixture(&each?)?))
        })
        .collect();
    let whisker_log_evidence = (0..first.whisker_log_evidence.len())
        .map(|h| log_mean_exp(parts.iter().map(|p| p.whisker_log_evidence[h])))
        .collect();
    Ok(Posterior {
        unknowns: first.unknowns.clone(),
        trace: Vec::new(),
        skipped: first.skipped,
        resamples: parts.iter().map(|p| p.resamples).sum(),
        diverged: parts.iter().map(|p| p.diverged).sum(),
        refused_moves: parts.iter().map(|p| p.refused_moves).sum(),
        steps: parts.iter().map(|p| p.steps).sum(),
        ringing_share: parts.iter().map(|p| p.ringing_share).sum::<f64>() / n,
        log_evidence: log_mean_exp(parts.iter().map(|p| p.log_evidence)),
        rate_widening: first.rate_widening,
        sensors: None,
        angle_gains,
        whisker,
        whisker_log_evidence,
    })
}

/// The filter fed one sample at a time as [`island_count`] islands (online use): each sample
/// goes to every island, side by side, and the posterior row is their merge ([`merge`]). Fed a
/// whole recording it gives [`run`]'s posterior, bit for bit.
pub struct Islands {
    filters: Vec<Filter>,
    /// The merged rows so far, and the rest of the islands' posteriors merged after the last
    /// sample.
    merged: Posterior,
}

impl Islands {
    /// The islands of `config`, for samples `period` seconds apart.
    pub fn new(config: &Config, period: f64) -> Result<Islands> {
        config.check()?;
        let filters = island_configs(config)
            .iter()
            .map(|c| Filter::new(c, period))
            .collect::<Result<Vec<_>>>()?;
        let merged = filters[0].posterior().clone();
        Ok(Islands { filters, merged })
    }

    /// The number of islands.
    pub fn count(&self) -> usize {
        self.filters.len()
    }

    /// Takes the sample `y` at time `t` on every island ([`Filter::update`]) and returns the
    /// merged posterior row. A sample that one island refuses, all refuse, and none takes it.
    pub fn update(&mut self, t: f64, y: &[f64; 5]) -> Result<&TraceRow> {
        use rayon::prelude::*;
        let (first, rest) = self.filters.split_first_mut().expect("an island");
        // The samples' times are checked by the first island before any other moves.
        first.update(t, y)?;
        rest.par_iter_mut()
            .map(|f| f.update(t, y).map(|_| ()))
            .collect::<Result<Vec<()>>>()?;
        let rows: Vec<&TraceRow> = self
            .filters
            .iter()
            .map(|f| f.posterior().trace.last().expect("a row"))
            .collect();
        let row = merge_rows(&rows)?;
        let parts: Vec<Posterior> = self
            .filters
            .iter()
            .map(|f| f.posterior().clone_without_trace())
            .collect();
        let trace = std::mem::take(&mut self.merged.trace);
        self.merged = merge_counts(&parts)?;
        self.merged.trace = trace;
        self.merged.trace.push(row);
        Ok(self.merged.trace.last().expect("a row"))
    }

    /// The merged posterior so far (its sensors are formed by [`Islands::sensors`]).
    pub fn posterior(&self) -> &Posterior {
        &self.merged
    }

    /// The sensors' gains and offsets after the last sample, the islands' mixed.
    pub fn sensors(&self) -> Option<SensorPosterior> {
        merge_sensors(&self.filters.iter().map(Filter::sensors).collect::<Vec<_>>())
    }

    /// Each island's particles after the last sample ([`Filter::particles`]).
    pub fn particles(&self) -> Vec<Particles> {
        self.filters.iter().map(Filter::particles).collect()
    }

    /// The merged posterior after the last sample, with the sensors, as [`run`] returns it.
    pub fn finish(self) -> Result<Posterior> {
        merge(self.filters.into_iter().map(Filter::finish).collect())
    }
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
