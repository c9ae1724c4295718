//! Any estimator on series aligned at the contact's onset: for recordings that start an unknown
//! time (up to a stated lead-in) before the approach.

use crate::error::{Error, Result};
use crate::experiment::{Sample, THETA12};
use crate::lead_in::{align, onset_time, own_threshold};
use crate::method::{Budget, Estimate, Method, Training};

/// Fewest samples an aligned window keeps after the onset.
const MIN_AFTER: usize = 10;

/// `inner` trained and applied on windows of the series that begin a fixed number of samples
/// (`pre`, one more than the latest onset after an approach among the training runs) before
/// the contact's onset
/// (where theta12 first leaves its start by a share of its own peak deviation, to a fraction of
/// a sample: [`onset_time`]),
/// so that a recording with up to `lead` samples of rest before the approach reads as one
/// without. The training runs should start up to `lead` samples before their approach
/// ([`crate::Family::with_start_jitter`]), so that they hold the rest and the random phase of
/// the contact between samples that such recordings hold. The windows are `lead` samples
/// shorter than the runs, so that a recording with the most lead-in still fills its window. What is lost is the time from the approach to contact,
/// which an unknown lead-in hides anyway.
pub struct Aligned {
    inner: Box<dyn Method>,
    /// Samples of lead-in allowed.
    lead: usize,
    /// Where the onset lands in a window, samples.
    pre: usize,
    /// Samples per window.
    window: usize,
}

impl Aligned {
    /// `inner` on aligned series, allowing up to `lead` samples of lead-in.
    pub fn new(inner: Box<dyn Method>, lead: usize) -> Aligned {
        Aligned {
            inner,
            lead,
            pre: 0,
            window: 0,
        }
    }

    fn aligned(&self, series: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let onset = series
            .get(THETA12)
            .and_then(|x| onset_time(x, own_threshold(x)))
            .unwrap_or(self.pre as f64);
        align(series, onset, self.pre, self.window)
    }

    fn aligned_samples(&self, samples: &[Sample]) -> Vec<Sample> {
        samples
            .iter()
            .map(|s| Sample {
                series: self.aligned(&s.series),
                params: s.params.clone(),
            })
            .collect()
    }
}

impl Method for Aligned {
    fn name(&self) -> &'static str {
        self.inner.name()
    }

    fn budget(&self) -> Budget {
        self.inner.budget()
    }

    fn channels(&self) -> Vec<usize> {
        self.inner.channels()
    }

    fn fit(&mut self, training: &Training) -> Result<()> {
        let runs: Vec<&Sample> = training
            .samples
            .iter()
            .chain(&training.calibration)
            .collect();
        let samples = runs
            .first()
            .map(|s| s.series[THETA12].len())
            .ok_or_else(|| Error::Setting("aligned series: no training runs".into()))?;
        // The training runs start up to `lead` samples before their approach (see
        // `Family::with_start_jitter`): the latest onset less that is the latest after an
        // approach, which the window keeps before the onset.
        let latest = runs
            .iter()
            .filter_map(|s| onset_time(&s.series[THETA12], own_threshold(&s.series[THETA12])))
            .fold(0.0, f64::max)
            .ceil() as usize;
        self.pre = latest.saturating_sub(self.lead) + 1;
        self.window = samples.saturating_sub(self.lead);
        if self.window < self.pre + MIN_AFTER {
            return Err(Error::Setting(format!(
                "max_delay: a lead-in of {} samples leaves {} of the recording's {samples}, too \
                 few to hold the strike (contact begins up to {} samples after the \
                 approach; at least {} are needed): allow a shorter lead-in or give a longer \
                 recording",
                self.lead,
                self.window,
                self.pre - 1,
                self.pre + MIN_AFTER
            )));
        }
        let family = training
            .family
            .with_timing(training.family.sample_rate(), self.window)?;
        self.inner.fit(&Training {
            family,
            samples: self.aligned_samples(&training.samples),
            calibration: self.aligned_samples(&training.calibration),
            noise: training.noise,
        })
    }

    fn predict(&self, obs: &[Vec<f64>]) -> Result<Vec<Estimate>> {
        self.inner.predict(&self.aligned(obs))
    }

    fn settings(&self) -> Vec<(String, f64)> {
        let mut s = self.inner.settings();
        s.push(("lead_samples".into(), self.lead as f64));
        s.push(("onset_at".into(), self.pre as f64));
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::experiment::Noise;
    use crate::family::Family;
    use crate::methods::by_name;

    /// A run of e2 recorded from `delay` s before the approach, cut to `samples` samples.
    fn delayed(family: &Family, p: &[f64], delay: f64, samples: usize) -> Vec<Vec<f64>> {
        let s = family.simulate_delayed(p, delay, &Noise::NONE, 3).unwrap();
        s.series.iter().map(|c| c[..samples].to_vec()).collect()
    }

    const METHOD: &str = "krr";

    #[test]
    fn a_lead_in_of_rest_leaves_the_estimate_where_it_was() {
        let family = Family::builtin("e2").unwrap();
        let n = family.samples();
        let train = |f: &Family| {
            crate::training_for(f, &Noise::NONE, &*by_name(METHOD).unwrap(), 5).unwrap()
        };
        let mut plain = by_name(METHOD).unwrap();
        plain.fit(&train(&family)).unwrap();
        // Trained on runs that start up to the lead-in before their approach.
        let lead = 40;
        let mut aligned = Aligned::new(by_name(METHOD).unwrap(), lead);
        aligned
            .fit(&train(
                &family.with_start_jitter(lead as f64 / family.sample_rate()),
            ))
            .unwrap();
        let p = [0.021, 0.7];
        let err = |m: &dyn Method, obs: &[Vec<f64>]| {
            let e = m.predict(obs).unwrap();
            ((e[0].mean - p[0]).abs(), (e[1].mean - p[1]).abs())
        };
        let on_time = delayed(&family, &p, 0.0, n);
        let late = delayed(&family, &p, 0.0304, n);
        let (d0, v0) = err(&aligned, &on_time);
        let (d1, v1) = err(&aligned, &late);
        let (d_plain, _) = err(plain.as_ref(), &late);
        // Aligned, the lead-in changes little; unaligned, it misleads.
        assert!(d0 < 1e-4 && d1 < 1e-4, "{d0} {d1}");
        assert!(v0 < 0.01 && v1 < 0.01, "{v0} {v1}");
        assert!(d_plain > 2e-4 && d_plain > 3.0 * d1, "{d_plain} {d1}");
    }

    #[test]
    fn a_lead_in_that_leaves_too_little_is_refused_by_name() {
        let family = Family::builtin("e1").unwrap();
        let training =
            crate::training_for(&family, &Noise::NONE, &*by_name(METHOD).unwrap(), 5).unwrap();
        let mut m = Aligned::new(by_name(METHOD).unwrap(), family.samples() - 5);
        let e = m.fit(&training).unwrap_err().to_string();
        assert!(e.contains("max_delay") && e.contains("lead-in"), "{e}");
    }
}
