//! Sensor noise estimated from the recordings themselves.
//!
//! A recording's sensor noise is measured by what a local polynomial cannot follow: every sample
//! is compared with the least-squares quintic through the seven samples centred on it (a
//! Savitzky–Golay smooth; its residual is the sixth difference of the samples, scaled), and the
//! residuals' scale is found robustly.
//!
//! - A quintic over 7 samples follows the whisker's own ringing (51 Hz in the first mode for
//!   `w30`) to a small fraction of a realistic noise level at 500 Hz and above. The cubic over
//!   the same 7 samples, used before, does so at 1 kHz (about 2% of a 3% noise level on clean
//!   `e2` strikes) but not at 500 Hz, where a window spans 12 ms, two thirds of a period: on
//!   strikes of a stand-in whisker at 500 Hz with 3% noise it read the noise 16–33% high per
//!   channel, the quintic 1–11%. A second difference reads 5–15% of a 3% level even at 1 kHz.
//! - Contact events and impacts make a few large residuals in a cluster. The scale starts from
//!   the median absolute residual, then every residual beyond [`TRIM`] standard deviations is
//!   dropped together with its neighbours within the smooth's half-width (a step in the signal
//!   spreads over the whole window), and the standard deviation is re-estimated from the rest
//!   with the normal distribution's truncation corrected for, a few times.
//! - Each residual of white noise of standard deviation σ has the standard deviation
//!   σ·√(1 − w₀), w₀ being the smooth's centre weight; the residuals are scaled by it, so the
//!   estimate is σ itself.
//!
//! Windows that hold a missing (`NaN`) value are skipped. A channel with fewer than
//! [`MIN_RESIDUALS`] complete windows is refused ([`Error::Observation`], naming the channel);
//! a channel that no quintic misses at all (constant, or exactly polynomial) has noise 0, and
//! one that the quintic misses in fewer than half of its windows (long constant stretches, a
//! coarsely quantised sensor) the root mean square of its residuals.
//!
//! Several recordings of one rig give one estimate by pooling their residuals
//! ([`estimate_pooled`]); [`batch_levels`] decides which recordings of a batch agree well enough
//! to share it, and [`quantise`] rounds a level so that estimators trained at one level can be
//! reused for recordings whose estimates differ by less than the estimate's own scatter.

use crate::error::{Error, Result};
use crate::experiment::CHANNELS;
use serde::Serialize;

/// Half-width of the smoothing window, samples (the window is 7 samples).
pub const HALF_WIDTH: usize = 3;
/// Residuals beyond this many standard deviations are treated as signal, not noise.
pub const TRIM: f64 = 3.0;
/// Complete windows a channel needs for its noise to be estimated.
pub const MIN_RESIDUALS: usize = 30;
/// A recording whose estimate exceeds its batch's pooled one by more than this factor on some
/// channel, falls below it by more than this factor on every channel, or by more than its square
/// on some channel, is given its own level ([`batch_levels`]).
pub const AGREEMENT: f64 = 1.5;
/// The samples of a recording whose own estimate scatters by about 12%, for which [`AGREEMENT`]
/// was set: an `e2` strike at 1 kHz. Shorter recordings scatter more ([`agreement_factor`]).
pub const AGREEMENT_SAMPLES: usize = 151;
/// Levels are rounded to powers of 2^(1/`STEPS_PER_OCTAVE`) ([`quantise`]): at most 4.4% off.
pub const STEPS_PER_OCTAVE: f64 = 8.0;

/// Refinement passes of the trimmed standard deviation.
const PASSES: usize = 5;
/// The median absolute deviation of a standard normal variable.
const MAD_NORMAL: f64 = 0.674_489_750_196_081_7;

/// What the least-squares quintic through 7 equally spaced samples leaves at the centre sample
/// (Savitzky–Golay): the residual `x₀ − Σ wⱼ xⱼ` is orthogonal to every polynomial of degree
/// five or less over the window, so it is proportional to the window's sixth difference, with
/// these binomial coefficients; the centre weight is `w₀ = 1 − 20²/924`.
const SIXTH_DIFFERENCE: [f64; 2 * HALF_WIDTH + 1] = [1.0, -6.0, 15.0, -20.0, 15.0, -6.0, 1.0];

