//! Stand-in "foreign" whiskers: perturbed versions of a nominal scenario that play the part of a
//! real rig (or another engine), so that calibration and estimators can be checked on recordings
//! that nothing was tuned on.
//!
//! From a seed, [`make`] draws a whisker and sensors that differ from the nominal as a real rig
//! would:
//! - Young's modulus, density and the damping coefficient each off by 10–25%, with a random sign;
//! - a taper (the tip radius 50–90% of the nominal's), a compliant follicle (a spring whose
//!   compliance is 0.3–3 times the nominal chain's base joint's, log-uniform, damped with a time
//!   constant e^±1 times the whisker's own), or both, each with probability 1/3;
//! - sensor gains off by up to 5% and offsets of up to 1% of each channel's range;
//! - the seed paper's discretisation (`seed`, k = EI/l) at many segments (50 by default).
//!
//! [`Standin::write`] writes, like `shared/data/foreign-dev`: `calib/` with the 9 template
//! strikes of `e2` (d ∈ {15, 23, 30} mm × v ∈ {0.3, 0.9, 1.5} m/s, clean unless asked), `eval/`
//! with off-grid strikes (d uniform in 15…30 mm, v in 0.3…1.5 m/s) carrying Gaussian noise of 3%
//! of each channel's range over those runs (`noise.json`), each folder with `truth.csv`
//! (`file,d,v`), plus `nominal.toml` (what the user believes), `standin.toml` (the truth as a
//! scenario, without noise) and `truth.json` (the true values under calibration's keys).

use crate::calibrate::UNITS;
use crate::error::{Error, Result};
use crate::reference::Reference;
use serde::Serialize;
use std::path::Path;
use vibrissa_core::chain::Discretisation;
use vibrissa_core::rng::Rng;
use vibrissa_core::sensors::CHANNELS;
use vibrissa_core::sim::{self, Response, Scenario, SensorResponse, COLUMNS};
use vibrissa_core::whisker::{Damping, Follicle};
use vibrissa_io::scenario::Document;
use vibrissa_io::series::{self, Series};

/// Template distances of `e2`, m.
pub const TEMPLATE_D: [f64; 3] = [0.015, 0.023, 0.030];
/// Template speeds of `e2`, m/s.
pub const TEMPLATE_V: [f64; 3] = [0.3, 0.9, 1.5];

/// How stand-ins and their recordings are made.
#[derive(Debug, Clone, Copy)]
pub struct Options {
    /// Segment count of the stand-in's chain.
    pub segments: usize,
    /// Its stiffness rule.
    pub discretisation: Discretisation,
    /// Off-grid strikes in `eval/`.
    pub off_grid: usize,
    /// Noise of the off-grid strikes, as a fraction of each channel's range over them.
    pub eval_noise: f64,
    /// Noise of the template strikes in `calib/`, likewise (0: clean).
    pub calib_noise: f64,
    /// Whether the whisker and sensors are perturbed; without, the stand-in is the nominal
    /// scenario itself (segments and discretisation as given here), a reference to compare with.
    pub perturb: bool,
    /// Longest lead-in of the off-grid strikes, s: each is recorded from a time drawn uniformly
    /// in [0, max_lead] before its approach, and every recording is `max_lead` longer than the
    /// nominal run (0: they start at the approach).
    pub max_lead: f64,
    /// A follicle of this compliance, relative to the nominal chain's base joint's, in every
    /// stand-in (`None`: drawn as above, with probability 2/3).
    pub compliance: Option<f64>,
    /// Time step of the stand-in's simulator, s, in (0, 1 ms] (`None`: the scenario's, 0.1 ms
    /// for `e2`). The default step leaves errors of a few percent of a channel's peak in fast
    /// strikes (docs/contact.md); 0.01 ms records what a converged integration would.
    pub dt: Option<f64>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            segments: 50,
            discretisation: Discretisation::Seed,
            off_grid: 20,
            eval_noise: 0.03,
            calib_noise: 0.0,
            perturb: true,
            max_lead: 0.0,
            compliance: None,
            dt: None,
        }
    }
}

/// The true value of a parameter, under the key calibration reports it by.
#[derive(Debug, Clone, Serialize)]
pub struct TrueValue {
    /// Calibration's key (`whisker.youngs_modulus`, `sensors.fx.gain`, `time_offset`).
    pub key: String,
    /// The value, SI (infinite: a clamped follicle's stiffness).
    pub value: f64,
}

