//! Recordings that start some time before the approach (a lead-in of rest before contact).
//!
//! A method trained on runs that start at the approach reads the time from the start to contact
//! as evidence about the object: a recording with a lead-in of rest looks like a much slower or
//! farther object, and the kernel regressors then go far wrong. This module tells when a
//! recording leaves rest later than any run of its scenario does, seen through the same sensor
//! noise ([`departure`], [`evident_lead`], [`batch_leads`]), and aligns series at the contact's
//! onset ([`contact_onset`], [`onset_time`], [`align`]) so that [`crate::methods::Aligned`] can
//! read them whatever their lead-in.

use crate::error::{Error, Result};
use crate::experiment::{Noise, THETA12};
use crate::family::Family;
use crate::recording::Recording;

/// The onset threshold, as a share of the series' own peak deviation of theta12 from its first
/// sample: relative, so that a whisker or chain whose joint angles are larger or smaller than
/// the scenario's (another segment count, another stiffness) crosses it at the same stage of
/// its rise; high above a sensor noise of a few percent of the range, low enough to be crossed
/// early in the rise.
pub const ONSET_SHARE: f64 = 0.2;

/// A departure from rest that counts, in sensor noise standard deviations (the departure from
/// the first sample, itself noisy, has about 1.4 of them).
pub const DEPART_Z: f64 = 5.0;

/// Without sensor noise, a departure that counts as a share of a channel's median peak
/// deviation over the scenario's runs.
pub const CLEAN_SHARE: f64 = 0.02;

/// Slack before a recording's departure from rest counts as later than its scenario's, s: a
/// whisker other than the scenario's may leave rest a little later (a softer whisker in a
/// softer follicle rises more slowly through the noise).
pub const ONSET_SLACK: f64 = 0.004;

/// A recording's departure from rest tells its start only when the strike stands clear of the
/// noise: some channel must reach this many times its departure threshold
/// ([`DEPART_Z`] noise deviations) from its first sample. A strike that barely rises through the
/// noise (a light touch near the tip under 10% noise: every channel's peak within 1.3 times the
/// threshold) crosses it at a time the noise chooses, tens of milliseconds after contact.
pub const CLEAR_PEAK: f64 = 2.0;

/// Further slack, as a share of the scenario's latest departure: a slow strike of a softer
/// whisker rises through the noise later in proportion (one of stand-in 14's strikes, recorded
/// from its approach, left rest at 24 ms where the scenario's latest run did at 11 ms). Shorter
/// lead-ins show in a batch instead ([`batch_leads`]).
pub const SLACK_SHARE: f64 = 1.0;

/// Fewest slack samples (at low sample rates).
const MIN_SLACK_SAMPLES: usize = 2;

/// Largest share of a recording that a lead-in may take: the rest must hold the strike.
pub const MAX_LEAD_SHARE: f64 = 0.5;

/// How improbable, for a recording at rest, the trend that vetoes a lead-in must be: the
/// channels' slopes over the span in which the scenario's runs all leave rest, in units of their
/// standard errors, summed in squares, beyond the chi-square quantile of this upper tail.
pub const MOTION_P: f64 = 1e-3;

/// The chi-square quantiles whose upper tail is [`MOTION_P`], for 1 to 5 degrees of freedom
/// (channels).
const MOTION_CHI2: [f64; 5] = [10.828, 13.816, 16.266, 18.467, 20.515];

/// The largest deviation of `x` from its first sample.
pub fn peak_deviation(x: &[f64]) -> f64 {
    let base = x.first().copied().unwrap_or(0.0);
    x.iter().map(|v| (v - base).abs()).fold(0.0, f64::max)
}

/// The onset threshold of a theta12 series: [`ONSET_SHARE`] of its peak deviation.
pub fn own_threshold(theta12: &[f64]) -> f64 {
    ONSET_SHARE * peak_deviation(theta12)
}

/// The contact's onset in a theta12 series: the first sample that, with the next one, deviates
/// from the first sample by more than `threshold` (two samples, so that one noise spike does
/// not count); `None` when there is none.
pub fn contact_onset(theta12: &[f64], threshold: f64) -> Option<usize> {
    let base = *theta12.first()?;
    let above = |k: usize| (theta12[k] - base).abs() > threshold;
    (1..theta12.len()).find(|&k| above(k) && (k + 1 == theta12.len() || above(k + 1)))
}

