//! Nearest neighbours among random training runs, on whole series (`knn`) or on series aligned
//! at the contact's onset (`shift`).

use crate::error::{Error, Result};
use crate::experiment::{Sample, CHANNELS, THETA12};
use crate::features::{aligned, channel_scales, coverage_factor, dist2, flatten, onset};
use crate::method::{Budget, Estimate, Method, Training, Z90};

/// Time kept after the onset by `shift`, s.
const WINDOW: f64 = 0.1;
/// Onset threshold of `shift`, as a fraction of the training runs' theta12 standard deviation.
const ONSET_FRACTION: f64 = 0.5;
/// Neighbour counts tried; the one with the least held-out error is kept.
const KS: [usize; 5] = [1, 2, 3, 5, 8];

/// Inverse-distance-weighted mean of the parameters of the `k` nearest training runs in the
/// space of normalised series. `k` is chosen on the last fifth of the training runs (fitted on
/// the rest); the std is constant per unknown, set so that 90% intervals cover 90% of those
/// held-out runs.
#[derive(Debug, Clone)]
pub struct Knn {
    /// Compare series aligned at the contact's onset.
    shifted: bool,
    /// Channel scales, `[CHANNELS]`.
    scales: Vec<f64>,
    /// Onset threshold on |theta12|, rad.
    threshold: f64,
    /// Samples kept after the onset by `shift` ([`WINDOW`] at the training runs' rate).
    window: usize,
    /// Training features `[runs][features]`.
    features: Vec<Vec<f64>>,
    /// Training parameters `[runs][unknowns]`.
    params: Vec<Vec<f64>>,
    /// Neighbours used.
    k: usize,
    /// Std per unknown, SI.
    std: Vec<f64>,
}

impl Knn {
    /// `knn`: whole series.
    pub fn plain() -> Knn {
        Knn::new(false)
    }

    /// `shift`: series aligned at the contact's onset.
    pub fn shifted() -> Knn {
        Knn::new(true)
    }

    fn new(shifted: bool) -> Knn {
        Knn {
            shifted,
            scales: Vec::new(),
            threshold: 0.0,
            window: 0,
            features: Vec::new(),
            params: Vec::new(),
            k: 5,
            std: Vec::new(),
        }
    }

    fn feature(&self, obs: &[Vec<f64>]) -> Result<Vec<f64>> {
        let channels: Vec<usize> = (0..CHANNELS.len()).collect();
        let x = flatten(obs, &channels, &self.scales)?;
        if !self.shifted {
            return Ok(x);
        }
        let start = onset(obs, self.threshold);
        Ok(aligned(obs, &channels, &self.scales, start, self.window))
    }

    fn learn(&mut self, samples: &[Sample]) -> Result<()> {
        self.features = samples
            .iter()
            .map(|s| self.feature(&s.series))
            .collect::<Result<_>>()?;
        self.params = samples.iter().map(|s| s.params.clone()).collect();
        Ok(())
    }

    fn point(&self, x: &[f64], k: usize) -> Vec<f64> {
        let mut d: Vec<(f64, usize)> = self
            .features
            .iter()
            .enumerate()
            .map(|(i, f)| (dist2(f, x), i))
            .collect();
        let k = k.min(d.len());
        d.select_nth_unstable_by(k - 1, |a, b| a.0.total_cmp(&b.0));
        let near = &d[..k];
        let w: Vec<f64> = near.iter().map(|(e, _)| 1.0 / (e.sqrt() + 1e-9)).collect();
        let z: f64 = w.iter().sum();
        (0..self.params[0].len())
            .map(|u| {
                near.iter()
                    .zip(&w)
                    .map(|((_, i), w)| w * self.params[*i][u])
                    .sum::<f64>()
                    / z
            })
            .collect()
    }
}

impl Method for Knn {
    fn name(&self) -> &'static str {
        if self.shifted {
            "shift"
        } else {
            "knn"
        }
    }

    fn budget(&self) -> Budget {
        Budget::Free
    }

    fn channels(&self) -> Vec<usize> {
        (0..CHANNELS.len()).collect()
    }

    fn fit(&mut self, training: &Training) -> Result<()> {
        let s = &training.samples;
        if s.len() < 10 {
            return Err(Error::Fit {
                method: self.name().into(),
                detail: "needs at least 10 training runs".into(),
            });
        }
        let channels: Vec<usize> = (0..CHANNELS.len()).collect();
        self.scales = channel_scales(s, &channels);
        self.threshold = ONSET_FRACTION * self.scales[THETA12];
        self.window = ((WINDOW * training.family.sample_rate()).round() as usize).max(1);
        // Hold out the last fifth to choose k and calibrate the std.
        let cut = s.len() * 4 / 5;
        let (fit, held) = s.split_at(cut);
        self.learn(fit)?;
        let ranges = training.family.ranges();
        let held_x: Vec<Vec<f64>> = held
            .iter()
            .map(|h| self.feature(&h.series))
            .collect::<Result<_>>()?;
        let mut best = (f64::INFINITY, KS[0]);
        for k in KS {
            let mut err = 0.0;
            for (h, x) in held.iter().zip(&held_x) {
                let p = self.point(x, k);
                for u in 0..p.len() {
                    err += (p[u] - h.params[u]).abs() / (ranges[u][1] - ranges[u][0]);
                }
            }
            if err < best.0 {
                best = (err, k);
            }
        }
        self.k = best.1;
        let unknowns = ranges.len();
        let mut pairs = vec![Vec::new(); unknowns];
        for (h, x) in held.iter().zip(&held_x) {
            let p = self.point(x, self.k);
            for u in 0..unknowns {
                pairs[u].push((p[u] - h.params[u], 1.0 / Z90));
            }
        }
        self.std = pairs.iter().map(|p| coverage_factor(p) / Z90).collect();
        // The final model uses every training run.
        self.learn(s)?;
        Ok(())
    }

    fn predict(&self, obs: &[Vec<f64>]) -> Result<Vec<Estimate>> {
        if self.features.is_empty() {
            return Err(Error::Fit {
                method: self.name().into(),
                detail: "not fitted".into(),
            });
        }
        let x = self.feature(obs)?;
        let p = self.point(&x, self.k);
        Ok(p.iter()
            .zip(&self.std)
            .map(|(m, s)| Estimate::normal(*m, *s))
            .collect())
    }

    fn settings(&self) -> Vec<(String, f64)> {
        let mut s = vec![("k".into(), self.k as f64)];
        if self.shifted {
            s.push(("onset_threshold".into(), self.threshold));
        }
        s
    }
}