/// A stand-in whisker and its sensors.
#[derive(Debug, Clone)]
pub struct Standin {
    /// The seed it was drawn from.
    pub seed: u64,
    /// The nominal scenario as a document (what the user believes).
    pub nominal: Document,
    /// The true scenario without labels (its sensor gains set, offsets still 0: they are drawn
    /// from the recordings' ranges by [`Standin::write`]).
    pub truth: Scenario,
    /// Relative offsets: each channel's offset as a fraction of its range, in [-0.01, 0.01].
    pub offset_fractions: [f64; 5],
}

/// Draws the stand-in of `seed` from `nominal` (a scenario of the `e2` family: it must take the
/// labels `d` and `v`).
pub fn make(nominal: &Document, seed: u64, options: &Options) -> Result<Standin> {
    let base = nominal
        .loaded_with(&["d=0.02".to_string(), "v=0.6".to_string()])?
        .scenario;
    if let Some(dt) = options.dt {
        let most = vibrissa_core::dynamics::MAX_DT;
        if !(dt.is_finite() && dt > 0.0 && dt <= most) {
            return Err(standin_error(&format!(
                "time step dt: a number of seconds in (0, {most}] (got {dt})"
            )));
        }
    }
    let mut rng = Rng::stream(seed, 0x57A4D);
    let mut truth = base.clone();
    if let Some(dt) = options.dt {
        truth.integrator.dt = dt;
    }
    if !options.perturb {
        truth.segments = options.segments;
        truth.discretisation = options.discretisation;
        return Ok(Standin {
            seed,
            nominal: nominal.clone(),
            truth,
            offset_fractions: [0.0; 5],
        });
    }
    let w = &mut truth.whisker;

    // Material and damping off by 10–25% either way.
    let off = |rng: &mut Rng| {
        let size = 0.10 + 0.15 * rng.uniform();
        if rng.uniform() < 0.5 {
            1.0 - size
        } else {
            1.0 + size
        }
    };
    w.youngs_modulus *= off(&mut rng);
    w.density *= off(&mut rng);
    let damping_factor = off(&mut rng);
    w.damping = match w.damping {
        Damping::ModalRatio { ratio } => Damping::ModalRatio {
            ratio: (ratio * damping_factor).min(0.9),
        },
        Damping::SegmentQ { q } => Damping::SegmentQ {
            q: q * damping_factor,
        },
        Damping::StiffnessProportional { beta } => Damping::StiffnessProportional {
            beta: beta * damping_factor,
        },
        Damping::None => Damping::None,
    };

    // A taper, a compliant follicle, or both.
    let variant = (rng.uniform() * 3.0) as usize;
    let taper = variant != 1;
    let follicle = variant != 0 || options.compliance.is_some();
    if taper {
        w.tip_radius *= 0.5 + 0.4 * rng.uniform();
    }
    if follicle {
        // Relative to the nominal chain's base joint (the user's belief, clamped).
        let reference = Reference::of(&base)?;
        let (k0, beta0) = (reference.k0, reference.beta0);
        let drawn = (0.3f64.ln() + rng.uniform() * 10.0f64.ln()).exp();
        let compliance = options.compliance.unwrap_or(drawn);
        if !(compliance.is_finite() && compliance > 0.0) {
            return Err(Error::Setting(format!(
                "stand-in follicle compliance: a finite ratio > 0 (got {compliance})"
            )));
        }
        let stiffness = k0 / compliance;
        let tau = beta0 * (2.0 * rng.uniform() - 1.0).exp();
        w.follicle = Follicle::Spring {
            stiffness,
            damping: stiffness * tau,
        };
    }

    // Sensors: gains off by up to 5%, offsets up to 1% of the range.
    let gains: [f64; 5] = std::array::from_fn(|_| 1.0 + 0.05 * (2.0 * rng.uniform() - 1.0));
    let offset_fractions = std::array::from_fn(|_| 0.01 * (2.0 * rng.uniform() - 1.0));
    truth.sensor_response = SensorResponse::from_array(std::array::from_fn(|c| Response {
        gain: gains[c] * base.sensor_response.to_array()[c].gain,
        offset: 0.0,
    }));
    truth.segments = options.segments;
    truth.discretisation = options.discretisation;
    truth.check().map_err(|e| standin_error(&e.to_string()))?;
    Ok(Standin {
        seed,
        nominal: nominal.clone(),
        truth,
        offset_fractions,
    })
}