/// The contact's onset to a fraction of a sample: where the deviation from the first sample
/// crosses `threshold` between the sample before [`contact_onset`]'s and that one (linearly
/// interpolated), in samples from the first.
pub fn onset_time(theta12: &[f64], threshold: f64) -> Option<f64> {
    if threshold <= 0.0 {
        return None;
    }
    let k = contact_onset(theta12, threshold)?;
    let base = theta12[0];
    let (a, b) = ((theta12[k - 1] - base).abs(), (theta12[k] - base).abs());
    let share = if b > a {
        ((threshold - a) / (b - a)).clamp(0.0, 1.0)
    } else {
        1.0
    };
    Some((k - 1) as f64 + share)
}

/// Share of a theta12 series' peak deviation up to which [`contact_start`] follows its rise.
pub const RISE_SHARE: f64 = 0.5;

/// When the contact began, in samples from the first (fractional, may be below 0): the rise of
/// theta12 from [`ONSET_SHARE`] to [`RISE_SHARE`] of its peak deviation, extended back as a line
/// to no deviation. Unlike the time at which a series leaves rest through its noise, this hardly
/// depends on how strong the strike is or how noisy the recording: the box pushes the whisker
/// at its own speed from the moment it meets it, so the early rise is close to a line. `None`
/// when the series never rises that far.
pub fn contact_start(theta12: &[f64]) -> Option<f64> {
    let peak = peak_deviation(theta12);
    let low = onset_time(theta12, ONSET_SHARE * peak)?;
    let high = onset_time(theta12, RISE_SHARE * peak)?;
    Some(low - (high - low) * ONSET_SHARE / (RISE_SHARE - ONSET_SHARE))
}

/// `window` samples of every channel of `series` shifted so that the time `onset` (in samples,
/// fractional) lands on sample `pre`, linearly interpolated between samples: before the
/// series' start each channel holds its first value, past its end its last. Empty channels stay
/// empty.
pub fn align(series: &[Vec<f64>], onset: f64, pre: usize, window: usize) -> Vec<Vec<f64>> {
    series
        .iter()
        .map(|ch| {
            if ch.is_empty() {
                return Vec::new();
            }
            let last = ch.len() - 1;
            (0..window)
                .map(|k| {
                    let at = k as f64 + onset - pre as f64;
                    if at <= 0.0 {
                        ch[0]
                    } else if at >= last as f64 {
                        ch[last]
                    } else {
                        let (i, f) = (at.floor() as usize, at.fract());
                        ch[i] * (1.0 - f) + ch[i + 1] * f
                    }
                })
                .collect()
        })
        .collect()
}

/// The first sample at which any channel with a threshold above 0 leaves its first value by
/// more than its threshold, and stays beyond it at the next sample; `None` when none does.
pub fn departure(series: &[Vec<f64>], thresholds: &[f64; 5]) -> Option<usize> {
    let samples = series.iter().map(Vec::len).max().unwrap_or(0);
    (1..samples).find(|&k| {
        series.iter().zip(thresholds).any(|(x, &thr)| {
            let beyond = |i: usize| x.get(i).is_some_and(|v| (v - x[0]).abs() > thr);
            thr > 0.0 && !x.is_empty() && beyond(k) && (k + 1 == x.len() || beyond(k + 1))
        })
    })
}

/// When the runs of a scenario leave rest, as seen through a recording's sensor noise.
#[derive(Debug, Clone)]
pub struct OnsetRange {
    /// Sample rate, Hz, samples of the runs, and the noise.
    timing: (f64, usize, [f64; 5]),
    /// Per channel, the departure that counts (0: the channel is not looked at), SI.
    pub thresholds: [f64; 5],
    /// Earliest and latest departure among the runs, samples.
    pub earliest: usize,
    /// See `earliest`.
    pub latest: usize,
    /// The latest [`contact_start`] of theta12 among the runs, samples (`None` when the
    /// recording lacks theta12 or no run rises).
    pub latest_start: Option<f64>,
}

