//! Shared pieces of the estimators: channel scales, normalised feature vectors, onset alignment
//! and interval calibration.

use crate::error::{Error, Result};
use crate::experiment::{Sample, THETA12};
use crate::method::Z90;

/// Per-channel scale: the standard deviation of the channel's values over a set of runs.
pub fn channel_scales(samples: &[Sample], channels: &[usize]) -> Vec<f64> {
    channels
        .iter()
        .map(|&c| {
            let (mut n, mut s, mut s2) = (0.0, 0.0, 0.0);
            for smp in samples {
                for &x in &smp.series[c] {
                    n += 1.0;
                    s += x;
                    s2 += x * x;
                }
            }
            let var = (s2 / n - (s / n).powi(2)).max(0.0);
            if var > 0.0 {
                var.sqrt()
            } else {
                1.0
            }
        })
        .collect()
}

/// The chosen channels of `obs`, each divided by its scale, concatenated. Every chosen channel
/// must be present and as long as the first.
pub fn flatten(obs: &[Vec<f64>], channels: &[usize], scales: &[f64]) -> Result<Vec<f64>> {
    let samples = channels
        .first()
        .and_then(|&c| obs.get(c))
        .map_or(0, |ch| ch.len());
    let mut out = Vec::with_capacity(channels.len() * samples);
    for (&c, &sc) in channels.iter().zip(scales) {
        let ch = obs
            .get(c)
            .filter(|ch| ch.len() == samples && samples > 0)
            .ok_or_else(|| {
                Error::Observation(format!(
                    "channel {} is missing or does not have the {samples} samples of {}",
                    crate::CHANNELS[c],
                    crate::CHANNELS[channels[0]]
                ))
            })?;
        out.extend(ch.iter().map(|x| x / sc));
    }
    Ok(out)
}

/// The first sample at which |theta12| exceeds `threshold` (0 if it never does).
pub fn onset(obs: &[Vec<f64>], threshold: f64) -> usize {
    obs[THETA12]
        .iter()
        .position(|x| x.abs() > threshold)
        .unwrap_or(0)
}

/// `window` samples of each chosen channel from `start` on (the last sample repeated past the
/// end), scaled, concatenated.
pub fn aligned(
    obs: &[Vec<f64>],
    channels: &[usize],
    scales: &[f64],
    start: usize,
    window: usize,
) -> Vec<f64> {
    let mut out = Vec::with_capacity(channels.len() * window);
    for (&c, &sc) in channels.iter().zip(scales) {
        let ch = &obs[c];
        for k in 0..window {
            out.push(ch[(start + k).min(ch.len() - 1)] / sc);
        }
    }
    out
}

/// Squared Euclidean distance.
pub fn dist2(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// The factor that makes `|error| ≤ 1.645·factor·std` hold for 90% of `(error, std)` pairs
/// (the 90th percentile of `|error|/(1.645·std)`); 1 without pairs.
pub fn coverage_factor(pairs: &[(f64, f64)]) -> f64 {
    coverage_factor_at(pairs, 0.9)
}

/// The factor that makes `|error| ≤ 1.645·factor·std` hold for a share `quantile` of
/// `(error, std)` pairs; 1 without pairs.
pub fn coverage_factor_at(pairs: &[(f64, f64)], quantile: f64) -> f64 {
    let mut r: Vec<f64> = pairs
        .iter()
        .filter(|(_, s)| *s > 0.0)
        .map(|(e, s)| e.abs() / (Z90 * s))
        .collect();
    if r.is_empty() {
        return 1.0;
    }
    r.sort_by(|a, b| a.total_cmp(b));
    // Linear interpolation at the quantile.
    let pos = quantile.clamp(0.0, 1.0) * (r.len() - 1) as f64;
    let (i, f) = (pos.floor() as usize, pos.fract());
    let q = if i + 1 < r.len() {
        r[i] * (1.0 - f) + r[i + 1] * f
    } else {
        r[i]
    };
    q.max(1e-12)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coverage_factor_makes_ninety_percent_of_errors_fit() {
        let pairs: Vec<(f64, f64)> = (1..=100).map(|k| (k as f64, Z90)).collect();
        let f = coverage_factor(&pairs);
        let inside = pairs
            .iter()
            .filter(|(e, s)| e.abs() <= Z90 * f * s + 1e-9)
            .count();
        assert!((89..=91).contains(&inside), "{inside}");
        let wide = coverage_factor_at(&pairs, 0.95);
        let inside = pairs
            .iter()
            .filter(|(e, s)| e.abs() <= Z90 * wide * s + 1e-9)
            .count();
        assert!((94..=96).contains(&inside), "{inside}");
    }
}
