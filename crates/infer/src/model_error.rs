//! What a calibrated whisker still misses: the residuals of its fit on the labelled strikes.
//!
//! Calibration fits the simulator's whisker to labelled strikes of the user's; the fitted whisker
//! is the best of the simulator's, not the user's. Where the two differ in kind (another taper,
//! another follicle, another engine), the fitted runs miss each labelled strike by an error that
//! is correlated in time (a contact that lasts a little longer, ringing a little out of phase), on
//! some whiskers as large as a few per cent of each channel's range. The fit's standard errors do
//! not hold it: they measure how well the strikes pin the whisker's parameters, not how far the
//! simulator's best whisker is from the recordings. A discriminative method trained on runs of
//! whiskers drawn from those standard errors alone has never met such an error, and its intervals,
//! fitted on held-out runs made alike, are too narrow on the user's recordings.
//!
//! [`ModelError`] keeps the residual of every labelled strike: the recording less the fitted
//! scenario's noise-free run at its labels. [`ModelError::add`] adds one of them, drawn per run,
//! to a training run, aligned at the run's approach, so that the training and held-out runs show
//! deviations of the size and time course that the user's whisker shows. The draw does not depend
//! on the run's own labels: a residual at one strike says how large the model's error is, not
//! what it is at another distance and speed. The residuals hold the labelled strikes' own sensor
//! noise too ([`ModelError::noise`]), but only as a few fixed patterns, so the training runs keep
//! their full fresh sensor noise: a method trained on runs whose noise were mostly those patterns
//! learns them and is too sure of itself on recordings with noise of their own (on labelled
//! strikes as noisy as the recordings, `krr-local`'s intervals held the distance in 50% of the
//! strikes with the runs' noise reduced by the strikes', 75% without).

use crate::error::{Error, Result};
use crate::experiment::{Noise, CHANNELS};
use crate::family::Family;
use std::path::Path;
use vibrissa_core::rng::Rng;

/// Random stream of a run's draw of a residual, apart from the run's other streams.
const STREAM_RESIDUAL: u64 = 0x3e5d_0000;

/// The residuals of a fitted scenario on the labelled strikes it was fitted to.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelError {
    /// Sample rate of the residual series, Hz.
    rate: f64,
    /// Per labelled strike, per channel of [`CHANNELS`]: the recording less the fitted
    /// scenario's run at its labels (empty where the recording lacks the channel; 0 at a
    /// missing value).
    residuals: Vec<[Vec<f64>; 5]>,
    /// The labelled strikes' sensor noise per channel, pooled over them (a part of the
    /// residuals), SI.
    pub noise: [f64; 5],
}

impl ModelError {
    /// The residuals of `family`'s nominal (fitted) whisker on the labelled strikes in `dir`
    /// (`truth.csv` and the recordings, as `vibrissa calibrate` reads them): every unknown of
    /// the family must be labelled.
    pub fn of(family: &Family, dir: &Path) -> Result<ModelError> {
        let bad = |what: String| {
            Error::Observation(format!("the labelled strikes in {}: {what}", dir.display()))
        };
        let set = vibrissa_io::labelled::read_labelled(
            dir,
            family.document(),
            &vibrissa_io::labelled::Options {
                ignore_unlisted: true,
            },
        )
        .map_err(|e| bad(e.to_string()))?;
        let nominal = family.nominal();
        let keys = nominal.unknowns();
        let Some(first) = set.recordings.first() else {
            return Err(bad("none is listed".into()));
        };
        let rate = first.rate();
        let mut residuals = Vec::with_capacity(set.recordings.len());
        let mut values = Vec::with_capacity(set.recordings.len());
        for rec in &set.recordings {
            let p = keys
                .iter()
                .map(|k| rec.labels.iter().find(|(n, _)| n == k).map(|&(_, x)| x))
                .collect::<Option<Vec<f64>>>()
                .ok_or_else(|| {
                    bad(format!(
                        "`{}` is not labelled with every unknown ({})",
                        rec.file,
                        keys.join(", ")
                    ))
                })?;
            if (rec.rate() - rate).abs() > 1e-6 * rate {
                return Err(bad(format!(
                    "`{}` is sampled at {} Hz, the first at {rate} Hz",
                    rec.file,
                    rec.rate()
                )));
            }
            let samples = rec.t().len();
            let run = nominal
                .with_timing(rate, samples)?
                .simulate(&p, &Noise::NONE, 0)?;
            let series: [Vec<f64>; 5] = std::array::from_fn(|c| {
                rec.channel(CHANNELS[c]).map_or_else(Vec::new, |x| {
                    x.iter()
                        .zip(&run.series[c])
                        .map(|(y, m)| if y.is_finite() { y - m } else { 0.0 })
                        .collect()
                })
            });
            values.push(
                CHANNELS
                    .iter()
                    .map(|name| rec.channel(name).map_or_else(Vec::new, |x| x.to_vec()))
                    .collect::<Vec<_>>(),
            );
            residuals.push(series);
        }
        let refs: Vec<&[Vec<f64>]> = values.iter().map(|v| v.as_slice()).collect();
        let present: Vec<usize> = (0..CHANNELS.len())
            .filter(|&c| values.iter().all(|v| !v[c].is_empty()))
            .collect();
        // Strikes too short or too odd for a noise estimate: their noise counts as 0 (the
        // training runs then keep all of theirs).
        let noise = crate::noise::estimate_pooled(&refs, &present).unwrap_or([0.0; 5]);
        Ok(ModelError {
            rate,
            residuals,
            noise,
        })
    }