/// Residuals of one series against its local quintic, scaled so that white noise of standard
/// deviation σ gives residuals of standard deviation σ; one per complete (all-finite) window.
/// Each residual is paired with the index of its window's centre, so that neighbours can be
/// found.
fn residuals(x: &[f64]) -> Vec<(usize, f64)> {
    // White noise σ gives a sixth difference of standard deviation σ·√Σcⱼ² = σ·√924.
    let scale = 1.0 / SIXTH_DIFFERENCE.iter().map(|c| c * c).sum::<f64>().sqrt();
    x.windows(SIXTH_DIFFERENCE.len())
        .enumerate()
        .filter(|(_, w)| w.iter().all(|v| v.is_finite()))
        .map(|(k, w)| {
            // x₀ minus the smooth is −(5/231)·Σ cⱼ (xⱼ − x₀); as the coefficients sum to 0, it is
            // exactly 0 where the window is constant.
            let centre = w[HALF_WIDTH];
            let r: f64 = w
                .iter()
                .zip(&SIXTH_DIFFERENCE)
                .map(|(a, c)| c * (a - centre))
                .sum();
            (k + HALF_WIDTH, -scale * r)
        })
        .collect()
}

/// The robust standard deviation of residual sets (one per recording; neighbours are looked for
/// only within a set).
fn robust_sigma(sets: &[Vec<(usize, f64)>]) -> f64 {
    let all: Vec<f64> = sets.iter().flatten().map(|(_, r)| r.abs()).collect();
    if all.is_empty() {
        return 0.0;
    }
    let mut sorted = all.clone();
    let mid = sorted.len() / 2;
    let (_, m, _) = sorted.select_nth_unstable_by(mid, f64::total_cmp);
    let mut sigma = *m / MAD_NORMAL;
    if sigma == 0.0 {
        // More than half the windows fit exactly (constant stretches, a coarsely quantised
        // sensor): the root mean square of all residuals, which is 0 only if all are. Trimming
        // would take every step of a quantised sensor for an event and leave nothing.
        return (all.iter().map(|r| r * r).sum::<f64>() / all.len() as f64).sqrt();
    }
    // Variance of a standard normal variable truncated to ±TRIM.
    let density = (-0.5 * TRIM * TRIM).exp() / (2.0 * std::f64::consts::PI).sqrt();
    let inside = 1.0 - 2.0 * normal_tail(TRIM);
    let truncated = 1.0 - 2.0 * TRIM * density / inside;
    for _ in 0..PASSES {
        let (mut sum, mut n) = (0.0, 0usize);
        for set in sets {
            let far: Vec<usize> = set
                .iter()
                .filter(|(_, r)| r.abs() > TRIM * sigma)
                .map(|(k, _)| *k)
                .collect();
            for (k, r) in set {
                if far.iter().all(|f| f.abs_diff(*k) > HALF_WIDTH) {
                    sum += r * r;
                    n += 1;
                }
            }
        }
        if n == 0 {
            break;
        }
        sigma = (sum / n as f64 / truncated).sqrt();
    }
    sigma
}

/// Upper tail probability of the standard normal distribution, P(Z > z), for z ≥ 0 (to about
/// 1e-7, Abramowitz and Stegun 26.2.17).
fn normal_tail(z: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.231_641_9 * z);
    let poly = t
        * (0.319_381_530
            + t * (-0.356_563_782
                + t * (1.781_477_937 + t * (-1.821_255_978 + t * 1.330_274_429))));
    (-0.5 * z * z).exp() / (2.0 * std::f64::consts::PI).sqrt() * poly
}

/// Chance at which white noise alone, over a whole recording, varies as much as a recording that
/// [`shows_signal`] counts as moving.
pub const NO_SIGNAL_CHANCE: f64 = 1e-3;

