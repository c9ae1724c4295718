//! Methods fitted once per timing and noise level of the recordings they estimate from.
//!
//! A discriminative method trains on simulations of the scenario at the recording's sample rate
//! and length with the recording's sensor noise. A batch of recordings made alike trains once:
//! [`Trained`] keeps every fitted method by `(rate, samples, noise)`.

use crate::evaluate::training_for;
use crate::experiment::CHANNELS;
use crate::method::Method;
use crate::model_error::ModelError;
use crate::recording::Recording;
use crate::{methods, Family, Result};
use std::sync::Arc;
use std::time::Instant;

/// What a fitted method is kept by: sample rate (Hz), samples, sensor noise per channel, the
/// segments of the recording's chain (when its metadata says), and the lead-in allowed
/// (samples; 0: the recordings start at the approach).
type Key = (f64, usize, [f64; 5], Option<usize>, usize);

/// Methods trained per timing (sample rate and length) and noise level of the recordings.
#[derive(Default)]
pub struct Trained {
    fitted: Vec<(Key, Box<dyn Method>)>,
    /// Per calibrated family (by name), the residuals of its fit on its labelled strikes, once
    /// read (`None`: none to read, or unreadable).
    residuals: Vec<(String, Option<Arc<ModelError>>)>,
    /// Wall time of all training, s.
    pub seconds: f64,
    /// Simulated runs trained on, over all timings.
    pub runs: usize,
}

/// `theta01 1.20e-3, …`: the noise of `channels`, for messages.
pub fn describe_noise(level: &[f64; 5], channels: &[usize]) -> String {
    channels
        .iter()
        .map(|&c| format!("{} {:.3}", CHANNELS[c], Short(level[c])))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A number to a given count of significant digits (the precision), in plain notation for
/// moderate magnitudes and in exponent notation otherwise.
pub(crate) struct Short(pub(crate) f64);

impl std::fmt::Display for Short {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (x, digits) = (self.0, f.precision().unwrap_or(3).max(1));
        if !x.is_finite() || x == 0.0 {
            return write!(f, "{x}");
        }
        let exponent = x.abs().log10().floor() as i32;
        if (-3..6).contains(&exponent) {
            let decimals = (digits as i32 - 1 - exponent).max(0) as usize;
            write!(f, "{x:.decimals$}")
        } else {
            write!(f, "{x:.*e}", digits - 1)
        }
    }
}