    /// How many labelled strikes' residuals it holds.
    pub fn strikes(&self) -> usize {
        self.residuals.len()
    }

    /// Root mean square of each channel's residuals over every strike (`NaN` for a channel no
    /// strike has).
    pub fn rms(&self) -> [f64; 5] {
        std::array::from_fn(|c| {
            let (mut sum, mut n) = (0.0, 0usize);
            for r in &self.residuals {
                sum += r[c].iter().map(|x| x * x).sum::<f64>();
                n += r[c].len();
            }
            (sum / n as f64).sqrt()
        })
    }

    /// Adds one strike's residual, drawn by the run's `seed`, to `series` (channels of
    /// [`CHANNELS`], sampled at `rate`, whose approach is `delay` seconds after its first
    /// sample): the residual at each sample's time since the approach, linearly interpolated
    /// between its own samples; nothing before the approach or past the residual's end.
    pub fn add(&self, series: &mut [Vec<f64>], rate: f64, delay: f64, seed: u64) {
        if self.residuals.is_empty() {
            return;
        }
        let k =
            (Rng::stream(seed, STREAM_RESIDUAL).next_u64() % self.residuals.len() as u64) as usize;
        let chosen = &self.residuals[k];
        for (x, r) in series.iter_mut().zip(chosen) {
            if r.is_empty() {
                continue;
            }
            for (j, v) in x.iter_mut().enumerate() {
                let at = (j as f64 / rate - delay) * self.rate;
                if at < 0.0 {
                    continue;
                }
                let i = at.floor() as usize;
                if i + 1 < r.len() {
                    let f = at - i as f64;
                    *v += r[i] * (1.0 - f) + r[i + 1] * f;
                } else if i + 1 == r.len() && at == i as f64 {
                    *v += r[i];
                } else {
                    break;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn held(residuals: Vec<[Vec<f64>; 5]>) -> ModelError {
        ModelError {
            rate: 1000.0,
            residuals,
            noise: [0.0; 5],
        }
    }

    #[test]
    fn a_residual_is_added_from_the_approach_on_and_interpolated() {
        let one = [
            vec![1.0, 2.0, 3.0],
            Vec::new(),
            vec![0.0; 3],
            vec![0.0; 3],
            vec![0.0; 3],
        ];
        let me = held(vec![one]);
        // Same rate, approach at the first sample.
        let mut s = vec![
            vec![10.0; 5],
            vec![5.0; 5],
            vec![0.0; 5],
            vec![0.0; 5],
            vec![0.0; 5],
        ];
        me.add(&mut s, 1000.0, 0.0, 1);
        assert_eq!(s[0], vec![11.0, 12.0, 13.0, 10.0, 10.0]);
        assert_eq!(
            s[1],
            vec![5.0; 5],
            "a channel without a residual is left alone"
        );
        // Twice the rate, approach 1 ms in: nothing before it, halfway values between samples.
        let mut s = vec![vec![0.0; 8]; 5];
        me.add(&mut s, 2000.0, 1e-3, 1);
        assert_eq!(s[0], vec![0.0, 0.0, 1.0, 1.5, 2.0, 2.5, 3.0, 0.0]);
    }

    #[test]
    fn the_draw_follows_the_seed_and_reaches_every_strike() {
        let me = held(
            (0..4)
                .map(|k| std::array::from_fn(|_| vec![k as f64]))
                .collect(),
        );
        let drawn = |seed| {
            let mut s = vec![vec![0.0]; 5];
            me.add(&mut s, 1000.0, 0.0, seed);
            s[0][0] as usize
        };
        assert_eq!(drawn(7), drawn(7));
        let mut seen = [false; 4];
        for seed in 0..64 {
            seen[drawn(seed)] = true;
        }
        assert!(seen.iter().all(|s| *s), "{seen:?}");
        assert_eq!(me.strikes(), 4);
    }
}
