//! What the filter reads and returns: observations, the per-sample trace and the posterior, and
//! the weighted summary of one unknown.

use super::gains::AngleGains;
use crate::method::Estimate;
use serde::Serialize;

/// Observations: sample times and channel values (`NaN` where a sample is missing).
#[derive(Debug, Clone, PartialEq)]
pub struct Observations {
    /// Sample times, s, increasing, starting at 0.
    pub t: Vec<f64>,
    /// `[CHANNELS][samples]`; channels that are not observed may be empty.
    pub values: Vec<Vec<f64>>,
}

impl Observations {
    /// Observations sampled at `rate` (Hz) from t = 0, from channel-major series.
    pub fn at_rate(values: Vec<Vec<f64>>, rate: f64) -> Observations {
        let n = values.iter().map(Vec::len).max().unwrap_or(0);
        Observations {
            t: (0..n).map(|k| k as f64 / rate).collect(),
            values,
        }
    }
}

/// The posterior of one sample.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TraceRow {
    /// Sample time, s.
    pub t: f64,
    /// Effective sample size before any resampling at this sample.
    pub ess: f64,
    /// Per free unknown: the posterior summary.
    pub estimates: Vec<Estimate>,
}

impl TraceRow {
    /// The row with the summaries of its first `factors.len()` unknowns widened about their
    /// means: the std and the interval's distances from the mean times each one's factor.
    pub fn widened(&self, factors: &[f64]) -> TraceRow {
        let mut row = self.clone();
        for (e, &f) in row.estimates.iter_mut().zip(factors) {
            e.std *= f;
            e.ci90 = [
                e.mean - f * (e.mean - e.ci90[0]),
                e.mean + f * (e.ci90[1] - e.mean),
            ];
        }
        row
    }

    /// The row with each estimate kept within `support` (per unknown, `[lo, hi]` of its prior,
    /// or `None`): the interval clipped to it, the std at most the prior's own (a uniform's,
    /// (hi − lo)/√12), the mean inside it. A widened row may otherwise claim to know less than
    /// the prior, or place its interval where the prior gives no weight.
    pub fn within(&self, support: &[Option<[f64; 2]>]) -> TraceRow {
        let mut row = self.clone();
        for (e, s) in row.estimates.iter_mut().zip(support) {
            let Some([lo, hi]) = *s else { continue };
            e.mean = e.mean.clamp(lo, hi);
            e.std = e.std.min((hi - lo) / 12f64.sqrt());
            e.ci90 = [e.ci90[0].clamp(lo, hi), e.ci90[1].clamp(lo, hi)];
        }
        row
    }
}

/// What a filter run returns.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Posterior {
    /// Names of the free unknowns, in the order of every [`TraceRow::estimates`].
    pub unknowns: Vec<&'static str>,
    /// One row per sample.
    pub trace: Vec<TraceRow>,
    /// Samples whose channel values were missing (`NaN`) and skipped, counted per value.
    pub skipped: usize,
    /// Resampling events.
    pub resamples: usize,
    /// Particle steps that diverged (those particles got weight zero).
    pub diverged: usize,
    /// Moves after resampling that were undone because they put a box around its particle's
    /// whisker (the particle kept its parent's box).
    pub refused_moves: usize,
    /// Physics steps taken over all particles.
    pub steps: u64,
    /// Share of particle-samples advanced on the free-ringing model (the box gone for good).
    pub ringing_share: f64,
    /// Logarithm of the (tempered) marginal likelihood of the observations, up to a constant
    /// that depends only on the noise levels: the sum over samples of the log mean weight
    /// update. Compares priors or models on the same series.
    pub log_evidence: f64,
    /// Factor by which the filter widened its observation noise for the recording's sample rate
    /// ([`super::per_time_factor`]; 1 at 1 kHz and below).
    pub rate_widening: f64,
    /// The sensors' gains and offsets after the last sample, per channel of
    /// [`crate::experiment::CHANNELS`], when the filter was not told them exactly
    /// ([`super::Config::sensor_spread`]); set by [`super::Filter::finish`] (`None` while the
    /// filter runs: [`super::Filter::sensors`] forms them then).
    pub sensors: Option<SensorPosterior>,
    /// The joint angles' gains after the last sample (the particles' beliefs matched to one
    /// normal each), when the filter was not told them exactly: what a batch pools.
    #[serde(skip)]
    pub angle_gains: Option<AngleGains>,
    /// The whisker parameters that differ between the whiskers the filter entertains, after
    /// the last sample, by their keys (`whisker.youngs_modulus`, …, the follicle by
    /// `whisker.follicle.compliance`); empty when it was told its whisker.
    pub whisker: Vec<(&'static str, Estimate)>,
    /// Log evidence of each whisker the filter entertains (the scenario's first, then its
    /// alternatives): the (tempered) likelihood of the samples so far given that whisker, up to
    /// the constant of [`Posterior::log_evidence`]; `-inf` once the whisker has lost every
    /// particle. Empty when the filter was told its whisker. Not serialised (JSON has no
    /// infinity).
    #[serde(skip)]
    pub whisker_log_evidence: Vec<f64>,
}

