//! The seed paper's template method (section VI-A), with its width chosen by leave-one-out.

use crate::error::{Error, Result};
use crate::experiment::{Sample, THETA12};
use crate::features::dist2;
use crate::method::{Budget, Estimate, Method, Training};

/// Gaussian responsibilities of the templates on `theta12` alone,
/// `λ_i ∝ exp(−Σ_t (m_i(t) − o(t))² / (2σ²))`, and the responsibility-weighted mean of the
/// templates' parameters. Its std is the responsibility-weighted spread of the templates'
/// parameters around that mean, but never less than the method's own leave-one-out error says
/// (its mean absolute error over the templates, as a normal's std): where one template takes all
/// the responsibility, the spread alone would be zero.
#[derive(Debug, Clone, Default)]
pub struct Template {
    /// Template `theta12` series, rad: `[templates][samples]`.
    series: Vec<Vec<f64>>,
    /// Template parameters: `[templates][unknowns]`.
    params: Vec<Vec<f64>>,
    /// Chosen variance σ², rad² (leave-one-out over the templates that the others surround).
    sigma2: f64,
    /// Leave-one-out mean absolute error at σ², in fractions of each unknown's range.
    loo_error: f64,
    /// Leave-one-out mean absolute error at σ² of each unknown, SI.
    loo_mae: Vec<f64>,
}

impl Template {
    /// An unfitted template method.
    pub fn new() -> Template {
        Template::default()
    }

    /// The chosen σ², rad².
    pub fn sigma2(&self) -> f64 {
        self.sigma2
    }

    /// Template parameters, `[templates][unknowns]`.
    pub fn template_params(&self) -> &[Vec<f64>] {
        &self.params
    }

    /// Responsibilities of the templates for `obs`, summing to 1.
    pub fn responsibilities(&self, obs: &[Vec<f64>]) -> Result<Vec<f64>> {
        let o = obs
            .get(THETA12)
            .filter(|o| !self.series.is_empty() && o.len() == self.series[0].len())
            .ok_or_else(|| {
                Error::Observation("theta12 is missing or has the wrong length".into())
            })?;
        Ok(weights(&self.series, o, self.sigma2, None))
    }
}

/// Normalised Gaussian responsibilities of `series` for `o` (leaving out index `skip`).
fn weights(series: &[Vec<f64>], o: &[f64], sigma2: f64, skip: Option<usize>) -> Vec<f64> {
    let e: Vec<f64> = series
        .iter()
        .enumerate()
        .map(|(i, m)| {
            if Some(i) == skip {
                f64::NEG_INFINITY
            } else {
                -dist2(m, o) / (2.0 * sigma2)
            }
        })
        .collect();
    // Log-sum-exp so that a narrow width does not underflow every weight.
    let top = e.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let w: Vec<f64> = e.iter().map(|x| (x - top).exp()).collect();
    let z: f64 = w.iter().sum();
    w.into_iter().map(|x| x / z).collect()
}

/// Responsibility-weighted mean and spread of `params`.
fn weighted(params: &[Vec<f64>], w: &[f64]) -> Vec<Estimate> {
    (0..params[0].len())
        .map(|j| {
            let mean: f64 = params.iter().zip(w).map(|(p, w)| w * p[j]).sum();
            let var: f64 = params
                .iter()
                .zip(w)
                .map(|(p, w)| w * (p[j] - mean).powi(2))
                .sum();
            Estimate::normal(mean, var.max(0.0).sqrt())
        })
        .collect()
}