fn standin_error(message: &str) -> Error {
    Error::Setting(format!("stand-in: {message}"))
}

/// One strike: its file name and labels.
#[derive(Debug, Clone)]
struct Strike {
    file: String,
    d: f64,
    v: f64,
    /// Time recorded before the approach, s.
    lead: f64,
    /// Time recorded in all, beyond the nominal run's, s.
    extra: f64,
}

impl Standin {
    /// The truth scenario with a strike's labels (the experiment's box at d, v).
    fn strike_scenario(&self, d: f64, v: f64) -> Result<Scenario> {
        let mut s = self.truth.clone();
        // The box is the last object (the experiment's).
        let labelled = self
            .nominal
            .loaded_with(&[format!("d={d:?}"), format!("v={v:?}")])?
            .scenario;
        s.objects = labelled.objects;
        Ok(s)
    }

    /// The template strikes of `calib/`.
    fn templates() -> Vec<Strike> {
        let mut out = Vec::new();
        for d in TEMPLATE_D {
            for v in TEMPLATE_V {
                out.push(Strike {
                    file: format!("d{:02.0}_v{:04.0}.csv", d * 1e3, v * 1e3),
                    d,
                    v,
                    lead: 0.0,
                    extra: 0.0,
                });
            }
        }
        out
    }

    /// The off-grid strikes of `eval/`.
    fn off_grid(&self, n: usize, max_lead: f64) -> Vec<Strike> {
        let mut rng = Rng::stream(self.seed, 0xE7A1);
        let mut leads = Rng::stream(self.seed, 0x1EAD);
        (0..n)
            .map(|k| {
                // A tenth of a millimetre and 10 mm/s, like the files' names say.
                let d = ((15.0 + 15.0 * rng.uniform()) * 10.0).round() / 1e4;
                let v = ((0.3 + 1.2 * rng.uniform()) * 100.0).round() / 100.0;
                let name = format!("{:.1}", d * 1e3).replace('.', "p");
                Strike {
                    file: format!("e{k:02}_d{name}_v{:04.0}.csv", v * 1e3),
                    d,
                    v,
                    lead: max_lead * leads.uniform(),
                    extra: max_lead,
                }
            })
            .collect()
    }

    /// Simulates strikes, noise-free, through the true sensors with the given offsets.
    fn simulate(&self, strikes: &[Strike], offsets: &[f64; 5]) -> Result<Vec<Vec<[f64; 10]>>> {
        use rayon::prelude::*;
        strikes
            .par_iter()
            .map(|s| {
                let mut sc = self.strike_scenario(s.d, s.v)?;
                // A lead-in: the box starts where it was `lead` earlier on its path.
                for o in &mut sc.objects {
                    if let vibrissa_core::objects::Motion::Constant { velocity, .. } = o.motion {
                        o.position[0] -= velocity[0] * s.lead;
                        o.position[1] -= velocity[1] * s.lead;
                    }
                }
                sc.duration += s.extra;
                let mut resp = sc.sensor_response.to_array();
                for c in 0..5 {
                    resp[c].offset = offsets[c];
                }
                sc.sensor_response = SensorResponse::from_array(resp);
                sim::run(&sc, &mut |_| {})
                    .map(|o| o.rows)
                    .map_err(|source| Error::Simulation {
                        d: s.d,
                        v: s.v,
                        source,
                    })
            })
            .collect()
    }

    /// The offsets in SI units: each channel's fraction of its range over the template strikes.
    fn offsets(&self) -> Result<[f64; 5]> {
        let rows = self.simulate(&Self::templates(), &[0.0; 5])?;
        let range = ranges(&rows);
        Ok(std::array::from_fn(|c| self.offset_fractions[c] * range[c]))
    }