/// The posterior of the sensors' gains and offsets (their mean and standard deviation over the
/// particles and their beliefs).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SensorPosterior {
    /// Gain of each channel's sensor.
    pub gain: [Estimate; 5],
    /// Offset of each channel's sensor, in the channel's unit.
    pub offset: [Estimate; 5],
}

impl Posterior {
    /// A posterior over `unknowns` with no sample yet.
    pub fn empty(unknowns: Vec<&'static str>) -> Posterior {
        Posterior {
            unknowns,
            trace: Vec::new(),
            skipped: 0,
            resamples: 0,
            diverged: 0,
            refused_moves: 0,
            steps: 0,
            ringing_share: 0.0,
            log_evidence: 0.0,
            rate_widening: 1.0,
            sensors: None,
            angle_gains: None,
            whisker: Vec::new(),
            whisker_log_evidence: Vec::new(),
        }
    }

    /// Every row's summary of the first `factors.len()` unknowns widened about its mean: the
    /// std and the interval's distances from the mean times each one's factor.
    pub fn widen(&mut self, factors: &[f64]) {
        for row in &mut self.trace {
            *row = row.widened(factors);
        }
    }

    /// Every row kept within `support` ([`TraceRow::within`]).
    pub fn within(&mut self, support: &[Option<[f64; 2]>]) {
        for row in &mut self.trace {
            *row = row.within(support);
        }
    }

    /// This posterior without its rows (every count and summary but the trace).
    pub fn clone_without_trace(&self) -> Posterior {
        Posterior {
            unknowns: self.unknowns.clone(),
            trace: Vec::new(),
            skipped: self.skipped,
            resamples: self.resamples,
            diverged: self.diverged,
            refused_moves: self.refused_moves,
            steps: self.steps,
            ringing_share: self.ringing_share,
            log_evidence: self.log_evidence,
            rate_widening: self.rate_widening,
            sensors: self.sensors.clone(),
            angle_gains: self.angle_gains,
            whisker: self.whisker.clone(),
            whisker_log_evidence: self.whisker_log_evidence.clone(),
        }
    }

    /// The posterior at the last sample.
    pub fn last(&self) -> &[Estimate] {
        self.trace.last().map(|r| &r.estimates[..]).unwrap_or(&[])
    }

    /// The sample time and effective sample size where the effective sample size was least (the
    /// first such sample), if there is any sample. A value near 1 means that one particle carried
    /// almost all the weight there: the cloud had lost the data, and the posterior after it
    /// rests on the descendants of very few particles and is likely too narrow.
    pub fn least_ess(&self) -> Option<(f64, f64)> {
        self.trace
            .iter()
            .map(|r| (r.t, r.ess))
            .reduce(|a, b| if b.1 < a.1 { b } else { a })
    }
}

/// Weighted mean, std and central 90% interval.
pub(super) fn summarise(vals: &[f64], w: &[f64]) -> Estimate {
    summarise_in_order(vals, w, &mut Vec::new())
}