impl Trained {
    /// The method `name` fitted on `family`'s runs at `rec`'s timing (and chain, when its
    /// metadata gives its segments) with the sensor noise `noise` (trained on first use; `log`
    /// hears what is trained and how long it took). With `lead` above 0 it reads series aligned
    /// at the contact's onset, for recordings that start up to `lead` samples before the
    /// approach ([`methods::Aligned`]).
    #[allow(clippy::too_many_arguments)]
    pub fn get(
        &mut self,
        family: &Family,
        rec: &Recording,
        noise: &[f64; 5],
        name: &str,
        seed: u64,
        lead: usize,
        log: &mut dyn FnMut(String),
    ) -> Result<&dyn Method> {
        let (rate, samples) = (rec.rate, rec.t.len());
        let key = (rate, samples, *noise, rec.segments, lead);
        let found = self.fitted.iter().position(|(k, _)| {
            (k.0 - key.0).abs() <= 1e-9 * key.0
                && k.1 == key.1
                && k.2 == key.2
                && k.3 == key.3
                && k.4 == key.4
        });
        let k = match found {
            Some(k) => k,
            None => {
                let timed = family.for_recording(rec)?;
                if let Some(n) = rec.segments.filter(|&n| n != family.segments()) {
                    log(format!(
                        "the recordings were made by a {n}-segment chain: training on it"
                    ));
                }
                let mut method = methods::by_name(name)?;
                // Aligned series: training runs that start up to the lead-in before the
                // approach, as the recordings may (rest before the contact, which falls
                // anywhere between samples).
                let timed = if lead > 0 {
                    method = Box::new(methods::Aligned::new(method, lead));
                    timed.with_start_jitter(lead as f64 / rate)
                } else {
                    timed
                };
                let t0 = Instant::now();
                let drawn = if family.randomisation().is_some() {
                    ", on whiskers drawn around the scenario's"
                } else {
                    ""
                };
                let aligned = if lead > 0 {
                    format!(
                        ", aligned at the contact's onset for a lead-in of up to {lead} samples"
                    )
                } else {
                    String::new()
                };
                log(format!(
                    "training {} ({} budget) on {samples}-sample runs at {} Hz with sensor noise \
                     {}{drawn}{aligned}…",
                    method.name(),
                    method.budget().name(),
                    Short(rate),
                    describe_noise(noise, &method.channels())
                ));
                // The residuals carry the labelled strikes' own noise too, but as one of a few
                // fixed patterns: the runs still get fresh noise at the recordings' full level.
                let residuals = self.residuals_of(family, log);
                let timed = timed.with_model_error(residuals);
                let noise = timed.training_noise(*noise);
                let training = training_for(&timed, &noise, method.as_ref(), seed)?;
                method.fit(&training)?;
                let secs = t0.elapsed().as_secs_f64();
                let runs = training.samples.len() + training.calibration.len();
                log(format!("trained on {runs} simulated runs in {secs:.2} s"));
                self.seconds += secs;
                self.runs += runs;
                self.fitted.push((key, method));
                self.fitted.len() - 1
            }
        };
        Ok(self.fitted[k].1.as_ref())
    }

    /// The residuals of `family`'s fit on the labelled strikes it was fitted to
    /// ([`ModelError`]), read on first use, when `family` was written by calibration and its
    /// record names a folder that is found; `log` hears what they are, or why there are none.
    fn residuals_of(
        &mut self,
        family: &Family,
        log: &mut dyn FnMut(String),
    ) -> Option<Arc<ModelError>> {
        if !family.is_calibrated() {
            return None;
        }
        if let Some((_, me)) = self.residuals.iter().find(|(n, _)| n == family.name()) {
            return me.clone();
        }
        let me = match family.labelled_strikes() {
            None => {
                log(format!(
                    "note: training without the fit's model error: {} names no labelled strikes \
                     found from here for this scenario (or gives the whisker of another), so \
                     intervals may be too narrow where the fitted whisker differs from yours",
                    family.name()
                ));
                None
            }
            Some(dir) => match ModelError::of(family, dir) {
                Ok(me) => {
                    let rms = me.rms();
                    let seen: Vec<usize> = (0..CHANNELS.len())
                        .filter(|&c| rms[c].is_finite())
                        .collect();
                    log(format!(
                        "adding to every training run the fitted whisker's residual on one of its \
                         {} labelled strikes ({}; RMS {}), beside the runs' own sensor noise",
                        me.strikes(),
                        dir.display(),
                        describe_noise(&rms, &seen)
                    ));
                    Some(Arc::new(me))
                }
                Err(e) => {
                    log(format!(
                        "note: training without the fit's model error ({e}); intervals may be \
                         too narrow where the fitted whisker differs from yours"
                    ));
                    None
                }
            },
        };
        self.residuals.push((family.name().to_string(), me.clone()));
        me
    }
}

