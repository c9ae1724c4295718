//! Several recordings of one whisker: learning that whisker from all of them together.
//!
//! A filter that entertains many whiskers weighs each by how well it explains one recording
//! ([`super::Posterior::whisker_log_evidence`]). Recordings made with the same whisker share it,
//! so the sum of their log evidences weighs each whisker by the whole batch, which one strike
//! alone cannot: the batch's favourite is close to the recordings' whisker even where each
//! strike's favourite is not. Pooling proceeds in rounds: filter every recording, sum the
//! evidences ([`scores`]), draw the next round's whiskers around those the batch favours
//! ([`next_whiskers`]), and filter again. The last round's posteriors are the estimates.

use super::gains::{self, AngleGains, GainMessage};
use super::recording::{Estimate, Options, MISFIT_LIMIT};
use crate::error::{Error, Result};
use vibrissa_core::rng::Rng;
use vibrissa_core::whisker::{Damping, Follicle, WhiskerParams};

/// Rounds of pooling after the first filtering of the batch, by default.
pub const ROUNDS: usize = 6;

/// Least batch that the filter pools by default ([`by_default`]): on the first 5 strikes of
/// six foreign sets pooling gained on every one, and below 5 recordings the outlier rule
/// ([`OUTLIER_LEAST`]) cannot name a recording of another whisker.
pub const AUTO_LEAST: usize = 5;

/// Whether the filter pools a batch of `recordings` of `family` when not told either way: when
/// it entertains several whiskers (the family is randomised, by request or because the
/// recordings defy its whisker), the whisker is not a calibrated one (whose fit is usually the
/// better whisker), and the batch holds at least [`AUTO_LEAST`] recordings. A batch is taken
/// to hold one whisker and one set of sensors; recordings of different whiskers must be
/// estimated apart, or with pooling switched off.
pub fn by_default(recordings: usize, family: &crate::Family) -> bool {
    recordings >= AUTO_LEAST && family.randomisation().is_some() && !family.is_calibrated()
}

/// Least log-sd of the whisker parameters drawn around the batch's favourites: each round looks
/// at least 5% around them, so that the rounds keep moving towards the whisker the batch
/// favours instead of settling on the first one found.
pub const FLOOR: f64 = 0.05;

/// A whisker that lost every particle on a recording counts as this many nats below the least
/// whisker that kept some (its evidence there is lower than theirs but was not measured): a
/// single recording then weighs against it without vetoing it.
pub const LOST_MARGIN: f64 = 5.0;

/// Each whisker's log evidence summed over the recordings: `evidence[r][h]` is recording `r`'s
/// log evidence of whisker `h` (`-inf` where it lost every particle, counted as
/// [`LOST_MARGIN`] below the recording's least finite one).
pub fn scores(evidence: &[Vec<f64>]) -> Result<Vec<f64>> {
    let bad = |detail: String| Error::Observation(format!("pooling the recordings: {detail}"));
    let Some(first) = evidence.first() else {
        return Err(bad("no recordings".into()));
    };
    let n = first.len();
    if n < 2 {
        return Err(bad(
            "the filter entertained one whisker: nothing to pool (it needs alternative whiskers, as --randomise gives)".into(),
        ));
    }
    let mut total = vec![0.0; n];
    for (r, ev) in evidence.iter().enumerate() {
        if ev.len() != n {
            return Err(bad(format!(
                "recording {r} weighed {} whiskers, the first {n}",
                ev.len()
            )));
        }
        if ev.iter().any(|x| x.is_nan() || *x == f64::INFINITY) {
            return Err(bad(format!(
                "recording {r} has a log evidence that is not a number"
            )));
        }
        let least = ev
            .iter()
            .copied()
            .filter(|x| x.is_finite())
            .fold(f64::INFINITY, f64::min);
        if !least.is_finite() {
            return Err(bad(format!("recording {r} kept no whisker")));
        }
        for (t, &x) in total.iter_mut().zip(ev) {
            *t += if x.is_finite() {
                x
            } else {
                least - LOST_MARGIN
            };
        }
    }
    Ok(total)
}

/// The damping's one parameter, if it has one.
fn damping_value(d: &Damping) -> Option<f64> {
    match *d {
        Damping::ModalRatio { ratio } => Some(ratio),
        Damping::SegmentQ { q } => Some(q),
        Damping::StiffnessProportional { beta } => Some(beta),
        Damping::None => None,
    }
}

/// `d` with its parameter set to `x`.
fn with_damping_value(d: &Damping, x: f64) -> Damping {
    match d {
        Damping::ModalRatio { .. } => Damping::ModalRatio { ratio: x },
        Damping::SegmentQ { .. } => Damping::SegmentQ { q: x },
        Damping::StiffnessProportional { .. } => Damping::StiffnessProportional { beta: x },
        Damping::None => Damping::None,
    }
}