impl OnsetRange {
    /// The departures from rest of `family`'s noise-free runs at the corners and the centre of
    /// its unknowns' ranges, at `rec`'s timing (the family's nominal whisker, never a randomised
    /// one). A channel counts where it leaves rest by [`DEPART_Z`] times its sensor noise
    /// `noise`; when every channel is clean, by [`CLEAN_SHARE`] of its median peak over the runs.
    pub fn of(family: &Family, rec: &Recording, noise: &[f64; 5]) -> Result<OnsetRange> {
        let timed = family.nominal().for_recording(rec)?;
        let ranges = timed.ranges();
        let corners = 1usize << ranges.len();
        let mut points: Vec<Vec<f64>> = (0..corners)
            .map(|c| {
                ranges
                    .iter()
                    .enumerate()
                    .map(|(u, r)| r[(c >> u) & 1])
                    .collect()
            })
            .collect();
        points.push(ranges.iter().map(|r| 0.5 * (r[0] + r[1])).collect());
        let runs = points
            .iter()
            .map(|p| timed.simulate(p, &Noise::NONE, 0).map(|s| s.series))
            .collect::<Result<Vec<_>>>()?;
        let present = |c: usize| !rec.values[c].is_empty();
        let thresholds: [f64; 5] = if noise.iter().any(|&s| s > 0.0) {
            std::array::from_fn(|c| if present(c) { DEPART_Z * noise[c] } else { 0.0 })
        } else {
            std::array::from_fn(|c| {
                let mut peaks: Vec<f64> = runs.iter().map(|r| peak_deviation(&r[c])).collect();
                peaks.sort_by(f64::total_cmp);
                if present(c) {
                    CLEAN_SHARE * peaks[peaks.len() / 2]
                } else {
                    0.0
                }
            })
        };
        let onsets: Vec<usize> = runs
            .iter()
            .filter_map(|r| departure(r, &thresholds))
            .collect();
        let latest_start = runs
            .iter()
            .filter_map(|r| contact_start(r.get(THETA12)?))
            .reduce(f64::max)
            .filter(|_| present(THETA12));
        Ok(OnsetRange {
            timing: (rec.rate, rec.t.len(), *noise),
            thresholds,
            earliest: onsets.iter().copied().min().unwrap_or(0),
            latest: onsets.iter().copied().max().unwrap_or(0),
            latest_start,
        })
    }

    /// Whether this range was found for `rec`'s timing and `noise`.
    pub fn fits(&self, rec: &Recording, noise: &[f64; 5]) -> bool {
        (self.timing.0 - rec.rate).abs() <= 1e-9 * rec.rate
            && self.timing.1 == rec.t.len()
            && self.timing.2 == *noise
    }
}

/// A recording's evident lead-in, in samples: when it leaves rest later than every run of the
/// scenario does (by more than [`ONSET_SLACK`] and [`SLACK_SHARE`] of the latest), the most
/// samples of rest it can start with (its departure less the scenario's earliest); `None`
/// otherwise, when it never leaves rest, or when no channel stands clear of the noise
/// ([`CLEAR_PEAK`]). Capped at [`MAX_LEAD_SHARE`] of the recording.
///
/// A recording that moves already within the rest that such a lead-in would leave
/// ([`moves_within`] over the span, or over its departure less the scenario's latest where that
/// is longer) has no evident lead-in, however late it crosses the departure threshold: a whisker
/// softer or thinner near its tip than the scenario's rises slowly through the noise after a
/// strike near the tip (a whisker tapered to 28 µm in a soft follicle, struck 2.7 mm from its tip
/// at 0.46 m/s, crossed it 45 ms in where the scenario's latest run did at 10 ms), and its rise
/// begins at the approach all the same.
pub fn evident_lead(range: &OnsetRange, rec: &Recording) -> Option<usize> {
    let clear = rec
        .values
        .iter()
        .zip(&range.thresholds)
        .any(|(x, &thr)| stands_clear(x, thr));
    if !clear {
        return None;
    }
    let onset = departure(&rec.values, &range.thresholds)?;
    let slack = ((ONSET_SLACK * rec.rate).ceil() as usize).max(MIN_SLACK_SAMPLES)
        + (SLACK_SHARE * range.latest as f64).ceil() as usize;
    let span = range.latest + slack;
    // The rest that any lead-in explaining this departure leaves: the recording's first
    // `onset - latest` samples at least (all of the span where that is longer).
    let rest = span.max(onset.saturating_sub(range.latest));
    (onset > span && !moves_within(&rec.values, &range.thresholds, rest)).then(|| {
        (onset - range.earliest).min((MAX_LEAD_SHARE * rec.t.len() as f64).floor() as usize)
    })
}