    /// The true values under calibration's keys (the follicle's stiffness is infinite when
    /// clamped; `time_offset` is 0).
    pub fn true_values(&self) -> Result<Vec<TrueValue>> {
        let w = &self.truth.whisker;
        let offsets = self.offsets()?;
        let mut out = vec![
            ("whisker.youngs_modulus".to_string(), w.youngs_modulus),
            ("whisker.density".to_string(), w.density),
            ("whisker.tip_radius".to_string(), w.tip_radius),
        ];
        match w.follicle {
            Follicle::Clamped => {
                out.push(("whisker.follicle.stiffness".into(), f64::INFINITY));
            }
            Follicle::Spring { stiffness, damping } => {
                out.push(("whisker.follicle.stiffness".into(), stiffness));
                out.push(("whisker.follicle.damping".into(), damping));
            }
        }
        match w.damping {
            Damping::ModalRatio { ratio } => out.push(("whisker.damping.ratio".into(), ratio)),
            Damping::SegmentQ { q } => out.push(("whisker.damping.q".into(), q)),
            Damping::StiffnessProportional { beta } => {
                out.push(("whisker.damping.beta".into(), beta))
            }
            Damping::None => {}
        }
        out.push(("time_offset".into(), 0.0));
        for (c, r) in self.truth.sensor_response.to_array().iter().enumerate() {
            out.push((format!("sensors.{}.gain", CHANNELS[c]), r.gain));
            out.push((format!("sensors.{}.offset", CHANNELS[c]), offsets[c]));
        }
        Ok(out
            .into_iter()
            .map(|(key, value)| TrueValue { key, value })
            .collect())
    }

    /// Writes the stand-in's labelled sets and descriptions into `dir` (see the
    /// [module documentation](self)).
    pub fn write(&self, dir: &Path, options: &Options) -> Result<()> {
        let io = |e: std::io::Error, what: &Path| {
            Error::Scenario(vibrissa_io::Error::Io {
                action: "write",
                path: what.to_path_buf(),
                error: e,
            })
        };
        let offsets = self.offsets()?;
        let mut rng = Rng::stream(self.seed, 0x0015E);
        for (folder, strikes, noise) in [
            ("calib", Self::templates(), options.calib_noise),
            (
                "eval",
                self.off_grid(options.off_grid, options.max_lead),
                options.eval_noise,
            ),
        ] {
            if strikes.is_empty() {
                continue;
            }
            let sub = dir.join(folder);
            std::fs::create_dir_all(&sub).map_err(|e| io(e, &sub))?;
            let mut rows = self.simulate(&strikes, &offsets)?;
            // Gaussian noise, a fraction of each channel's range over these runs.
            let range = ranges(&rows);
            let sd: [f64; 5] = std::array::from_fn(|c| noise * range[c]);
            if noise > 0.0 {
                for run in &mut rows {
                    for row in run.iter_mut() {
                        for c in 0..5 {
                            row[c + 1] += sd[c] * rng.normal();
                        }
                    }
                }
                let json: String = CHANNELS
                    .iter()
                    .zip(sd)
                    .map(|(n, s)| format!(" \"{n}\": {s:e}"))
                    .collect::<Vec<_>>()
                    .join(",\n");
                let path = sub.join("noise.json");
                std::fs::write(&path, format!("{{\n{json}\n}}\n")).map_err(|e| io(e, &path))?;
            }
            let mut truth = String::from("file,d,v\n");
            for (strike, run) in strikes.iter().zip(&rows) {
                let mut series = Series::new(&COLUMNS);
                for row in run {
                    series.push_row(row);
                }
                series::write(&series, sub.join(&strike.file))?;
                truth.push_str(&format!("{},{:?},{:?}\n", strike.file, strike.d, strike.v));
            }
            let path = sub.join("truth.csv");
            std::fs::write(&path, truth).map_err(|e| io(e, &path))?;
            if options.max_lead > 0.0 && folder == "eval" {
                let mut leads = String::from("file,lead\n");
                for strike in &strikes {
                    leads.push_str(&format!("{},{:?}\n", strike.file, strike.lead));
                }
                let path = dir.join("leads.csv");
                std::fs::write(&path, leads).map_err(|e| io(e, &path))?;
            }
        }

        // What the user believes, the truth as a scenario, and the true values.
        self.nominal.write(&dir.join("nominal.toml"))?;
        let mut truth_doc = self.nominal.clone();
        for set in self.truth_overrides(&offsets) {
            truth_doc.set(&set)?;
        }
        truth_doc.write(&dir.join("standin.toml"))?;
        let values = self.true_values()?;
        let json = serde_json::json!({
            "seed": self.seed,
            "segments": self.truth.segments,
            "discretisation": self.truth.discretisation.name(),
            "dt": self.truth.integrator.dt,
            "units": UNITS,
            "parameters": values
                .iter()
                .map(|v| (v.key.clone(), if v.value.is_finite() { serde_json::json!(v.value) } else { serde_json::json!("inf") }))
                .collect::<serde_json::Map<String, serde_json::Value>>(),
        });
        let path = dir.join("truth.json");
        std::fs::write(&path, format!("{json:#}\n")).map_err(|e| io(e, &path))?;
        Ok(())
    }