/// Weighted mean and covariance of the rows of `x` with weights `p` (summing to 1).
fn moments<const K: usize>(x: &[[f64; K]], p: &[f64]) -> ([f64; K], [[f64; K]; K]) {
    let mut mean = [0.0; K];
    for (row, &w) in x.iter().zip(p) {
        for k in 0..K {
            mean[k] += w * row[k];
        }
    }
    let mut cov = [[0.0; K]; K];
    for (row, &w) in x.iter().zip(p) {
        for i in 0..K {
            for j in 0..K {
                cov[i][j] += w * (row[i] - mean[i]) * (row[j] - mean[j]);
            }
        }
    }
    (mean, cov)
}

/// `count` whiskers for the next round, given this round's `whiskers` and their pooled
/// [`scores`]: the favourite first, then draws around the favoured ones. The batch's weights
/// are `exp(score − max)`. The logarithms of the modulus, density, tip radius and damping are
/// drawn jointly normal with the weighted mean and covariance of the whiskers of the favourite's
/// damping kind, plus [`FLOOR`]² on the diagonal; the follicle is a spring with the weighted
/// share of sprung whiskers (its stiffness and damping log-normal about theirs, with twice the
/// floor), clamped otherwise. Everything else is the favourite's.
pub fn next_whiskers(
    whiskers: &[WhiskerParams],
    scores: &[f64],
    count: usize,
    seed: u64,
) -> Result<Vec<WhiskerParams>> {
    let bad = |detail: &str| Error::Observation(format!("pooling the recordings: {detail}"));
    if whiskers.len() != scores.len() || whiskers.is_empty() {
        return Err(bad("one score per whisker needed"));
    }
    if scores.iter().any(|s| !s.is_finite()) {
        return Err(bad("a pooled score is not finite"));
    }
    let max = scores.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let best = scores
        .iter()
        .position(|&s| s == max)
        .expect("the maximum is one of the scores");
    let favourite = &whiskers[best];
    let kind = std::mem::discriminant(&favourite.damping);
    // The whiskers whose continuous parameters enter the fit: the favourite's damping kind.
    let mut rows = Vec::new();
    let mut p = Vec::new();
    for (w, &s) in whiskers.iter().zip(scores) {
        let damping = if std::mem::discriminant(&w.damping) == kind {
            damping_value(&w.damping).map_or(0.0, f64::ln)
        } else {
            continue;
        };
        rows.push([
            w.youngs_modulus.ln(),
            w.density.ln(),
            w.tip_radius.ln(),
            damping,
        ]);
        p.push((s - max).exp());
    }
    let total: f64 = p.iter().sum();
    p.iter_mut().for_each(|x| *x /= total);
    let (mean, mut cov) = moments(&rows, &p);
    for (i, row) in cov.iter_mut().enumerate() {
        row[i] += FLOOR * FLOOR;
    }
    let chol = nalgebra::Matrix4::from_fn(|i, j| cov[i][j])
        .cholesky()
        .ok_or_else(|| bad("the favoured whiskers' spread is not positive definite"))?
        .l();
    // The follicle: the weighted share of springs, and their parameters' log-moments.
    let weights: Vec<f64> = scores.iter().map(|s| (s - max).exp() / total).collect();
    let springs: Vec<([f64; 2], f64)> = whiskers
        .iter()
        .zip(&weights)
        .filter_map(|(w, &p)| match w.follicle {
            Follicle::Spring { stiffness, damping } => {
                Some(([stiffness.ln(), damping.max(1e-300).ln()], p))
            }
            Follicle::Clamped => None,
        })
        .collect();
    let spring_share: f64 =
        springs.iter().map(|(_, p)| p).sum::<f64>() / weights.iter().sum::<f64>();
    let (spring_mean, spring_sd) = if springs.is_empty() {
        ([0.0; 2], [0.0; 2])
    } else {
        let sw: f64 = springs.iter().map(|(_, p)| p).sum();
        let x: Vec<[f64; 2]> = springs.iter().map(|(x, _)| *x).collect();
        let q: Vec<f64> = springs.iter().map(|(_, p)| p / sw.max(1e-300)).collect();
        let (m, c) = moments(&x, &q);
        let floor = 2.0 * FLOOR;
        (
            m,
            [
                (c[0][0] + floor * floor).sqrt(),
                (c[1][1] + floor * floor).sqrt(),
            ],
        )
    };
    let undamped_springs = springs.iter().all(|(x, _)| x[1] < -600.0);
    let mut rng = Rng::stream(seed, 0x9001);
    let mut out = vec![favourite.clone()];
    while out.len() < count {
        let z: [f64; 4] = std::array::from_fn(|_| rng.normal());
        let x: [f64; 4] =
            std::array::from_fn(|i| mean[i] + (0..=i).map(|j| chol[(i, j)] * z[j]).sum::<f64>());
        let mut w = favourite.clone();
        w.youngs_modulus = x[0].exp();
        w.density = x[1].exp();
        w.tip_radius = x[2].exp().min(w.base_radius);
        if damping_value(&w.damping).is_some() {
            w.damping = with_damping_value(&w.damping, x[3].exp());
        }
        w.follicle = if !springs.is_empty() && rng.uniform() < spring_share {
            let stiffness = (spring_mean[0] + spring_sd[0] * rng.normal()).exp();
            let damping = if undamped_springs {
                0.0
            } else {
                (spring_mean[1] + spring_sd[1] * rng.normal()).exp()
            };
            Follicle::Spring { stiffness, damping }
        } else {
            Follicle::Clamped
        };
        out.push(w);
    }
    out.truncate(count.max(1));
    Ok(out)
}