/// Whether `recordings` (with their sensor noise and allowed lead-in) defy the scenario
/// `family` at `krr`'s estimates and near them ([`crate::check::unexplained`],
/// [`crate::check::defies`], weighed where that decides against the scenario's own runs at the
/// first recording's noise, [`null_unexplained`]): what tells the particle filter, before it
/// runs, that the recordings are not of the scenario's whisker. `krr` trains on the scenario's
/// own whisker (`family`'s nominal); a recording that lacks a channel it reads, or holds one
/// flat beside others that vary (a sensor that recorded nothing), is not looked at.
pub fn defied_by(
    family: &Family,
    recordings: &[Recording],
    noise: &[[f64; 5]],
    leads: &[usize],
    seed: u64,
    log: &mut dyn FnMut(String),
) -> Result<crate::check::Verdict> {
    let nominal = family.nominal();
    let channels = methods::by_name("krr")?.channels();
    let mut trained = Trained::default();
    let (mut recs, mut points, mut levels, mut allowed) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for ((rec, level), &lead) in recordings.iter().zip(noise).zip(leads) {
        if channels.iter().any(|&c| rec.values[c].is_empty())
            || !rec.dead_channels(&channels).is_empty()
        {
            continue;
        }
        let method = trained.get(&nominal, rec, level, "krr", seed, lead, log)?;
        // `krr` reads whole series: values the filter would skip are filled in for it (the
        // check itself skips them).
        points.push(method.predict(&rec.filled(&channels).0.values)?);
        recs.push(rec);
        levels.push(*level);
        allowed.push(lead);
    }
    let defied = crate::check::unexplained(&nominal, &recs, &points, &levels, &channels, &allowed);
    Ok(crate::check::defies(defied, recs.len(), || {
        null_unexplained(
            &mut trained,
            &nominal,
            recs[0],
            &levels[0],
            allowed[0],
            "krr",
            seed,
            log,
        )
    }))
}

/// How many of [`crate::check::NULL_RUNS`] runs of the scenario itself (`family`'s nominal
/// whisker, at `template`'s timing and chain, with the random forces of the scenario and the
/// sensor noise that makes them read `level`, starting at the approach) the method `name`
/// (trained on `family`, as for the recordings) reads so that the scenario explains them neither
/// at its estimates nor near them ([`crate::check::unexplained`]): how often the check calls the
/// scenario's own recordings unexplained at this noise.
#[allow(clippy::too_many_arguments)]
pub fn null_unexplained(
    trained: &mut Trained,
    family: &Family,
    template: &Recording,
    level: &[f64; 5],
    lead: usize,
    name: &str,
    seed: u64,
    log: &mut dyn FnMut(String),
) -> Result<usize> {
    use crate::check::NULL_RUNS;
    let nominal = family.nominal();
    let timed = nominal.for_recording(template)?;
    let noise = timed.training_sensor_noise(&timed.training_noise(*level))?;
    let null_seed = seed ^ 0x6e75_6c6c;
    let params = timed.random_params(NULL_RUNS, null_seed);
    let runs = timed.simulate_all(&params, &noise, null_seed, &|| {})?;
    let method = trained.get(family, template, level, name, seed, lead, log)?;
    let recs: Vec<Recording> = runs
        .into_iter()
        .map(|r| Recording {
            t: template.t.clone(),
            values: r.series,
            rate: template.rate,
            segments: template.segments,
        })
        .collect();
    let points = recs
        .iter()
        .map(|r| method.predict(&r.values))
        .collect::<Result<Vec<_>>>()?;
    let refs: Vec<&Recording> = recs.iter().collect();
    let channels = method.channels();
    Ok(crate::check::unexplained(
        &nominal,
        &refs,
        &points,
        &vec![*level; NULL_RUNS],
        &channels,
        &vec![lead; NULL_RUNS],
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_numbers() {
        assert_eq!(format!("{:.3}", Short(1000.0)), "1000");
        assert_eq!(format!("{:.6}", Short(1000.0)), "1000.00");
        assert_eq!(format!("{:.3}", Short(2.3562e-7)), "2.36e-7");
        assert_eq!(format!("{:.3}", Short(0.0)), "0");
        assert_eq!(
            describe_noise(&[1e-3, 2e-3, 0.0, 0.0, 0.0], &[0, 1]),
            "theta01 0.00100, theta12 0.00200"
        );
    }
}