/// Whether `rec` shows anything beyond its sensor noise `level` on the channels `needs`: the sum
/// over those channels of each sample's squared deviation from the channel's mean, in units of
/// its noise variance, exceeds what white noise of those levels gives with a chance of
/// [`NO_SIGNAL_CHANCE`] (a χ² with one degree of freedom per sample and channel, less one per
/// channel; its quantile by Wilson and Hilferty's cube). A strike adds the energy of its whole
/// bend, where one sample's extreme would be lost in the noise. `None` when no channel of
/// `needs` has a noise level above 0 to compare with. A recording that shows nothing holds no
/// strike the estimators can read: the object missed the whisker or stayed beyond its reach.
pub fn shows_signal(
    rec: &crate::recording::Recording,
    level: &[f64; 5],
    needs: &[usize],
) -> Option<bool> {
    let mut chi2 = 0.0;
    let mut dof = 0usize;
    for &c in needs {
        let sigma = level[c];
        let x: Vec<f64> = rec.values[c]
            .iter()
            .copied()
            .filter(|v| v.is_finite())
            .collect();
        if !(sigma > 0.0 && sigma.is_finite()) || x.len() < 2 {
            continue;
        }
        let mean = x.iter().sum::<f64>() / x.len() as f64;
        chi2 += x.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (sigma * sigma);
        dof += x.len() - 1;
    }
    if dof == 0 {
        return None;
    }
    let k = dof as f64;
    let z = crate::evaluate::normal_quantile(1.0 - NO_SIGNAL_CHANCE);
    let w = 2.0 / (9.0 * k);
    let quantile = k * (1.0 - w + z * w.sqrt()).powi(3);
    Some(chi2 > quantile)
}

/// The sensor noise (standard deviation, in the series' unit) of one channel of several
/// recordings of one rig, `name` naming the channel in errors.
pub fn channel_sigma(name: &str, series: &[&[f64]]) -> Result<f64> {
    let sets: Vec<Vec<(usize, f64)>> = series.iter().map(|x| residuals(x)).collect();
    let n: usize = sets.iter().map(Vec::len).sum();
    if n < MIN_RESIDUALS {
        let samples: usize = series.iter().map(|x| x.len()).sum();
        return Err(Error::Observation(format!(
            "channel {name}: too few samples to estimate its noise ({samples} samples give {n} \
             complete windows of {}; at least {MIN_RESIDUALS} are needed)",
            SIXTH_DIFFERENCE.len()
        )));
    }
    Ok(robust_sigma(&sets))
}

/// The sensor noise of `channels` (indices into [`CHANNELS`]) of one recording, channel-major
/// `[CHANNELS][samples]`; channels not asked for are 0.
pub fn estimate(series: &[Vec<f64>], channels: &[usize]) -> Result<[f64; 5]> {
    estimate_pooled(&[series], channels)
}

/// The sensor noise of `channels` of several recordings of one rig, their residuals pooled;
/// channels not asked for are 0. A recording that lacks a channel (an empty series) adds
/// nothing to it.
pub fn estimate_pooled(recordings: &[&[Vec<f64>]], channels: &[usize]) -> Result<[f64; 5]> {
    let mut out = [0.0; 5];
    for &c in channels {
        let series: Vec<&[f64]> = recordings
            .iter()
            .filter_map(|r| r.get(c))
            .map(|x| x.as_slice())
            .collect();
        out[c] = channel_sigma(CHANNELS[c], &series)?;
    }
    Ok(out)
}

/// `sigma` rounded to the nearest power of 2^(1/[`STEPS_PER_OCTAVE`]) (0 stays 0).
pub fn quantise(sigma: f64) -> f64 {
    if !(sigma > 0.0 && sigma.is_finite()) {
        return 0.0;
    }
    ((sigma.log2() * STEPS_PER_OCTAVE).round() / STEPS_PER_OCTAVE).exp2()
}

/// Where a recording's noise level came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Source {
    /// Estimated from the batch's recordings that agree with each other, pooled.
    Batch,
    /// Estimated from this recording alone (it disagrees with the rest of its batch).
    Own,
}

/// The noise levels of a batch of recordings.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BatchNoise {
    /// Per recording: the sensor noise per channel of [`CHANNELS`], SI, quantised (stated
    /// channels as stated, channels neither stated nor asked for 0).
    pub levels: Vec<[f64; 5]>,
    /// Per recording: where its estimated channels' levels came from.
    pub sources: Vec<Source>,
    /// Per recording: its own estimate of each asked-for channel, unquantised (stated channels
    /// as stated).
    pub own: Vec<[f64; 5]>,
    /// Per recording: the factor within which its own estimate agreed with the pooled one
    /// ([`agreement_factor`]).
    pub agreement: Vec<f64>,
}