/// What pooling gives: the last round's estimates, and for each recording how much better
/// (nats) the best whisker it met in any round explains it than the batch's favourite of the
/// last round does (its log evidence there).
#[derive(Debug)]
pub struct Pooled {
    /// The last round's estimates, one per recording.
    pub estimates: Vec<Estimate>,
    /// Each recording's shortfall under the batch's favourite, nats (≥ 0; where the favourite
    /// lost every particle on it, counted as the pooling's sum counts a lost whisker:
    /// [`LOST_MARGIN`] below the least whisker the recording kept).
    pub shortfall: Vec<f64>,
    /// Whether the favourite lost every particle on each recording.
    pub lost: Vec<bool>,
}

/// Recordings flagged as disagreeing with the batch's favourite whisker: those whose
/// [`Pooled::shortfall`] is an outlier of the batch's, above its median by more than
/// [`OUTLIER_MADS`] scaled median absolute deviations. None in a batch of fewer than
/// [`OUTLIER_LEAST`] recordings.
pub fn disagreeing(shortfall: &[f64]) -> Vec<usize> {
    if shortfall.len() < OUTLIER_LEAST {
        return Vec::new();
    }
    let m = median(shortfall);
    let mad = median(&shortfall.iter().map(|s| (s - m).abs()).collect::<Vec<_>>());
    if !m.is_finite() || !mad.is_finite() {
        return Vec::new();
    }
    // The normal's scale from the MAD, and a floor of one nat for batches that agree closely.
    let limit = m + OUTLIER_MADS * (1.4826 * mad).max(1.0);
    (0..shortfall.len())
        .filter(|&r| shortfall[r] > limit)
        .collect()
}

/// A warning for the batch when the whiskers it settled on leave most of its recordings
/// unexplained ([`unexplained_batch`]), and one for each recording of `pooled` that
/// [`disagreeing`] flags, `names` naming the recordings in order.
pub fn warnings(pooled: &Pooled, names: &[String]) -> Vec<String> {
    let s = &pooled.shortfall;
    let each = disagreeing(s).into_iter().map(|r| {
        let how = if pooled.lost.get(r).copied().unwrap_or(false) {
            format!(
                "lost every particle on it (counted {:.1} nats worse than the best whisker it \
                 met, {LOST_MARGIN} below the least it kept)",
                s[r]
            )
        } else {
            format!(
                "explains it {:.1} nats worse than the best whisker it met",
                s[r]
            )
        };
        format!(
            "`{}`: the batch's favourite whisker {how}, where on half the batch it is within \
             {:.1} nats of the best: it may not be a recording of the batch's whisker (a \
             foreign recording pulls the others' estimates: pool it apart or leave it out); \
             on a batch of one whisker this happens to about one recording in twenty",
            names.get(r).map_or("?", String::as_str),
            median(s)
        )
    });
    unexplained_batch(pooled).into_iter().chain(each).collect()
}

/// The warning for a batch whose last round's median misfit exceeds [`MISFIT_LIMIT`], if it
/// does. The batch is judged by its median rather than recording by recording: the last
/// round's misfit separates sets of recordings (1.5–2.0 on stand-ins of our own chain, 1.8–2.6
/// on those around another engine's tapered whisker) more than it separates the strikes of one
/// set, and the pooled intervals held the truth in 88–100% of the strikes of sets that crossed 2
/// on some of their strikes (docs/filter.md).
fn unexplained_batch(pooled: &Pooled) -> Option<String> {
    let misfits: Vec<f64> = pooled.estimates.iter().map(|e| e.misfit).collect();
    // A batch of no recordings has a NaN median, and no warning.
    let mid = Some(median(&misfits)).filter(|m| *m > MISFIT_LIMIT)?;
    let lo = misfits.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = misfits.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    Some(format!(
        "the whiskers the batch settled on leave its recordings' residuals {mid:.1} times the \
         variance the filter's noise model allows (the median of the batch; {lo:.1} to \
         {hi:.1}), where recordings the scenario describes stay below {MISFIT_LIMIT}: none of \
         the whiskers the filter simulates is the recordings' own, and the estimates rest on a \
         model that misses part of them; calibrating the whisker from labelled strikes \
         (`vibrissa calibrate`) describes it better"
    ))
}

/// The median of `v` (NaN when empty; infinite values count as the largest).
pub fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(|a, b| a.total_cmp(b));
    match s.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => s[n / 2],
        n => 0.5 * (s[n / 2 - 1] + s[n / 2]),
    }
}

/// Scaled median absolute deviations above the median that flag a recording (see
/// [`disagreeing`]): a conventional outlier rule, not fitted.
pub const OUTLIER_MADS: f64 = 5.0;

/// Fewest recordings for [`disagreeing`] to judge.
pub const OUTLIER_LEAST: usize = 5;

/// The best log evidence of each recording over the whiskers of one round.
fn best_evidence(estimates: &[Estimate]) -> Vec<f64> {
    estimates
        .iter()
        .map(|e| {
            e.posterior
                .whisker_log_evidence
                .iter()
                .copied()
                .fold(f64::NEG_INFINITY, f64::max)
        })
        .collect()
}

