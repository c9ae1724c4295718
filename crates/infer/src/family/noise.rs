//! The noise a family's runs carry: the `noisy` variant's levels (from the clean reference
//! runs' ranges), the levels a scenario states, and the sensor noise that training runs need
//! beside the random forces' response to look as noisy as the recordings.

use super::Family;
use crate::error::Result;
use crate::experiment::{Noise, Variant, CHANNELS, SENSOR_NOISE_FRACTION};
use std::collections::HashMap;
use std::sync::{Mutex, OnceLock};

/// A small cache of values computed once per family (by digest): the noisy variant's levels.
fn noise_cache() -> &'static Mutex<HashMap<u64, [f64; 5]>> {
    static CACHE: OnceLock<Mutex<HashMap<u64, [f64; 5]>>> = OnceLock::new();
    CACHE.get_or_init(|| Mutex::new(HashMap::new()))
}

/// [`Family::clean_ranges`] by the family's digest.
fn ranges_cache() -> &'static Mutex<HashMap<u64, [f64; 5]>> {
    static CACHE: OnceLock<Mutex<HashMap<u64, [f64; 5]>>> = OnceLock::new();
    CACHE.get_or_init(|| Mutex::new(HashMap::new()))
}

impl Family {
    /// The sensor noise the scenario states per channel of [`CHANNELS`] (the channels its
    /// `[sensor_noise]` table names), SI; estimators estimate the others from the recordings.
    pub fn stated_noise(&self) -> [Option<f64>; 5] {
        self.stated_noise
    }

    /// The noise of training runs for recordings whose sensor noise is `sensor` (per channel of
    /// [`CHANNELS`], SI): that sensor noise and the scenario's own process noise (`process_noise`,
    /// 0 unless the file sets it).
    pub fn training_noise(&self, sensor: [f64; 5]) -> Noise {
        Noise {
            sensor,
            process: self.base.process_noise,
        }
    }

    /// The noise to simulate training runs with, for recordings whose noise was measured as
    /// `measured`: the scenario's random forces (`process_noise`) shake the whisker fast enough
    /// that part of what a noise estimate measures on a recording is their response, and training
    /// runs simulated with the same random forces carry that part already. Each channel's sensor
    /// noise is therefore what the measured level leaves above the level the random forces alone
    /// show to the same estimator (on the scenario's templates, clean sensors), in quadrature;
    /// without random forces it is the measured level itself.
    pub fn training_sensor_noise(&self, measured: &Noise) -> Result<Noise> {
        if measured.process <= 0.0 {
            return Ok(*measured);
        }
        let response = self.process_response(measured.process)?;
        Ok(Noise {
            sensor: std::array::from_fn(|c| {
                (measured.sensor[c].powi(2) - response[c].powi(2))
                    .max(0.0)
                    .sqrt()
            }),
            process: measured.process,
        })
    }

    /// The noise level each channel shows to [`crate::noise::estimate_pooled`] on the templates
    /// simulated with random forces of intensity `process` and clean sensors (cached per family).
    fn process_response(&self, process: f64) -> Result<[f64; 5]> {
        let key = (self.nominal().digest() ^ process.to_bits()).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        if let Some(r) = noise_cache().lock().ok().and_then(|c| c.get(&key).copied()) {
            return Ok(r);
        }
        let noise = Noise {
            sensor: [0.0; 5],
            process,
        };
        let runs = self
            .nominal()
            .simulate_all(&self.templates(), &noise, 0x9e0c, &|| {})?;
        let series: Vec<&[Vec<f64>]> = runs.iter().map(|s| &s.series[..]).collect();
        let all: Vec<usize> = (0..CHANNELS.len()).collect();
        let response = crate::noise::estimate_pooled(&series, &all)?;
        if let Ok(mut c) = noise_cache().lock() {
            c.insert(key, response);
        }
        Ok(response)
    }

    /// The noise of `variant` on this family: what `vibrissa experiment` makes its recordings
    /// with (no estimator is told it). `noisy` is a sensor noise of 5% of each channel's
    /// peak-to-peak range over the clean reference runs, plus [`crate::experiment::PROCESS_NOISE`].
    /// The reference runs are the family's grid; for a family built on the experiment box they
    /// are the `e2` grid of its own scenario (docs/experiments.md defines `noisy` by the `e2` runs).
    pub fn noise(&self, variant: Variant) -> Result<Noise> {
        match variant {
            Variant::Clean => Ok(Noise::NONE),
            Variant::Noisy => {
                let key = self.doc.digest();
                let cached = noise_cache().lock().ok().and_then(|c| c.get(&key).copied());
                let sensor = match cached {
                    Some(l) => l,
                    None => {
                        let l = self.clean_ranges()?.map(|r| SENSOR_NOISE_FRACTION * r);
                        if let Ok(mut c) = noise_cache().lock() {
                            c.insert(key, l);
                        }
                        l
                    }
                };
                Ok(Noise {
                    sensor,
                    process: crate::experiment::PROCESS_NOISE,
                })
            }
        }
    }

    /// Peak-to-peak range of each channel over the clean reference runs (see
    /// [`Family::noise`]), `[CHANNELS]`, SI.
    pub fn clean_ranges(&self) -> Result<[f64; 5]> {
        // Computed once per family and timing: every estimate's check of units asks for them.
        let key = self.digest();
        if let Some(r) = ranges_cache()
            .lock()
            .ok()
            .and_then(|c| c.get(&key).copied())
        {
            return Ok(r);
        }
        let runs = match self.experiment {
            Some(_) => {
                let e2 = Family::builtin("e2")?;
                let reference = Family {
                    spec: e2.spec,
                    experiment: self.experiment,
                    randomised: None,
                    ..self.clone()
                };
                reference.simulate_all(&reference.grid(), &Noise::NONE, 0, &|| {})?
            }
            None => self
                .nominal()
                .simulate_all(&self.grid(), &Noise::NONE, 0, &|| {})?,
        };
        let mut lo = [f64::INFINITY; 5];
        let mut hi = [f64::NEG_INFINITY; 5];
        for s in &runs {
            for (c, ch) in s.series.iter().enumerate() {
                for &x in ch {
                    lo[c] = lo[c].min(x);
                    hi[c] = hi[c].max(x);
                }
            }
        }
        let ranges = std::array::from_fn(|c| hi[c] - lo[c]);
        if let Ok(mut c) = ranges_cache().lock() {
            c.insert(key, ranges);
        }
        Ok(ranges)
    }
}