/// Whether a channel `x` with departure threshold `thr` (0: not looked at) rises at least
/// [`CLEAR_PEAK`] times above it.
fn stands_clear(x: &[f64], thr: f64) -> bool {
    thr > 0.0 && !x.is_empty() && peak_deviation(x) >= CLEAR_PEAK * thr
}

/// How much later `rec`'s contact starts than any run of `range`'s scenario, in samples: the
/// [`contact_start`] of its theta12 (the joint angle next to the base, which the contact moves
/// from its first instant) less the latest of the runs'. `None` where theta12 does not stand
/// clear of the noise ([`stands_clear`]).
fn late_start(range: &OnsetRange, rec: &Recording) -> Option<f64> {
    let latest = range.latest_start?;
    let x = &rec.values[THETA12];
    stands_clear(x, range.thresholds[THETA12])
        .then(|| contact_start(x))
        .flatten()
        .map(|start| start - latest)
}

/// Fewest recordings of one timing whose contact starts [`batch_leads`] weighs together.
pub const BATCH_STARTS: usize = 5;

/// Whether `series` moves within its first `last + 1` samples: the least-squares slope of each
/// channel with a threshold above 0, over those samples, divided by its standard error for
/// white noise of standard deviation `threshold / DEPART_Z` (the sensor noise where the
/// thresholds come from it), squared and summed over the channels, exceeds the chi-square
/// quantile of [`MOTION_P`] for that many channels. A slope, not a deviation from the first
/// sample: it needs no baseline (the first sample is as noisy as the rest) and gathers a slow
/// drift of a few noise deviations over tens of samples that no single sample shows.
pub fn moves_within(series: &[Vec<f64>], thresholds: &[f64; 5], last: usize) -> bool {
    let mut chi2 = 0.0;
    let mut channels = 0usize;
    for (x, &thr) in series.iter().zip(thresholds) {
        let m = x.len().min(last + 1);
        if thr <= 0.0 || m < 3 {
            continue;
        }
        let sigma = thr / DEPART_Z;
        let centre = (m - 1) as f64 / 2.0;
        let mean = x[..m].iter().sum::<f64>() / m as f64;
        let (mut sxy, mut sxx) = (0.0, 0.0);
        for (k, v) in x[..m].iter().enumerate() {
            let dt = k as f64 - centre;
            sxy += dt * (v - mean);
            sxx += dt * dt;
        }
        // slope = sxy / sxx, its standard error sigma / sqrt(sxx).
        let z = sxy / (sigma * sxx.sqrt());
        if z.is_finite() {
            chi2 += z * z;
            channels += 1;
        }
    }
    channels > 0 && chi2 > MOTION_CHI2[channels.min(MOTION_CHI2.len()) - 1]
}