/// Most recordings that the search rounds filter, by default: the rounds before the last look
/// for the batch's whisker on at most this many of its recordings, spread through the batch
/// ([`search_subset`]), and the last round filters every recording, so that a large batch costs
/// about one filtering per recording beyond these instead of one per round. On batches of 20–40
/// foreign strikes a search on 12 of them erred as much on average as one on all, but over seeds
/// it strayed further on a batch of 20 (docs/filter.md): up to 20 keep a batch of that size
/// pooled on all of its recordings.
pub const SEARCH_RECORDINGS: usize = 20;

/// Fewest recordings of the first filtering from which the joint angles' gains are pooled
/// ([`super::gains`]): their scatter between recordings is read off those recordings alone. On
/// the other engine's set, batches of 5 of its strikes read the distance worse with the gains
/// pooled on 3 of 4 batches (0.69 mm against 0.56 mm on average); batches of 10 (two of its, two
/// of stand-ins) as well (0.44 against 0.45 mm), and of 20 better (0.46 against 0.63 mm over
/// seven sets; docs/filter.md).
pub const GAINS_LEAST: usize = 10;

/// The indices of at most `most` of `recordings` recordings, spread evenly through the batch
/// (all of them when there are no more than `most`; at least one).
pub fn search_subset(recordings: usize, most: usize) -> Vec<usize> {
    let most = most.max(1);
    if recordings <= most {
        return (0..recordings).collect();
    }
    // The k-th of `most` equal shares of the batch, at its middle.
    (0..most)
        .map(|k| ((2 * k + 1) * recordings) / (2 * most))
        .collect()
}

/// Filters the recordings at the given indices (in that order) with the given options.
pub type FilterSome<'a> = dyn FnMut(&Options, &[usize]) -> Result<Vec<Estimate>> + 'a;

/// Pools a batch of `recordings` recordings: filters the search's recordings
/// ([`search_subset`] of at most `search`) with the family's whiskers, then for each of
/// `rounds` rounds draws the next whiskers around those the filtered recordings favour
/// ([`scores`], [`next_whiskers`]) and filters again with them ([`Options::whiskers`]): the
/// search's recordings in every round but the last, every recording in the last; then the
/// recordings on which the last favourite lost every particle again, as
/// [`Options::lost_islands`] islands where that is set and more than [`Options::islands`].
/// `filter(options, indices)` filters the recordings at `indices` (in that order). Tells
/// `progress` each round's favourite. Returns the last round's estimates of every recording and
/// each one's shortfall under the last favourite ([`Pooled`]; a recording outside the search
/// measures it against the best whisker of the last round only).
pub fn refine(
    recordings: usize,
    options: &Options,
    rounds: usize,
    search: usize,
    seed: u64,
    filter: &mut FilterSome<'_>,
    progress: &mut dyn FnMut(String),
) -> Result<Pooled> {
    if recordings == 0 {
        return Err(Error::Observation(
            "pooling the recordings: no recordings".into(),
        ));
    }
    if rounds == 0 {
        return Err(Error::Observation(
            "pooling the recordings: at least 1 round of pooling is needed".into(),
        ));
    }
    let subset = search_subset(recordings, search);
    let all: Vec<usize> = (0..recordings).collect();
    if subset.len() < recordings {
        progress(format!(
            "pooling: the search rounds filter {} of the {recordings} recordings, spread through \
             the batch; the last round filters all of them",
            subset.len()
        ));
    }
    // Filters the recordings `on` and keeps each one's best log evidence over the rounds.
    let mut best = vec![f64::NEG_INFINITY; recordings];
    let mut filter_on = |options: &Options, on: &[usize]| -> Result<Vec<Estimate>> {
        let estimates = one_each(on, filter(options, on)?)?;
        for (&r, e) in on.iter().zip(best_evidence(&estimates)) {
            best[r] = best[r].max(e);
        }
        Ok(estimates)
    };
    let mut options = options.clone();
    let mut estimates = filter_on(&options, &subset)?;
    // What each recording of the first filtering says about the joint angles' gains, and each
    // recording's prior of them for the later filterings.
    if options.pool_gains && subset.len() >= GAINS_LEAST {
        let messages: Vec<Option<GainMessage>> = (0..recordings)
            .map(|r| {
                let at = subset.iter().position(|&s| s == r)?;
                let e = &estimates[at];
                let q = e.posterior.angle_gains?;
                Some(q.divided_by(&AngleGains::of(&e.config)))
            })
            .collect();
        if let (Some(e), true) = (estimates.first(), messages.iter().any(Option::is_some)) {
            // One more recording's prior, under every message: what the batch reads.
            let mut priors = messages.clone();
            priors.push(None);
            let mut priors = gains::batch_priors(&AngleGains::nominal(&e.config), &priors);
            let batch = priors.pop().expect("one prior per recording and one more");
            progress(format!(
                "pooling: the batch reads the joint angles' gains as theta01 {:.3} ± {:.3}, \
                 theta12 {:.3} ± {:.3} (from one recording to the next); each recording is \
                 filtered on with what the others read",
                batch.mean[0],
                batch.var[0].sqrt(),
                batch.mean[1],
                batch.var[1].sqrt()
            ));
            options.batch_gains = priors;
        }
    }
    for round in 1..=rounds {
        let evidence: Vec<Vec<f64>> = estimates
            .iter()
            .map(|e| e.posterior.whisker_log_evidence.clone())
            .collect();
        let scores = scores(&evidence)?;
        let config = &estimates[0].config;
        let whiskers: Vec<WhiskerParams> = std::iter::once(config.whisker.clone())
            .chain(config.alternatives.iter().cloned())
            .collect();
        let next = next_whiskers(
            &whiskers,
            &scores,
            whiskers.len(),
            seed.wrapping_add(round as u64),
        )?;
        progress(format!(
            "pooling round {round} of {rounds}: the batch favours {}; filtering again among {} \
             whiskers drawn around it",
            describe(&next[0]),
            next.len()
        ));
        options.whiskers = Some(next);
        let on = if round == rounds { &all } else { &subset };
        estimates = filter_on(&options, on)?;
    }
    // The last round's favourite: its whiskers' pooled best.
    let evidence: Vec<Vec<f64>> = estimates
        .iter()
        .map(|e| e.posterior.whisker_log_evidence.clone())
        .collect();
    let (shortfall, lost) = shortfalls(&evidence, &best);
    // Where the favourite lost every particle, the recording's posterior rests on the few
    // particles of other whiskers that survived it, and where they settle depends on the
    // filter's seed: filtered again as islands, its intervals hold that scatter.
    let again: Vec<usize> = (0..recordings).filter(|&r| lost[r]).collect();
    let more = |&k: &usize| k > options.islands && !again.is_empty();
    if let Some(islands) = options.lost_islands.filter(more) {
        progress(format!(
            "pooling: the batch's favourite whisker lost every particle on {} of the \
             recordings; filtering {} again as {islands} islands, so that {} intervals hold \
             the filter's own scatter",
            again.len(),
            if again.len() == 1 { "it" } else { "them" },
            if again.len() == 1 { "its" } else { "their" }
        ));
        let apart = Options {
            islands,
            ..options.clone()
        };
        for (&r, e) in again.iter().zip(one_each(&again, filter(&apart, &again)?)?) {
            estimates[r] = e;
        }
    }
    // The batch is judged as a whole ([`warnings`]), not recording by recording.
    for e in &mut estimates {
        e.misfit_limit = None;
    }
    Ok(Pooled {
        estimates,
        shortfall,
        lost,
    })
}