/// The factor by which the noise estimate of a recording of `samples` samples may stray from
/// its batch's pooled estimate and still agree with it: [`AGREEMENT`] from
/// [`AGREEMENT_SAMPLES`] samples on, and for a shorter recording [`AGREEMENT`] raised to the
/// square root of the ratio of the counts, as its estimate's scatter grows (2.0 for 51 samples,
/// a 150-ms strike at 333 Hz). At 333 Hz a recording's own estimate strayed 0.3–3.7 times the
/// true noise (four stand-in whiskers, 40 strikes each, every third sample; 0.72–1.33 at 1 kHz),
/// and with [`AGREEMENT`] 37 of their 160 strikes were given their own, scattered, levels; with
/// this factor 3.
pub fn agreement_factor(samples: usize) -> f64 {
    let ratio = AGREEMENT_SAMPLES as f64 / samples.max(1) as f64;
    AGREEMENT.powf(ratio.sqrt().max(1.0))
}

/// The noise levels of a batch of recordings (channel-major `[CHANNELS][samples]` each) on the
/// channels `channels`: a channel given in `stated` is taken as stated; every other one is
/// estimated. Recordings whose own estimates agree with the batch's pooled estimate share the
/// pooled estimate of those recordings (one rig: one level, estimated from all of them); a
/// recording noisier than the pooled estimate by more than a factor ([`agreement_factor`]:
/// [`AGREEMENT`], wider for a short recording) on some channel, quieter by more than that on
/// every channel, or by more than its square on some channel keeps its own. Levels are
/// [`quantise`]d.
pub fn batch_levels(
    recordings: &[&[Vec<f64>]],
    channels: &[usize],
    stated: &[Option<f64>; 5],
) -> Result<BatchNoise> {
    let estimated: Vec<usize> = channels
        .iter()
        .copied()
        .filter(|&c| stated[c].is_none())
        .collect();
    let own = recordings
        .iter()
        .map(|r| estimate(r, &estimated))
        .collect::<Result<Vec<_>>>()?;
    // A recording's own estimate scatters about its level by about 12% (one 151-sample channel
    // of white noise), with a long tail below: one channel in 200 reads less than 1/1.5 of its
    // level, which a batch of 20 recordings of 5 channels meets more often than not. A channel
    // read quieter alone is therefore not enough to set a recording apart (nor is it the side
    // that makes intervals too narrow); a recording is its own when it is noisier on some
    // channel, quieter on every one, or far quieter on one.
    // A shorter recording's estimate scatters more: it agrees within a wider factor.
    let pooled = estimate_pooled(recordings, &estimated)?;
    let factors: Vec<f64> = recordings
        .iter()
        .map(|r| {
            let samples = estimated
                .iter()
                .filter_map(|&c| r.get(c).map(|x| x.iter().filter(|v| v.is_finite()).count()))
                .min()
                .unwrap_or(AGREEMENT_SAMPLES);
            agreement_factor(samples)
        })
        .collect();
    let agrees = |mine: &[f64; 5], pooled: &[f64; 5], f: f64| {
        let pairs = || estimated.iter().map(|&c| (mine[c], pooled[c]));
        let noisier = pairs().any(|(a, b)| a > f * b);
        let quieter = |g: f64| move |(a, b): (f64, f64)| g * a < b;
        let all_quieter = !estimated.is_empty() && pairs().all(quieter(f));
        let far_quieter = pairs().any(quieter(f * f));
        !(noisier || all_quieter || far_quieter)
    };
    let members: Vec<bool> = own
        .iter()
        .zip(&factors)
        .map(|(o, f)| agrees(o, &pooled, *f))
        .collect();
    let shared = if members.iter().filter(|m| **m).count() > 1 {
        let chosen: Vec<&[Vec<f64>]> = recordings
            .iter()
            .zip(&members)
            .filter(|(_, m)| **m)
            .map(|(r, _)| *r)
            .collect();
        Some(estimate_pooled(&chosen, &estimated)?)
    } else {
        None
    };
    let with_stated = |mut x: [f64; 5]| {
        for (c, s) in stated.iter().enumerate() {
            if let Some(s) = s {
                x[c] = *s;
            }
        }
        x
    };
    let mut levels = Vec::with_capacity(recordings.len());
    let mut sources = Vec::with_capacity(recordings.len());
    for (mine, member) in own.iter().zip(&members) {
        let (level, source) = match (&shared, member) {
            (Some(s), true) => (*s, Source::Batch),
            _ => (*mine, Source::Own),
        };
        let mut q = [0.0; 5];
        for &c in &estimated {
            q[c] = quantise(level[c]);
        }
        levels.push(with_stated(q));
        sources.push(source);
    }
    Ok(BatchNoise {
        levels,
        sources,
        own: own.into_iter().map(with_stated).collect(),
        agreement: factors,
    })
}