    /// Overrides that turn the nominal document into the stand-in's scenario.
    fn truth_overrides(&self, offsets: &[f64; 5]) -> Vec<String> {
        let w = &self.truth.whisker;
        let mut out = vec![
            format!("segments={}", self.truth.segments),
            format!("discretisation={}", self.truth.discretisation.name()),
            format!("dt={:?}", self.truth.integrator.dt),
            format!("whisker.youngs_modulus={:?}", w.youngs_modulus),
            format!("whisker.density={:?}", w.density),
            format!("whisker.tip_radius={:?}", w.tip_radius),
        ];
        out.push(match w.follicle {
            Follicle::Clamped => "whisker.follicle={ kind = \"clamped\" }".to_string(),
            Follicle::Spring { stiffness, damping } => format!(
                "whisker.follicle={{ kind = \"spring\", stiffness = {stiffness:?}, damping = {damping:?} }}"
            ),
        });
        out.push(match w.damping {
            Damping::ModalRatio { ratio } => {
                format!("whisker.damping={{ kind = \"modal_ratio\", ratio = {ratio:?} }}")
            }
            Damping::SegmentQ { q } => {
                format!("whisker.damping={{ kind = \"segment_q\", q = {q:?} }}")
            }
            Damping::StiffnessProportional { beta } => {
                format!("whisker.damping={{ kind = \"stiffness_proportional\", beta = {beta:?} }}")
            }
            Damping::None => "whisker.damping={ kind = \"none\" }".to_string(),
        });
        for (c, r) in self.truth.sensor_response.to_array().iter().enumerate() {
            out.push(format!(
                "sensors.{}={{ gain = {:?}, offset = {:?} }}",
                CHANNELS[c], r.gain, offsets[c]
            ));
        }
        out
    }
}

/// Range (max − min) of each observed channel over runs of contract rows (1 without spread).
fn ranges(runs: &[Vec<[f64; 10]>]) -> [f64; 5] {
    std::array::from_fn(|c| {
        let (lo, hi) = runs
            .iter()
            .flatten()
            .map(|r| r[c + 1])
            .filter(|v| v.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            });
        if hi > lo {
            hi - lo
        } else {
            1.0
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stated_compliance_gives_every_stand_in_that_follicle() {
        let nominal = Document::load("e2", &[]).unwrap();
        let base = nominal
            .loaded_with(&["d=0.02".to_string(), "v=0.6".to_string()])
            .unwrap()
            .scenario;
        let k0 = Reference::of(&base).unwrap().k0;
        for seed in 1..6 {
            let options = Options {
                compliance: Some(6.0),
                ..Options::default()
            };
            let s = make(&nominal, seed, &options).unwrap();
            match s.truth.whisker.follicle {
                Follicle::Spring { stiffness, .. } => {
                    assert!((stiffness * 6.0 / k0 - 1.0).abs() < 1e-12, "seed {seed}")
                }
                Follicle::Clamped => panic!("seed {seed}: clamped"),
            }
        }
        let bad = Options {
            compliance: Some(-1.0),
            ..Options::default()
        };
        let err = make(&nominal, 1, &bad).unwrap_err();
        assert!(err.to_string().contains("compliance"), "{err}");
    }

    #[test]
    fn a_stated_time_step_records_the_stand_in_at_that_step() {
        let nominal = Document::load("e2", &[]).unwrap();
        let fine = Options {
            dt: Some(1e-5),
            ..Options::default()
        };
        for perturb in [true, false] {
            let options = Options { perturb, ..fine };
            let s = make(&nominal, 3, &options).unwrap();
            assert_eq!(s.truth.integrator.dt, 1e-5);
            assert!(s
                .truth_overrides(&[0.0; 5])
                .contains(&"dt=1e-5".to_string()));
        }
        // The same whisker as at the scenario's own step: only the step differs.
        let coarse = make(&nominal, 3, &Options::default()).unwrap();
        let s = make(&nominal, 3, &fine).unwrap();
        assert_eq!(s.truth.whisker, coarse.truth.whisker);
        assert_eq!(coarse.truth.integrator.dt, 1e-4);
        for dt in [0.0, -1e-5, 2e-3, f64::NAN] {
            let bad = Options {
                dt: Some(dt),
                ..Options::default()
            };
            let err = make(&nominal, 1, &bad).unwrap_err();
            assert!(err.to_string().contains("time step dt"), "{err}");
        }
    }
}