/// `estimates`, if there is one for each recording of `on`.
fn one_each(on: &[usize], estimates: Vec<Estimate>) -> Result<Vec<Estimate>> {
    if estimates.len() == on.len() {
        return Ok(estimates);
    }
    Err(Error::Observation(format!(
        "pooling the recordings: asked to filter {} recordings, got {} estimates",
        on.len(),
        estimates.len()
    )))
}

/// Each recording's shortfall under the batch's favourite whisker (the best of the pooled
/// [`scores`] of `evidence`, the last round's log evidences per recording and whisker) below
/// `best`, the best log evidence each recording met in any round, and whether the favourite
/// lost every particle on it. A lost favourite is counted as the pooled scores count it,
/// [`LOST_MARGIN`] below the least whisker the recording kept: a whisker's particles die out
/// by chance as well as by misfit (on the other engine's 20 strikes, all of one whisker, the
/// favourite lost them on 4), so a lost favourite is no proof that the recording is another
/// whisker's. Zeros where the evidence cannot be pooled.
fn shortfalls(evidence: &[Vec<f64>], best: &[f64]) -> (Vec<f64>, Vec<bool>) {
    let Ok(total) = scores(evidence) else {
        return (vec![0.0; evidence.len()], vec![false; evidence.len()]);
    };
    let fav = (0..total.len()).fold(0, |b, h| if total[h] > total[b] { h } else { b });
    evidence
        .iter()
        .zip(best)
        .map(|(ev, b)| {
            let least = ev
                .iter()
                .copied()
                .filter(|x| x.is_finite())
                .fold(f64::INFINITY, f64::min);
            let lost = !ev[fav].is_finite();
            let at = if lost { least - LOST_MARGIN } else { ev[fav] };
            ((b - at).max(0.0), lost)
        })
        .unzip()
}