/// Parses a noise statement: `auto` (every channel estimated), `none` (every channel 0: clean
/// recordings) or comma-separated `CHANNEL=SIGMA` (SI, finite, ≥ 0), the channels not named
/// estimated. Returns the stated channels, `[CHANNELS]`.
pub fn parse_statement(text: &str) -> Result<[Option<f64>; 5]> {
    let text = text.trim();
    match text {
        "auto" => return Ok([None; 5]),
        "none" => return Ok([Some(0.0); 5]),
        _ => {}
    }
    let mut out = [None; 5];
    for part in text.split(',') {
        let bad = || {
            Error::Setting(format!(
                "noise `{part}`: expected `auto`, `none` or CHANNEL=SIGMA,... with CHANNEL one \
                 of {} and SIGMA a standard deviation >= 0 in SI units",
                CHANNELS.join(", ")
            ))
        };
        let (name, value) = part.split_once('=').ok_or_else(bad)?;
        let c = CHANNELS
            .iter()
            .position(|n| *n == name.trim())
            .ok_or_else(bad)?;
        let sigma: f64 = value.trim().parse().map_err(|_| bad())?;
        if !(sigma.is_finite() && sigma >= 0.0) {
            return Err(bad());
        }
        if out[c].is_some() {
            return Err(Error::Setting(format!(
                "noise: channel {} is given twice",
                CHANNELS[c]
            )));
        }
        out[c] = Some(sigma);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use vibrissa_core::rng::Rng;

    /// A damped ringing at `f` Hz sampled at 1 kHz, amplitude 1, with white noise `sigma`.
    fn ringing(n: usize, f: f64, sigma: f64, seed: u64) -> Vec<f64> {
        let mut rng = Rng::stream(seed, 1);
        (0..n)
            .map(|k| {
                let t = k as f64 * 1e-3;
                (2.0 * std::f64::consts::PI * f * t).sin() * (-3.0 * t).exp() + sigma * rng.normal()
            })
            .collect()
    }

    /// A recording of one channel `x` (theta12) at 1 kHz.
    fn one_channel(x: Vec<f64>) -> crate::recording::Recording {
        let t = (0..x.len()).map(|k| k as f64 * 1e-3).collect();
        let mut columns = vec![None; 5];
        columns[1] = Some(x);
        crate::recording::Recording::from_columns(
            "r",
            t,
            columns,
            None,
            &[1],
            crate::recording::Reader::Filter,
        )
        .unwrap()
    }

    #[test]
    fn noise_alone_shows_no_signal_and_a_bend_buried_sample_by_sample_does() {
        let sigma = 0.01;
        let mut level = [0.0; 5];
        level[1] = sigma;
        // White noise alone: counted as moving in about one recording in a thousand.
        let moving = (0..2000)
            .filter(|&seed| {
                let mut rng = Rng::stream(seed, 7);
                let x = (0..151).map(|_| sigma * rng.normal()).collect();
                shows_signal(&one_channel(x), &level, &[1]) == Some(true)
            })
            .count();
        assert!(moving <= 8, "{moving} of 2000");
        // A bend of 2.5 σ over 40 samples: no sample stands out of the noise, the whole does.
        let shown = (0..200)
            .filter(|&seed| {
                let mut rng = Rng::stream(seed, 9);
                let x = (0..151)
                    .map(|k| {
                        let bend = if (50..90).contains(&k) {
                            2.5 * sigma
                        } else {
                            0.0
                        };
                        bend + sigma * rng.normal()
                    })
                    .collect();
                shows_signal(&one_channel(x), &level, &[1]) == Some(true)
            })
            .count();
        assert_eq!(shown, 200);
        // Nothing to compare with: no noise level, or a channel not read.
        let x: Vec<f64> = (0..151).map(|k| k as f64).collect();
        assert_eq!(shows_signal(&one_channel(x.clone()), &[0.0; 5], &[1]), None);
        assert_eq!(shows_signal(&one_channel(x), &level, &[0]), None);
    }

    #[test]
    fn a_quintic_leaves_no_residual() {
        // The coefficients annihilate every polynomial of degree five or less, and their
        // residual is the quintic smooth's: the centre sample minus the least-squares quintic's
        // value there, scaled by 1/√(1 − w₀).
        assert_eq!(SIXTH_DIFFERENCE.iter().sum::<f64>(), 0.0);
        let x: Vec<f64> = (0..60)
            .map(|k| {
                let t = k as f64 / 10.0;
                0.3 - 0.2 * t + 0.05 * t * t - 0.01 * t.powi(3) + 0.002 * t.powi(4)
                    - 1e-4 * t.powi(5)
            })
            .collect();
        for (_, r) in residuals(&x) {
            assert!(r.abs() < 1e-12, "{r}");
        }
        assert!(channel_sigma("theta01", &[&x]).unwrap() < 1e-12);
        // A unit spike at a window's centre leaves the residual 1 − w₀ (the smooth keeps w₀
        // of it), scaled by 1/√(1 − w₀): √(1 − w₀), with the quintic's centre weight over 7
        // samples w₀ = 131/231 (its smoothing weights are (5, −30, 75, 131, 75, −30, 5)/231).
        let mut spike = vec![0.0; 7];
        spike[3] = 1.0;
        let w0: f64 = 131.0 / 231.0;
        let r = residuals(&spike)[0].1;
        assert!((r - (1.0 - w0).sqrt()).abs() < 1e-12, "{r}");
    }

    /// A damped ringing at `f` Hz sampled at `rate`, amplitude 1, with white noise `sigma`.
    fn ringing_at(n: usize, rate: f64, f: f64, sigma: f64, seed: u64) -> Vec<f64> {
        let mut rng = Rng::stream(seed, 1);
        (0..n)
            .map(|k| {
                let t = k as f64 / rate;
                (2.0 * std::f64::consts::PI * f * t).sin() * (-3.0 * t).exp() + sigma * rng.normal()
            })
            .collect()
    }

    #[test]
    fn ringing_sampled_at_500_hz_is_not_read_as_noise() {
        // 51 Hz sampled at 500 Hz: about ten samples a period. The noise is measured within a
        // few percent; a cubic over the same seven samples reads it a fifth high or more.
        let sigma = 0.01;
        let x = ringing_at(1000, 500.0, 51.0, sigma, 9);
        let s = channel_sigma("theta01", &[&x]).unwrap();
        assert!((s / sigma - 1.0).abs() < 0.08, "{s}");
        let cubic = [-2.0, 3.0, 6.0, 7.0, 6.0, 3.0, -2.0].map(|w: f64| w / 21.0);
        let r: Vec<f64> = x
            .windows(7)
            .map(|w| {
                (w[3] - w.iter().zip(&cubic).map(|(a, b)| a * b).sum::<f64>())
                    / (1.0 - 7.0 / 21.0f64).sqrt()
            })
            .collect();
        let mut abs: Vec<f64> = r.iter().map(|v| v.abs()).collect();
        abs.sort_by(f64::total_cmp);
        let cubic_mad = abs[abs.len() / 2] / MAD_NORMAL;
        assert!(cubic_mad > 1.15 * s, "{cubic_mad} vs {s}");
    }

    #[test]
    fn white_noise_on_a_ringing_signal_is_measured() {
        for sigma in [0.01, 0.03, 0.1] {
            let x = ringing(4000, 51.0, sigma, 7);
            let s = channel_sigma("theta12", &[&x]).unwrap();
            assert!((s / sigma - 1.0).abs() < 0.06, "{s} for {sigma}");
        }
        // Without noise, the ringing itself reads as far less than any of those levels, where
        // the second difference reads it as much more.
        let clean = ringing(4000, 51.0, 0.0, 7);
        let s = channel_sigma("theta12", &[&clean]).unwrap();
        assert!(s < 2e-3, "{s}");
        let d2 = crate::pf::noise_from_series(&[&[clean.clone()][..]])[0];
        assert!(d2 > 5.0 * s, "{d2} vs {s}");
    }

    #[test]
    fn steps_and_spikes_do_not_inflate_the_estimate() {
        let mut x = ringing(300, 51.0, 0.02, 3);
        // Contact events: steps and an impact.
        for v in x.iter_mut().skip(80) {
            *v += 0.8;
        }
        for v in x.iter_mut().skip(200) {
            *v -= 0.5;
        }
        x[150] += 1.5;
        x[151] -= 0.7;
        let s = channel_sigma("m0", &[&x]).unwrap();
        assert!((s / 0.02 - 1.0).abs() < 0.15, "{s}");
    }

    #[test]
    fn missing_values_are_skipped_and_short_channels_refused() {
        let mut x = ringing(400, 51.0, 0.05, 5);
        x[100] = f64::NAN;
        x[250] = f64::NAN;
        let s = channel_sigma("fx", &[&x]).unwrap();
        assert!(s.is_finite() && (s / 0.05 - 1.0).abs() < 0.2, "{s}");
        let short = ringing(20, 51.0, 0.05, 5);
        let e = channel_sigma("fy", &[&short]).unwrap_err().to_string();
        assert!(e.contains("fy") && e.contains("20 samples"), "{e}");
        let gaps = vec![f64::NAN; 400];
        assert!(channel_sigma("fy", &[&gaps]).is_err());
    }

    #[test]
    fn a_constant_or_coarsely_quantised_channel_is_not_nan() {
        let flat = vec![0.25; 200];
        assert_eq!(channel_sigma("m0", &[&flat]).unwrap(), 0.0);
        // Quantised to steps that most windows do not see.
        let q: Vec<f64> = (0..400)
            .map(|k| ((k as f64) / 37.0).floor() * 1e-3)
            .collect();
        let s = channel_sigma("m0", &[&q]).unwrap();
        assert!(s.is_finite() && s > 0.0 && s < 1e-3, "{s}");
    }

    #[test]
    fn quantised_levels_are_close_and_shared() {
        for x in [1e-7, 3.3e-3, 0.7, 12.0] {
            let q = quantise(x);
            assert!((q / x - 1.0).abs() <= 0.045, "{q} for {x}");
            assert_eq!(quantise(q), q);
        }
        assert_eq!(quantise(1.0e-3), quantise(1.01e-3));
        assert_eq!(quantise(0.0), 0.0);
        assert_eq!(quantise(f64::NAN), 0.0);
    }

    #[test]
    fn a_batch_shares_one_level_and_sets_apart_the_odd_recording() {
        let runs: Vec<Vec<Vec<f64>>> = (0..6)
            .map(|k| {
                let sigma = if k == 5 { 0.2 } else { 0.03 };
                vec![
                    ringing(151, 51.0, sigma, 10 + k),
                    ringing(151, 40.0, 0.01, 20 + k),
                ]
            })
            .collect();
        let refs: Vec<&[Vec<f64>]> = runs.iter().map(|r| &r[..]).collect();
        let b = batch_levels(&refs, &[0, 1], &[None; 5]).unwrap();
        for k in 0..5 {
            assert_eq!(b.sources[k], Source::Batch);
            assert_eq!(b.levels[k], b.levels[0]);
        }
        assert!(
            (b.levels[0][0] / 0.03 - 1.0).abs() < 0.12,
            "{:?}",
            b.levels[0]
        );
        assert_eq!(b.sources[5], Source::Own);
        assert!(
            (b.levels[5][0] / 0.2 - 1.0).abs() < 0.25,
            "{:?}",
            b.levels[5]
        );
        // Stated channels are taken as stated.
        let stated = [None, Some(0.5), None, None, None];
        let b = batch_levels(&refs, &[0, 1], &stated).unwrap();
        assert!(b.levels.iter().all(|l| l[1] == 0.5));
    }

    #[test]
    fn a_recording_quieter_on_one_channel_alone_stays_with_its_batch() {
        // Recording 5's first channel is 0.53 times as noisy as the rest (about as far as a single
        // recording's estimate strays by chance); recording 6 is half as noisy on both
        // channels, recording 7 a third as noisy on its second channel only.
        let sigmas = |k: u64| match k {
            5 => [0.016, 0.01],
            6 => [0.015, 0.005],
            7 => [0.03, 0.0033],
            _ => [0.03, 0.01],
        };
        let runs: Vec<Vec<Vec<f64>>> = (0..8)
            .map(|k| {
                let [s0, s1] = sigmas(k);
                vec![
                    ringing(151, 51.0, s0, 10 + k),
                    ringing(151, 40.0, s1, 20 + k),
                ]
            })
            .collect();
        let refs: Vec<&[Vec<f64>]> = runs.iter().map(|r| &r[..]).collect();
        let b = batch_levels(&refs, &[0, 1], &[None; 5]).unwrap();
        for k in 0..6 {
            assert_eq!(b.sources[k], Source::Batch, "recording {k}: {:?}", b.own[k]);
        }
        assert_eq!(b.sources[6], Source::Own, "{:?}", b.own[6]);
        assert_eq!(b.sources[7], Source::Own, "{:?}", b.own[7]);
        assert_eq!(b.levels[5], b.levels[0]);
    }

    #[test]
    fn short_recordings_of_one_level_share_it_and_a_noisier_one_is_still_set_apart() {
        // 51 samples at 333 Hz (an e2 strike every third sample): each recording's own estimate
        // scatters far more than at 151 samples, so the factor within which they agree widens
        // (white noise alone strays little at this count: see the next test for strikes);
        // recording 24 is four times as noisy on its first channel.
        let runs: Vec<Vec<Vec<f64>>> = (0..25)
            .map(|k| {
                let s0 = if k == 24 { 0.12 } else { 0.03 };
                vec![
                    ringing_at(51, 333.3, 31.0, s0, 100 + k),
                    ringing_at(51, 333.3, 23.0, 0.01, 200 + k),
                ]
            })
            .collect();
        let refs: Vec<&[Vec<f64>]> = runs.iter().map(|r| &r[..]).collect();
        let b = batch_levels(&refs, &[0, 1], &[None; 5]).unwrap();
        for k in 0..24 {
            assert_eq!(b.sources[k], Source::Batch, "recording {k}: {:?}", b.own[k]);
        }
        assert_eq!(b.sources[24], Source::Own, "{:?}", b.own[24]);
        assert!(
            b.agreement.iter().all(|f| (f - 2.0).abs() < 0.02),
            "{:?}",
            b.agreement
        );
        assert_eq!(agreement_factor(151), AGREEMENT);
        assert_eq!(agreement_factor(1000), AGREEMENT);
    }

    #[test]
    fn strikes_at_333_hz_share_their_level() {
        // Thirty e2 strikes of a 50-segment chain on the seed paper's stiffness rule (as another
        // engine's whisker), every third sample (51 samples), 3% noise: each strike's own
        // estimate strays further from the pooled one than at 1 kHz, by chance and by the
        // chain's faster modes aliased into its residuals (our 20-segment chain strays less).
        let sets = ["segments=50".to_string(), "discretisation=seed".to_string()];
        let family = crate::Family::open("e2", &sets)
            .unwrap()
            .with_timing(1000.0 / 3.0, 51)
            .unwrap();
        let noise = crate::experiment::Noise {
            sensor: [3.6e-3, 8.9e-3, 1.4e-6, 1.0e-4, 7.1e-5],
            process: 0.0,
        };
        let runs: Vec<Vec<Vec<f64>>> = (0..30)
            .map(|k| {
                let d = 0.0155 + 0.0141 * ((k as f64 * 0.618_034) % 1.0);
                let v = 0.32 + 1.16 * ((k as f64 * 0.414_214) % 1.0);
                family.simulate(&[d, v], &noise, 40 + k).unwrap().series
            })
            .collect();
        let refs: Vec<&[Vec<f64>]> = runs.iter().map(|r| &r[..]).collect();
        let all = [0, 1, 2, 3, 4];
        let b = batch_levels(&refs, &all, &[None; 5]).unwrap();
        let own = b.sources.iter().filter(|s| **s == Source::Own).count();
        // What AGREEMENT alone would have set apart.
        let pooled = estimate_pooled(&refs, &all).unwrap();
        let strays = b
            .own
            .iter()
            .filter(|o| all.iter().any(|&c| o[c] > AGREEMENT * pooled[c]))
            .count();
        assert!(own <= 1, "{own} of 30 set apart: {:?}", b.own);
        assert!(strays >= 3, "{strays}");
    }

    #[test]
    fn statements_parse_or_name_what_is_wrong() {
        assert_eq!(parse_statement("auto").unwrap(), [None; 5]);
        assert_eq!(parse_statement("none").unwrap(), [Some(0.0); 5]);
        assert_eq!(
            parse_statement("theta12=2e-3, fx=1e-4").unwrap(),
            [None, Some(2e-3), None, Some(1e-4), None]
        );
        for bad in ["theta3=1", "m0=-1", "m0=nan", "m0", "", "m0=1,m0=2"] {
            let e = parse_statement(bad).unwrap_err().to_string();
            assert!(e.contains("noise"), "{bad}: {e}");
        }
    }
}