/// Per recording, the lead-in (samples of rest before the approach) that a method should allow:
/// `max_delay` (s, in [0, 1]) for every recording when it is above 0; otherwise the lead-in
/// that the batch's recordings of its timing show ([`evident_lead`] through each one's sensor
/// noise `noise`, estimated from the recording for the channels where it is 0; a warning to
/// `warn` for each): the largest of them, for every recording of that timing (a short lead-in does not
/// show, and they train once), and 0 when none shows one. `names` name the recordings in
/// messages.
///
/// When none shows one alone, [`BATCH_STARTS`] or more recordings of one timing are weighed
/// together: if the median of their [`contact_start`]s (those whose theta12 stands clear of the
/// noise) is later than the latest of the scenario's runs, most of the batch met the object
/// later than the scenario can, and every recording of that timing is read as possibly starting
/// early, up to the longest departure from rest among them less the scenario's earliest (one
/// warning for the batch).
pub fn batch_leads(
    max_delay: f64,
    family: &Family,
    names: &[String],
    recordings: &[Recording],
    noise: &[[f64; 5]],
    warn: &mut dyn FnMut(String),
) -> Result<Vec<usize>> {
    if !(max_delay.is_finite() && (0.0..=1.0).contains(&max_delay)) {
        return Err(Error::Setting(format!(
            "max_delay: expected a lead-in between 0 and 1 s, got {max_delay}"
        )));
    }
    if max_delay > 0.0 {
        return Ok(recordings
            .iter()
            .map(|r| (max_delay * r.rate - 1e-6).ceil().max(1.0) as usize)
            .collect());
    }
    let mut ranges: Vec<OnsetRange> = Vec::new();
    let mut evident = Vec::with_capacity(recordings.len());
    let mut range_of = Vec::with_capacity(recordings.len());
    for ((name, rec), given) in names.iter().zip(recordings).zip(noise) {
        // Every channel the recording holds is looked at: one alone (theta12 of another chain)
        // may rise later than the scenario's through the same noise.
        let mut level = *given;
        for (c, sigma) in level.iter_mut().enumerate() {
            if *sigma == 0.0 && !rec.values[c].is_empty() {
                *sigma = crate::noise::estimate(&rec.values, &[c]).map_or(0.0, |l| l[c]);
            }
        }
        let level = &level;
        let k = match ranges.iter().position(|r| r.fits(rec, level)) {
            Some(k) => k,
            None => {
                ranges.push(OnsetRange::of(family, rec, level)?);
                ranges.len() - 1
            }
        };
        let range = &ranges[k];
        let lead = evident_lead(range, rec);
        if let Some(lead) = lead {
            let ms = |samples: usize| samples as f64 / rec.rate * 1e3;
            warn(format!(
                "`{name}`: the whisker leaves rest {:.1} ms into the recording, later than in any \
                 run of the scenario (by {:.1} ms, seen through the same noise): it seems to start before the approach, so \
                 it is read as starting up to {:.1} ms before it (say so with a maximum delay, \
                 --max-delay SECONDS; the time to contact then tells nothing)",
                ms(lead + range.earliest),
                ms(range.latest),
                ms(lead)
            ));
        }
        evident.push(lead);
        range_of.push(k);
    }
    let same_timing = |a: &Recording, b: &Recording| {
        (a.rate - b.rate).abs() <= 1e-9 * a.rate && a.t.len() == b.t.len()
    };
    // A batch whose contacts begin later than any run's: each lead-in may be too short to show
    // alone, but most of the batch cannot be that late without one.
    let mut judged = vec![false; recordings.len()];
    for i in 0..recordings.len() {
        if judged[i] {
            continue;
        }
        let group: Vec<usize> = (0..recordings.len())
            .filter(|&j| same_timing(&recordings[i], &recordings[j]))
            .collect();
        for &j in &group {
            judged[j] = true;
        }
        if group.iter().any(|&j| evident[j].is_some()) {
            continue;
        }
        let mut late: Vec<f64> = group
            .iter()
            .filter_map(|&j| late_start(&ranges[range_of[j]], &recordings[j]))
            .collect();
        if late.len() < BATCH_STARTS {
            continue;
        }
        late.sort_by(f64::total_cmp);
        let median = 0.5 * (late[(late.len() - 1) / 2] + late[late.len() / 2]);
        if median <= 0.0 {
            continue;
        }
        let rec = &recordings[i];
        let cap = (MAX_LEAD_SHARE * rec.t.len() as f64).floor() as usize;
        let mut longest = 0;
        for &j in &group {
            let range = &ranges[range_of[j]];
            if let Some(onset) = departure(&recordings[j].values, &range.thresholds) {
                let lead = onset.saturating_sub(range.earliest).clamp(1, cap);
                evident[j] = Some(lead);
                longest = longest.max(lead);
            }
        }
        let ms = |samples: f64| samples / rec.rate * 1e3;
        warn(format!(
            "{} recordings: their contacts begin later than in any run of the scenario (by \
             {:.1} ms, the median over the {} whose strikes stand clear of the noise, each \
             strike's rise extended back): they seem to start before the approach, so each is \
             read as starting up to {:.1} ms before it (say so with a maximum delay, \
             --max-delay SECONDS; the time to contact then tells nothing)",
            group.len(),
            ms(median),
            late.len(),
            ms(longest as f64)
        ));
    }
    // Recordings of one timing come from one rig and protocol: when one shows a lead-in, each
    // may have one (a short one does not show), so all are read alike.
    Ok(recordings
        .iter()
        .map(|rec| {
            recordings
                .iter()
                .zip(&evident)
                .filter(|(other, _)| same_timing(rec, other))
                .filter_map(|(_, l)| *l)
                .max()
                .unwrap_or(0)
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_onset_ignores_one_spike_and_a_constant_offset() {
        let mut x = vec![0.3; 40];
        x[5] = 0.9; // one spike
        for (k, v) in x.iter_mut().enumerate().skip(20) {
            *v = 0.3 + 0.05 * (k - 19) as f64;
        }
        assert_eq!(contact_onset(&x, 0.12), Some(22));
        assert_eq!(contact_onset(&[0.3; 10], 0.1), None);
        assert_eq!(contact_onset(&[], 0.1), None);
        // Deviations 0.1 then 0.15 about the crossing at 0.12: two fifths of the way.
        assert!((onset_time(&x, 0.12).unwrap() - 21.4).abs() < 1e-9);
    }

    /// Five channels of `n` samples: white noise of standard deviation 1 about `signal(k)`.
    fn noisy(n: usize, seed: u64, signal: impl Fn(usize) -> f64) -> Recording {
        let mut rng = vibrissa_core::rng::Rng::new(seed);
        let values = (0..5)
            .map(|_| (0..n).map(|k| signal(k) + rng.normal()).collect())
            .collect();
        Recording {
            t: (0..n).map(|k| k as f64 * 1e-3).collect(),
            values,
            rate: 1000.0,
            segments: None,
        }
    }

    /// A scenario whose runs leave rest within 2–10 samples of unit noise at 1 kHz.
    fn unit_range() -> OnsetRange {
        OnsetRange {
            timing: (1000.0, 100, [1.0; 5]),
            thresholds: [DEPART_Z; 5],
            earliest: 2,
            latest: 10,
            latest_start: None,
        }
    }

    #[test]
    fn a_slow_rise_from_the_start_is_no_lead_in_and_rest_then_a_strike_is() {
        // The scenario's runs leave rest within 2–10 samples: the span looked at is 10 + 4 + 10.
        let range = unit_range();
        let (mut slow, mut beyond, mut late, mut rest) = (0, 0, 0, 0);
        for seed in 0..20 {
            // A drift of 0.12 noise deviations per sample from sample 3: beyond the threshold
            // (5) mostly after the span, yet moving from the start.
            let drift = noisy(100, seed, |k| 0.12 * k.saturating_sub(3) as f64);
            beyond += (departure(&drift.values, &range.thresholds).unwrap() > 24) as usize;
            slow += evident_lead(&range, &drift).is_some() as usize;
            // Rest for 40 samples, then a strike that rises by 3 noise deviations per sample.
            let strike = noisy(100, seed, |k| 3.0 * k.saturating_sub(40) as f64);
            late += evident_lead(&range, &strike).is_some() as usize;
            rest += moves_within(&strike.values, &range.thresholds, 24) as usize;
        }
        assert!(
            beyond >= 15,
            "{beyond} of 20 drifts cross the threshold after the span"
        );
        assert_eq!(slow, 0, "a slow rise read as a lead-in");
        assert_eq!(late, 20, "rest then a strike not read as a lead-in");
        assert_eq!(rest, 0, "rest read as motion");
        // A channel without a threshold is not looked at; none at all: no motion.
        let drift = noisy(100, 1, |k| 0.1 * k as f64);
        assert!(moves_within(
            &drift.values,
            &[0.0, 0.0, DEPART_Z, 0.0, 0.0],
            24
        ));
        assert!(!moves_within(&drift.values, &[0.0; 5], 24));
    }

    #[test]
    fn a_contact_starts_where_its_rise_extended_back_meets_rest() {
        // Rest at 0.3, then a rise of 0.05 per sample from sample 19 to a peak at sample 40.
        let x: Vec<f64> = (0..60)
            .map(|k| 0.3 + 0.05 * (k.min(40) as f64 - 19.0).max(0.0))
            .collect();
        let start = contact_start(&x).unwrap();
        assert!((start - 19.0).abs() < 1e-9, "{start}");
        assert_eq!(contact_start(&[0.3; 10]), None);
    }

    #[test]
    fn a_strike_that_barely_clears_the_noise_tells_no_lead_in() {
        let range = unit_range();
        // Rest for 40 samples, then a step to 1.5 thresholds on every channel: late, but weak.
        let step = |height: f64| Recording {
            t: (0..100).map(|k| k as f64 * 1e-3).collect(),
            values: vec![
                (0..100)
                    .map(|k| if k >= 40 { height } else { 0.0 })
                    .collect();
                5
            ],
            rate: 1000.0,
            segments: None,
        };
        assert_eq!(evident_lead(&range, &step(1.5 * DEPART_Z)), None);
        assert_eq!(evident_lead(&range, &step(4.0 * DEPART_Z)), Some(38));
    }

    /// Eight `e2` strikes with sensor noise of 3% of each channel's range and the `noisy`
    /// variant's random forces, each recorded from `lead(k)` seconds before its approach and
    /// cut to one length.
    fn e2_batch(lead: impl Fn(usize) -> f64) -> Vec<Recording> {
        let e2 = Family::builtin("e2").unwrap();
        let mut noise = e2.noise(crate::experiment::Variant::Noisy).unwrap();
        noise.sensor = noise
            .sensor
            .map(|s| s * 0.03 / crate::experiment::SENSOR_NOISE_FRACTION);
        let runs: Vec<Vec<Vec<f64>>> = (0..8)
            .map(|k| {
                let p = [0.016 + 0.0018 * k as f64, 0.4 + 0.15 * k as f64];
                e2.simulate_delayed(&p, lead(k), &noise, k as u64)
                    .unwrap()
                    .series
            })
            .collect();
        let n = runs.iter().map(|r| r[0].len()).min().unwrap();
        runs.into_iter()
            .map(|r| Recording {
                t: (0..n).map(|k| k as f64 * 1e-3).collect(),
                values: r.into_iter().map(|c| c[..n].to_vec()).collect(),
                rate: 1000.0,
                segments: None,
            })
            .collect()
    }

    #[test]
    fn a_batch_whose_contacts_begin_late_is_read_as_starting_early() {
        let e2 = Family::builtin("e2").unwrap();
        let names: Vec<String> = (0..8).map(|k| format!("r{k}")).collect();
        let leads = |recs: &[Recording]| {
            let mut said = Vec::new();
            let l = batch_leads(0.0, &e2, &names, recs, &[[0.0; 5]; 8], &mut |w| {
                said.push(w)
            })
            .unwrap();
            (l, said)
        };
        // From the approach: no lead-in.
        let (l, said) = leads(&e2_batch(|_| 0.0));
        assert!(
            l.iter().all(|&x| x == 0) && said.is_empty(),
            "{l:?} {said:?}"
        );
        // 3–10 ms of rest first: too short to show alone, plain in the batch.
        let (l, said) = leads(&e2_batch(|k| 0.003 + 0.001 * k as f64));
        assert_eq!(said.len(), 1, "{said:?}");
        assert!(
            said[0].contains("8 recordings: their contacts"),
            "{}",
            said[0]
        );
        assert!(l.iter().all(|&x| x >= 10 && x == l[0]), "{l:?}");
    }

    #[test]
    fn rest_seldom_reads_as_motion() {
        // The veto's false alarms on pure noise: about MOTION_P of recordings.
        let thresholds = [DEPART_Z; 5];
        let hits = (0..2000)
            .filter(|&seed| moves_within(&noisy(40, seed, |_| 0.0).values, &thresholds, 30))
            .count();
        assert!(hits <= 8, "{hits} of 2000");
    }

    #[test]
    fn alignment_moves_the_onset_and_pads_with_the_ends() {
        let s = vec![vec![1.0, 2.0, 3.0, 4.0, 5.0], Vec::new()];
        // Onset 1 to sample 3: two samples of the first value in front.
        assert_eq!(align(&s, 1.0, 3, 5)[0], vec![1.0, 1.0, 1.0, 2.0, 3.0]);
        // Onset 3 to sample 1: the start dropped, the last value repeated.
        assert_eq!(align(&s, 3.0, 1, 5)[0], vec![3.0, 4.0, 5.0, 5.0, 5.0]);
        assert!(align(&s, 3.0, 1, 5)[1].is_empty());
        // Between samples: interpolated.
        assert_eq!(align(&s, 1.5, 1, 3)[0], vec![1.5, 2.5, 3.5]);
        // A series and the same with a lead-in of rest align alike.
        let late = vec![vec![1.0, 1.0, 1.0, 1.0, 2.0, 3.0, 4.0, 5.0]];
        assert_eq!(align(&late, 4.0, 2, 5)[0], align(&s, 1.0, 2, 5)[0]);
    }
}