/// A whisker in a few words (modulus, density, tip radius, follicle), for progress messages.
fn describe(w: &WhiskerParams) -> String {
    let follicle = match w.follicle {
        Follicle::Clamped => "a clamped follicle".to_string(),
        Follicle::Spring { stiffness, .. } => {
            format!("a follicle spring of {stiffness:.3e} N·m/rad")
        }
    };
    format!(
        "modulus {:.3} GPa, density {:.0} kg/m³, tip radius {:.1} µm, {follicle}",
        w.youngs_modulus / 1e9,
        w.density,
        w.tip_radius * 1e6
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_recording_far_below_the_batch_s_favourite_is_flagged() {
        let mut s = vec![0.7, 1.2, 1.5, 2.0, 2.2, 2.6, 3.1, 3.5, 4.1, 5.2];
        assert!(disagreeing(&s).is_empty(), "a batch that agrees");
        s.push(35.0);
        s.push(40.0);
        assert_eq!(disagreeing(&s), vec![10, 11]);
        // Too few recordings to judge; a batch whose median is lost says nothing.
        assert!(disagreeing(&[0.0, 0.0, 50.0]).is_empty());
        assert!(disagreeing(&[f64::INFINITY; 6]).is_empty());
        // The warnings name the flagged recordings.
        let mut lost = vec![false; s.len()];
        lost[10] = true;
        let pooled = Pooled {
            estimates: Vec::new(),
            shortfall: s,
            lost,
        };
        let names: Vec<String> = (0..12).map(|k| format!("r{k}.csv")).collect();
        let w = warnings(&pooled, &names);
        assert_eq!(w.len(), 2);
        assert!(w[0].starts_with("`r10.csv`") && w[0].contains("lost every particle"));
        assert!(w[0].contains("counted 35.0 nats worse"), "{}", w[0]);
        assert!(w[1].starts_with("`r11.csv`") && w[1].contains("40.0 nats"));
    }

    #[test]
    fn a_lost_favourite_counts_as_the_pooled_scores_count_it() {
        let inf = f64::NEG_INFINITY;
        // Whisker 1 is the favourite (-10 - 15 - (20 + 5) = -50, against -52 and -53); it lost
        // every particle on the third recording, whose least kept whisker is at -20.
        let evidence = [
            vec![-12.0, -10.0, inf],
            vec![-22.0, -15.0, -16.0],
            vec![-18.0, inf, -20.0],
        ];
        let (s, lost) = shortfalls(&evidence, &[-9.0, -15.0, -18.0]);
        assert_eq!(lost, vec![false, false, true]);
        assert_eq!(s, vec![1.0, 0.0, 2.0 + LOST_MARGIN]);
        assert!(s.iter().all(|x| x.is_finite()));
        // Evidence that cannot be pooled leaves nothing to flag.
        let (s, lost) = shortfalls(&[vec![-1.0]], &[-1.0]);
        assert_eq!((s, lost), (vec![0.0], vec![false]));
    }

    #[test]
    fn a_batch_is_warned_of_when_most_of_its_recordings_are_unexplained() {
        use super::super::{Config, Posterior};
        let config = Config::e2([0.01, 0.01, 1e-6, 1e-4, 1e-4], 10, 1);
        let batch = |misfits: &[f64]| Pooled {
            estimates: misfits
                .iter()
                .map(|&misfit| Estimate {
                    posterior: Posterior::empty(vec!["d"]),
                    config: config.clone(),
                    sensor: [0.01; 5],
                    sigma: [0.01; 5],
                    misfit,
                    misfit_limit: None,
                    seconds: 0.0,
                })
                .collect(),
            shortfall: vec![0.0; misfits.len()],
            lost: vec![false; misfits.len()],
        };
        let names: Vec<String> = (0..5).map(|k| format!("r{k}.csv")).collect();
        // Two recordings above the limit, the median below it: no warning.
        assert!(warnings(&batch(&[1.5, 1.6, 1.7, 2.5, 2.6]), &names).is_empty());
        let w = warnings(&batch(&[2.1, 2.2, 2.3, 1.9, 2.4]), &names);
        assert_eq!(w.len(), 1);
        assert!(
            w[0].contains("2.2 times") && w[0].contains("1.9 to 2.4"),
            "{}",
            w[0]
        );
        // A recording of the batch is not warned of on its own; one filtered alone is, when its
        // misfit exceeds its limit.
        let mut one = batch(&[2.5]).estimates.remove(0);
        let unexplained =
            |e: &Estimate| e.warnings("r0.csv").iter().any(|w| w.contains("explains"));
        assert!(!unexplained(&one));
        one.misfit_limit = Some(2.7);
        assert!(!unexplained(&one));
        one.misfit_limit = Some(MISFIT_LIMIT);
        assert!(unexplained(&one));
        // Diverged steps are reported when more than a hundredth of the particles were dropped.
        let dropped = |e: &Estimate| e.warnings("r0.csv").iter().any(|w| w.contains("diverged"));
        one.config.particles = 1000;
        one.posterior.diverged = 10;
        assert!(!dropped(&one));
        one.posterior.diverged += 1;
        assert!(dropped(&one));
    }

    #[test]
    fn a_recording_the_favourite_lost_is_filtered_again_as_islands() {
        use super::super::{Config, Posterior};
        let mut config = Config::e2([0.01, 0.01, 1e-6, 1e-4, 1e-4], 10, 1);
        config.alternatives = vec![WhiskerParams {
            youngs_modulus: 2.5e9,
            ..config.whisker.clone()
        }];
        // Whisker 0 explains every recording better, but loses its particles on recording 2
        // when filtered as one island.
        let seen = std::cell::RefCell::new(Vec::new());
        let mut filter = |options: &Options, which: &[usize]| -> Result<Vec<Estimate>> {
            seen.borrow_mut().push((options.islands, which.to_vec()));
            Ok(which
                .iter()
                .map(|&r| {
                    let mut posterior = Posterior::empty(vec!["d"]);
                    posterior.whisker_log_evidence = if r == 2 && options.islands == 1 {
                        vec![f64::NEG_INFINITY, -2.0]
                    } else {
                        vec![-1.0, -2.0]
                    };
                    Estimate {
                        posterior,
                        config: config.clone(),
                        sensor: [0.01; 5],
                        sigma: [0.01; 5],
                        misfit: 1.0,
                        misfit_limit: Some(MISFIT_LIMIT),
                        seconds: options.islands as f64,
                    }
                })
                .collect())
        };
        let all: Vec<usize> = (0..8).collect();
        let mut options = Options::new(10);
        options.islands = 1;
        options.lost_islands = Some(3);
        let pooled = refine(8, &options, 2, 20, 1, &mut filter, &mut |_| {}).unwrap();
        assert_eq!(
            seen.take(),
            [
                (1, all.clone()),
                (1, all.clone()),
                (1, all.clone()),
                (3, vec![2])
            ]
        );
        assert_eq!(pooled.lost, all.iter().map(|&r| r == 2).collect::<Vec<_>>());
        // Its estimate is the islands', the others' the last round's.
        let took: Vec<f64> = pooled.estimates.iter().map(|e| e.seconds).collect();
        assert_eq!(
            took,
            all.iter()
                .map(|&r| if r == 2 { 3.0 } else { 1.0 })
                .collect::<Vec<_>>()
        );
        // Unset, or no more islands than every round ran: nothing is filtered again.
        for lost_islands in [None, Some(1)] {
            options.lost_islands = lost_islands;
            refine(8, &options, 2, 20, 1, &mut filter, &mut |_| {}).unwrap();
            assert_eq!(seen.take().len(), 3);
        }
    }

    #[test]
    fn each_recording_is_filtered_under_the_others_angle_gains() {
        use super::super::{Config, Posterior, SensorSpread};
        // Recording r measures theta12's gain as `seen[r]` with precision `each` (exactly
        // normal): a filter begun under N(μ, v) ends at the product. After a round, every
        // recording's prior must be the nominal times the other recordings' measurements.
        let seen = [0.42, 0.38, 0.45, 0.40, 0.36, 0.41, 0.44, 0.39, 0.37, 0.43];
        let n = seen.len();
        assert_eq!(n, GAINS_LEAST);
        let each = 400.0;
        let mut config = Config::e2([0.01, 0.01, 1e-6, 1e-4, 1e-4], 10, 1);
        config.sensor_spread = SensorSpread::rough();
        config.alternatives = vec![WhiskerParams {
            youngs_modulus: 2.5e9,
            ..config.whisker.clone()
        }];
        let nominal = AngleGains::nominal(&config);
        let priors_seen = std::cell::RefCell::new(Vec::<Vec<Option<AngleGains>>>::new());
        let mut filter = |options: &Options, which: &[usize]| -> Result<Vec<Estimate>> {
            let used = which.iter().map(|&r| options.for_recording(r).angle_gains);
            priors_seen.borrow_mut().push(used.collect());
            Ok(which
                .iter()
                .map(|&r| {
                    let mut config = config.clone();
                    config.angle_gains = options.for_recording(r).angle_gains;
                    let prior = AngleGains::of(&config);
                    let precision = 1.0 / prior.var[1] + each;
                    let mut post = prior;
                    post.var[1] = 1.0 / precision;
                    post.mean[1] = (prior.mean[1] / prior.var[1] + each * seen[r]) / precision;
                    let mut posterior = Posterior::empty(vec!["d"]);
                    posterior.whisker_log_evidence = vec![-1.0, -2.0];
                    posterior.angle_gains = Some(post);
                    Estimate {
                        posterior,
                        config,
                        sensor: [0.01; 5],
                        sigma: [0.01; 5],
                        misfit: 1.0,
                        misfit_limit: Some(MISFIT_LIMIT),
                        seconds: 0.0,
                    }
                })
                .collect())
        };
        let options = Options::new(10);
        let pooled = refine(n, &options, 2, 20, 1, &mut filter, &mut |_| {}).unwrap();
        // The batch is judged as a whole, not each of its recordings.
        assert!(pooled.estimates.iter().all(|e| e.misfit_limit.is_none()));
        // The first filtering knew nothing of the batch; each later one held the others.
        let first = priors_seen.take();
        assert_eq!(first.len(), 3);
        assert!(first[0].iter().all(Option::is_none));
        let v0 = nominal.var[1];
        for round in &first[1..] {
            for (r, prior) in round.iter().enumerate() {
                let prior = prior.expect("a batch prior");
                let others: f64 = (0..n).filter(|&s| s != r).map(|s| seen[s]).sum();
                let precision = 1.0 / v0 + (n - 1) as f64 * each;
                let mean = (nominal.mean[1] / v0 + each * others) / precision;
                assert!((prior.var[1] - 1.0 / precision).abs() < 1e-12 / precision);
                assert!(
                    (prior.mean[1] - mean).abs() < 1e-9,
                    "{} vs {mean}",
                    prior.mean[1]
                );
                // theta01's gain was not measured: its prior stays the nominal.
                assert_eq!(
                    (prior.mean[0], prior.var[0]),
                    (nominal.mean[0], nominal.var[0])
                );
            }
        }
        // Told not to, the batch leaves each recording's gains alone.
        let apart = Options {
            pool_gains: false,
            ..Options::new(10)
        };
        refine(n, &apart, 2, 20, 1, &mut filter, &mut |_| {}).unwrap();
        let second = priors_seen.take();
        assert_eq!(second.len(), 3);
        assert!(second.iter().flatten().all(Option::is_none));
        // Nor does a batch too small to read the gains' scatter from.
        refine(n - 1, &options, 2, 20, 1, &mut filter, &mut |_| {}).unwrap();
        assert!(priors_seen.take().iter().flatten().all(Option::is_none));
        // A search on fewer than that of a large batch: the gains are read from the search's.
        refine(n, &options, 2, n - 1, 1, &mut filter, &mut |_| {}).unwrap();
        assert!(priors_seen.take().iter().flatten().all(Option::is_none));
    }

    #[test]
    fn the_search_takes_recordings_spread_through_the_batch() {
        assert_eq!(search_subset(5, 12), vec![0, 1, 2, 3, 4]);
        assert_eq!(search_subset(12, 12).len(), 12);
        let s = search_subset(40, 12);
        assert_eq!(s.len(), 12);
        assert!(s.windows(2).all(|w| w[0] < w[1]), "{s:?}");
        assert_eq!((s[0], s[11]), (1, 38));
        // Every share of the batch holds one: gaps of 3 or 4 recordings.
        assert!(
            s.windows(2).all(|w| (3..=4).contains(&(w[1] - w[0]))),
            "{s:?}"
        );
        assert_eq!(search_subset(3, 0), vec![1]);
        assert!(search_subset(0, 12).is_empty());
    }

    #[test]
    fn scores_sum_the_recordings_and_count_a_lost_whisker_below_the_least_kept() {
        let inf = f64::NEG_INFINITY;
        let s = scores(&[vec![-10.0, -12.0, inf], vec![-20.0, -15.0, -16.0]]).unwrap();
        assert_eq!(s, vec![-30.0, -27.0, -12.0 - LOST_MARGIN - 16.0]);
        assert!(scores(&[]).is_err());
        assert!(scores(&[vec![-1.0]]).is_err(), "one whisker");
        assert!(
            scores(&[vec![-1.0, -2.0], vec![-1.0]]).is_err(),
            "lengths differ"
        );
        assert!(scores(&[vec![inf, inf]]).is_err(), "no whisker kept");
        assert!(scores(&[vec![f64::NAN, -1.0]]).is_err());
    }

    #[test]
    fn the_next_whiskers_gather_around_the_batch_s_favourites() {
        let base = WhiskerParams::w30();
        let mut whiskers = Vec::new();
        for k in 0..8 {
            let mut w = base.clone();
            w.youngs_modulus = base.youngs_modulus * (0.7 + 0.1 * k as f64);
            w.density = base.density * (1.3 - 0.05 * k as f64);
            if k % 2 == 1 {
                w.follicle = Follicle::Spring {
                    stiffness: 1e-4 * (1.0 + k as f64),
                    damping: 1e-8,
                };
            }
            whiskers.push(w);
        }
        // Whisker 4 (clamped, modulus 1.1 times the base's) is far ahead of the others.
        let mut s = vec![-100.0; 8];
        s[4] = 0.0;
        let next = next_whiskers(&whiskers, &s, 400, 7).unwrap();
        assert_eq!(next.len(), 400);
        assert_eq!(next[0], whiskers[4]);
        let logs: Vec<f64> = next[1..]
            .iter()
            .map(|w| (w.youngs_modulus / whiskers[4].youngs_modulus).ln())
            .collect();
        let m = logs.iter().sum::<f64>() / logs.len() as f64;
        let sd = (logs.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / logs.len() as f64).sqrt();
        assert!(m.abs() < 0.015, "mean log-ratio {m}");
        assert!((sd - FLOOR).abs() < 0.01, "log-sd {sd}");
        assert!(next.iter().all(|w| w.follicle == Follicle::Clamped));
        assert!(next.iter().all(|w| w.tip_radius <= w.base_radius));
        assert!(next.iter().all(|w| w.check().is_ok()));
        // Two favourites, one sprung: both kinds drawn, about half each, and the spread spans
        // the two moduli.
        s[5] = 0.0;
        let next = next_whiskers(&whiskers, &s, 400, 7).unwrap();
        let sprung = next
            .iter()
            .filter(|w| matches!(w.follicle, Follicle::Spring { .. }))
            .count();
        assert!((150..250).contains(&sprung), "{sprung}");
        let e: Vec<f64> = next.iter().map(|w| w.youngs_modulus).collect();
        let lo = e.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = e.iter().copied().fold(0.0, f64::max);
        assert!(lo < whiskers[4].youngs_modulus && hi > whiskers[5].youngs_modulus);
        // The same seed draws the same whiskers.
        assert_eq!(next, next_whiskers(&whiskers, &s, 400, 7).unwrap());
        assert!(next_whiskers(&whiskers, &s[..3], 10, 7).is_err());
    }
}