/// [`summarise`], with `order` the particles' order by value at the last call (the indices of
/// `vals` in ascending order of their values then; empty, or of another length, at the first
/// call), brought up to date here. A filter's static unknowns keep their values from sample to
/// sample until the particles are resampled, so the order of the last sample is nearly or wholly
/// the order of this one, and sorting it again takes a pass instead of a full sort.
pub(super) fn summarise_in_order(vals: &[f64], w: &[f64], order: &mut Vec<u32>) -> Estimate {
    let mean: f64 = vals.iter().zip(w).map(|(x, w)| x * w).sum();
    let var: f64 = vals
        .iter()
        .zip(w)
        .map(|(x, w)| w * (x - mean) * (x - mean))
        .sum();
    if order.len() != vals.len() {
        order.clear();
        order.extend(0..vals.len() as u32);
    }
    // A stable sort finds the runs that are already in order. Equal values may come in any
    // order: the quantile is the value at which the cumulative weight crosses q, whichever of
    // the equal ones it stops at (their order moves that sum only by rounding).
    order.sort_by(|&a, &b| vals[a as usize].total_cmp(&vals[b as usize]));
    let quantile = |q: f64| {
        let mut cum = 0.0;
        for &i in order.iter() {
            cum += w[i as usize];
            if cum >= q {
                return vals[i as usize];
            }
        }
        vals[*order.last().expect("at least one particle") as usize]
    };
    Estimate {
        mean,
        std: var.max(0.0).sqrt(),
        ci90: [quantile(0.05), quantile(0.95)],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn least_ess_finds_the_first_smallest_sample() {
        let row = |t: f64, ess: f64| TraceRow {
            t,
            ess,
            estimates: vec![],
        };
        let mut post = Posterior::empty(vec![]);
        assert_eq!(post.least_ess(), None);
        post.trace = vec![
            row(0.0, 100.0),
            row(0.001, 3.0),
            row(0.002, 3.0),
            row(0.003, 50.0),
        ];
        assert_eq!(post.least_ess(), Some((0.001, 3.0)));
    }

    #[test]
    fn widening_scales_the_std_and_the_interval_about_the_mean() {
        let mut post = Posterior::empty(vec!["d", "v"]);
        let e = |mean: f64, std: f64, lo: f64, hi: f64| Estimate {
            mean,
            std,
            ci90: [lo, hi],
        };
        post.trace = vec![TraceRow {
            t: 0.0,
            ess: 10.0,
            estimates: vec![e(2.0, 0.5, 1.0, 4.0), e(1.0, 0.1, 0.9, 1.1)],
        }];
        post.widen(&[2.0]);
        let last = post.last();
        assert_eq!((last[0].std, last[0].ci90), (1.0, [0.0, 6.0]));
        // Unknowns past the factors given stay as they were.
        assert_eq!((last[1].std, last[1].ci90), (0.1, [0.9, 1.1]));
    }

    #[test]
    fn a_kept_order_gives_the_summary_of_a_fresh_one() {
        let vals: Vec<f64> = (0..200).map(|i| ((i * 37) % 101) as f64 * 0.1).collect();
        let w: Vec<f64> = (0..200).map(|i| 1.0 + (i % 7) as f64).collect();
        let total: f64 = w.iter().sum();
        let w: Vec<f64> = w.iter().map(|x| x / total).collect();
        let fresh = summarise(&vals, &w);
        // An order kept from other values (reversed), then from the same ones.
        let mut order: Vec<u32> = (0..200).rev().collect();
        assert_eq!(summarise_in_order(&vals, &w, &mut order).ci90, fresh.ci90);
        assert!(order
            .windows(2)
            .all(|p| vals[p[0] as usize] <= vals[p[1] as usize]));
        let kept = summarise_in_order(&vals, &w, &mut order);
        assert_eq!(
            (kept.mean, kept.std, kept.ci90),
            (fresh.mean, fresh.std, fresh.ci90)
        );
        // A stale order of another length is replaced.
        let mut short = vec![0u32; 3];
        assert_eq!(summarise_in_order(&vals, &w, &mut short).ci90, fresh.ci90);
        assert_eq!(short.len(), 200);
    }

    #[test]
    fn weighted_summary_matches_hand_values() {
        let e = summarise(&[1.0, 2.0, 3.0], &[0.25, 0.5, 0.25]);
        assert!((e.mean - 2.0).abs() < 1e-12);
        assert!((e.std - 0.5f64.sqrt()).abs() < 1e-12);
        assert_eq!(e.ci90, [1.0, 3.0]);
    }
}