impl Method for Template {
    fn name(&self) -> &'static str {
        "template"
    }

    fn budget(&self) -> Budget {
        Budget::Paper
    }

    fn channels(&self) -> Vec<usize> {
        vec![THETA12]
    }

    fn fit(&mut self, training: &Training) -> Result<()> {
        let t: &[Sample] = &training.samples;
        if t.len() < 2 {
            return Err(Error::Fit {
                method: "template".into(),
                detail: "needs at least two templates".into(),
            });
        }
        self.series = t.iter().map(|s| s.series[THETA12].clone()).collect();
        self.params = t.iter().map(|s| s.params.clone()).collect();
        let ranges = training.family.ranges();
        // Only templates that the others surround take part: a weighted mean of the others
        // cannot reach one outside their range, whatever the width.
        let surrounded: Vec<usize> = (0..t.len())
            .filter(|&j| {
                (0..ranges.len()).all(|u| {
                    let others = (0..t.len()).filter(|&i| i != j).map(|i| self.params[i][u]);
                    let (lo, hi) = others.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| {
                        (l.min(x), h.max(x))
                    });
                    lo <= self.params[j][u] && self.params[j][u] <= hi
                })
            })
            .collect();
        let held: Vec<usize> = if surrounded.is_empty() {
            (0..t.len()).collect()
        } else {
            surrounded
        };
        // σ² on a log grid from 1e-10 to 1e2 rad²; keep the one with the least leave-one-out error.
        let mut best = (f64::INFINITY, 1.0);
        for k in 0..=240 {
            let sigma2 = 10f64.powf(-10.0 + 12.0 * k as f64 / 240.0);
            let mut err = 0.0;
            for &j in &held {
                let s = &self.series[j];
                let w = weights(&self.series, s, sigma2, Some(j));
                let est = weighted(&self.params, &w);
                for (u, e) in est.iter().enumerate() {
                    err += (e.mean - self.params[j][u]).abs() / (ranges[u][1] - ranges[u][0]);
                }
            }
            err /= (held.len() * ranges.len()) as f64;
            if err < best.0 - 1e-12 {
                best = (err, sigma2);
            }
        }
        self.loo_error = best.0;
        self.sigma2 = best.1;
        // Each unknown's leave-one-out error at that width, for the intervals' floor.
        let mut mae = vec![0.0; ranges.len()];
        for &j in &held {
            let w = weights(&self.series, &self.series[j], self.sigma2, Some(j));
            for (u, e) in weighted(&self.params, &w).iter().enumerate() {
                mae[u] += (e.mean - self.params[j][u]).abs() / held.len() as f64;
            }
        }
        self.loo_mae = mae;
        Ok(())
    }

    fn predict(&self, obs: &[Vec<f64>]) -> Result<Vec<Estimate>> {
        let w = self.responsibilities(obs)?;
        // A mean absolute error is √(2/π) of a normal's std.
        let scale = (std::f64::consts::PI / 2.0).sqrt();
        Ok(weighted(&self.params, &w)
            .into_iter()
            .zip(&self.loo_mae)
            .map(|(e, mae)| {
                let floor = mae * scale;
                if e.std < floor {
                    Estimate::normal(e.mean, floor)
                } else {
                    e
                }
            })
            .collect())
    }

    fn settings(&self) -> Vec<(String, f64)> {
        vec![
            ("sigma2".into(), self.sigma2),
            ("loo_error_fraction_of_range".into(), self.loo_error),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_interval_is_never_narrower_than_the_leave_one_out_error() {
        // Three templates far apart for the width: a recording equal to one of them gives it all
        // the responsibility, and the templates' spread alone would be zero.
        let series: Vec<Vec<f64>> = (0..3).map(|k| vec![0.1 * k as f64; 20]).collect();
        let t = Template {
            series: series.clone(),
            params: vec![vec![0.015, 0.3], vec![0.023, 0.9], vec![0.030, 1.5]],
            sigma2: 1e-8,
            loo_error: 0.2,
            loo_mae: vec![0.002, 0.1],
        };
        let mut obs = vec![Vec::new(); crate::experiment::CHANNELS.len()];
        obs[THETA12] = series[1].clone();
        let est = t.predict(&obs).unwrap();
        let scale = (std::f64::consts::PI / 2.0).sqrt();
        assert_eq!(est[0].mean, 0.023);
        assert!((est[0].std - 0.002 * scale).abs() < 1e-15, "{:?}", est[0]);
        assert!((est[1].std - 0.1 * scale).abs() < 1e-15, "{:?}", est[1]);
        assert!(est[0].ci90[0] < 0.023 && 0.023 < est[0].ci90[1]);
        // A wide spread is kept as it is.
        let wide = Template { sigma2: 1e3, ..t };
        let est = wide.predict(&obs).unwrap();
        assert!(est[0].std > 0.002 * scale * 2.0, "{:?}", est[0]);
    }
}
