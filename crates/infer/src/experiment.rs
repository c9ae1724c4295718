//! The seed's experiments `e1` and `e2` (EXPERIMENTS.md): their grids, templates, variants and
//! noise, and simulated runs as samples.

use crate::error::{Error, Result};
use rayon::prelude::*;
use serde::Serialize;
use std::sync::OnceLock;
use vibrissa_core::rng::Rng;
use vibrissa_core::scenes::e2_box;
use vibrissa_core::sim::{self, Scenario, SensorNoise};

/// Observed channels, in the order of [`Sample::series`].
pub const CHANNELS: [&str; 5] = ["theta01", "theta12", "m0", "fx", "fy"];
/// Index of `theta12` in [`CHANNELS`].
pub const THETA12: usize = 1;
/// Samples per run (150 ms at 1 kHz, both ends included).
pub const SAMPLES: usize = 151;
/// Sample rate, Hz.
pub const SAMPLE_RATE: f64 = 1000.0;
/// Process-noise intensity of the `noisy` variant, N·s^½·m^-½ (random forces on every segment).
pub const PROCESS_NOISE: f64 = 2.0e-5;
/// Sensor noise of the `noisy` variant as a fraction of each channel's peak-to-peak range over
/// the clean `e2` runs.
pub const SENSOR_NOISE_FRACTION: f64 = 0.05;
/// Distance range of both experiments, m.
pub const D_RANGE: [f64; 2] = [0.015, 0.030];
/// Speed range of `e2`, m/s.
pub const V_RANGE: [f64; 2] = [0.3, 1.5];
/// Speed of `e1`, m/s.
pub const E1_SPEED: f64 = 0.6;

/// One run's observations and the parameters that produced it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Sample {
    /// Observed channels, channel-major: `[CHANNELS][SAMPLES]` (theta01, theta12 in rad; m0 in
    /// N·m; fx, fy in N).
    pub series: Vec<Vec<f64>>,
    /// The unknowns: `[d]` (m) for `e1`, `[d, v]` (m, m/s) for `e2`.
    pub params: Vec<f64>,
}

/// One of the seed's two experiments.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Experiment {
    /// Distance only, v = 0.6 m/s.
    E1,
    /// Distance and speed.
    E2,
}

/// Clean runs or runs with sensor and process noise.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Variant {
    /// No noise.
    Clean,
    /// Sensor noise of 5% of each channel's clean peak-to-peak range, plus process noise.
    Noisy,
}

impl Variant {
    /// Parses `clean` or `noisy`.
    pub fn parse(name: &str) -> Result<Variant> {
        match name {
            "clean" => Ok(Variant::Clean),
            "noisy" => Ok(Variant::Noisy),
            _ => Err(Error::Unknown {
                what: "variant",
                name: name.to_string(),
                choices: "clean, noisy".into(),
            }),
        }
    }

    /// `clean` or `noisy`.
    pub fn name(self) -> &'static str {
        match self {
            Variant::Clean => "clean",
            Variant::Noisy => "noisy",
        }
    }
}

impl Experiment {
    /// Parses `e1` or `e2`.
    pub fn parse(name: &str) -> Result<Experiment> {
        match name {
            "e1" => Ok(Experiment::E1),
            "e2" => Ok(Experiment::E2),
            _ => Err(Error::Unknown {
                what: "experiment",
                name: name.to_string(),
                choices: "e1, e2".into(),
            }),
        }
    }

    /// `e1` or `e2`.
    pub fn name(self) -> &'static str {
        match self {
            Experiment::E1 => "e1",
            Experiment::E2 => "e2",
        }
    }

    /// Names of the unknowns, in the order of [`Sample::params`].
    pub fn unknowns(self) -> &'static [&'static str] {
        match self {
            Experiment::E1 => &["d"],
            Experiment::E2 => &["d", "v"],
        }
    }

    /// Speeds of the grid, m/s.
    pub fn speeds(self) -> Vec<f64> {
        match self {
            Experiment::E1 => vec![E1_SPEED],
            Experiment::E2 => vec![0.3, 0.6, 0.9, 1.2, 1.5],
        }
    }

    /// Distances of the grid, m: 15, 16, …, 30 mm.
    pub fn distances(self) -> Vec<f64> {
        (15..=30).map(|mm| mm as f64 * 1e-3).collect()
    }

    /// Every run of the grid as `(d, v)`, distance fastest.
    pub fn grid(self) -> Vec<[f64; 2]> {
        let mut g = Vec::new();
        for v in self.speeds() {
            for d in self.distances() {
                g.push([d, v]);
            }
        }
        g
    }

    /// Whether grid point `(d, v)` is a template.
    pub fn is_template(self, p: [f64; 2]) -> bool {
        let near = |x: f64, set: &[f64]| set.iter().any(|s| (x - s).abs() < 1e-9);
        let d_ok = near(p[0], &[0.015, 0.023, 0.030]);
        match self {
            Experiment::E1 => d_ok,
            Experiment::E2 => d_ok && near(p[1], &[0.3, 0.9, 1.5]),
        }
    }

    /// The unknowns of a run at `(d, v)`.
    pub fn params(self, p: [f64; 2]) -> Vec<f64> {
        match self {
            Experiment::E1 => vec![p[0]],
            Experiment::E2 => vec![p[0], p[1]],
        }
    }

    /// The range of each unknown, `[unknowns][lo, hi]`.
    pub fn ranges(self) -> Vec<[f64; 2]> {
        match self {
            Experiment::E1 => vec![D_RANGE],
            Experiment::E2 => vec![D_RANGE, V_RANGE],
        }
    }

    /// The paper's mean absolute errors, SI (`[d]` or `[d, v]`).
    pub fn paper_errors(self) -> Vec<f64> {
        match self {
            Experiment::E1 => vec![1.2e-3],
            Experiment::E2 => vec![2.0e-3, 0.28],
        }
    }

    /// `n` parameter draws, uniform in the experiment's range and never exactly on its grid.
    pub fn random_params(self, n: usize, seed: u64) -> Vec<[f64; 2]> {
        let grid = self.grid();
        let mut rng = Rng::stream(seed, 0x7261_6e64);
        let mut out = Vec::with_capacity(n);
        while out.len() < n {
            let d = D_RANGE[0] + (D_RANGE[1] - D_RANGE[0]) * rng.uniform();
            let v = match self {
                Experiment::E1 => E1_SPEED,
                Experiment::E2 => V_RANGE[0] + (V_RANGE[1] - V_RANGE[0]) * rng.uniform(),
            };
            let on_grid = grid
                .iter()
                .any(|g| (g[0] - d).abs() < 1e-7 && (g[1] - v).abs() < 1e-7);
            if !on_grid {
                out.push([d, v]);
            }
        }
        out
    }
}

/// Noise of a variant: sensor noise per channel and the process-noise intensity.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Noise {
    /// Sensor noise standard deviation per channel, `[CHANNELS]`, SI.
    pub sensor: [f64; 5],
    /// Process-noise intensity, N·s^½·m^-½.
    pub process: f64,
}

impl Noise {
    /// No noise.
    pub const NONE: Noise = Noise {
        sensor: [0.0; 5],
        process: 0.0,
    };

    /// The noise of `variant`: for `noisy`, 5% of each channel's peak-to-peak range over the 80
    /// clean `e2` runs (computed once per process) and [`PROCESS_NOISE`].
    pub fn of(variant: Variant) -> Result<Noise> {
        match variant {
            Variant::Clean => Ok(Noise::NONE),
            Variant::Noisy => {
                static LEVELS: OnceLock<[f64; 5]> = OnceLock::new();
                let sensor = match LEVELS.get() {
                    Some(l) => *l,
                    None => {
                        let l = clean_ranges()?.map(|r| SENSOR_NOISE_FRACTION * r);
                        *LEVELS.get_or_init(|| l)
                    }
                };
                Ok(Noise {
                    sensor,
                    process: PROCESS_NOISE,
                })
            }
        }
    }
}

/// Peak-to-peak range of each channel over the 80 clean `e2` runs, `[CHANNELS]`, SI.
pub fn clean_ranges() -> Result<[f64; 5]> {
    let runs = simulate_all(
        Experiment::E2,
        &Experiment::E2.grid(),
        &Noise::NONE,
        0,
        &|| {},
    )?;
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
    Ok(std::array::from_fn(|c| hi[c] - lo[c]))
}

/// Simulates one run of `experiment` at `(d, v)` with `noise`, seeded by `seed`.
pub fn simulate(experiment: Experiment, p: [f64; 2], noise: &Noise, seed: u64) -> Result<Sample> {
    simulate_delayed(experiment, p, 0.0, noise, seed)
}

/// [`simulate`] with the recording started `delay` seconds before the run's t = 0: the box
/// starts `v·delay` farther away and the series is `delay` longer (151 + 1000·delay samples).
pub fn simulate_delayed(
    experiment: Experiment,
    p: [f64; 2],
    delay: f64,
    noise: &Noise,
    seed: u64,
) -> Result<Sample> {
    let [d, v] = p;
    let mut object = e2_box(d, v);
    object.position[1] -= v * delay;
    let scenario = Scenario {
        objects: vec![object],
        duration: 0.15 + delay,
        process_noise: noise.process,
        sensor_noise: SensorNoise {
            theta01: noise.sensor[0],
            theta12: noise.sensor[1],
            m0: noise.sensor[2],
            fx: noise.sensor[3],
            fy: noise.sensor[4],
        },
        seed,
        ..Scenario::default()
    };
    let out =
        sim::run(&scenario, &mut |_| {}).map_err(|source| Error::Simulation { d, v, source })?;
    // Columns 1..=5 of the contract's rows are the observed channels.
    let series = (0..CHANNELS.len())
        .map(|c| out.rows.iter().map(|r| r[c + 1]).collect())
        .collect();
    Ok(Sample {
        series,
        params: experiment.params(p),
    })
}

/// Simulates every run of `params` in parallel; run `k` is seeded by stream `k` of `seed`.
/// `tick` is called once per finished run (from any thread).
pub fn simulate_all(
    experiment: Experiment,
    params: &[[f64; 2]],
    noise: &Noise,
    seed: u64,
    tick: &(dyn Fn() + Sync),
) -> Result<Vec<Sample>> {
    params
        .par_iter()
        .enumerate()
        .map(|(k, &p)| {
            let run_seed = Rng::stream(seed, k as u64).next_u64();
            let s = simulate(experiment, p, noise, run_seed);
            tick();
            s
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grids_and_templates_match_the_restated_experiments() {
        let e1 = Experiment::E1.grid();
        assert_eq!(e1.len(), 16);
        assert_eq!(
            e1.iter()
                .filter(|p| Experiment::E1.is_template(**p))
                .count(),
            3
        );
        let e2 = Experiment::E2.grid();
        assert_eq!(e2.len(), 80);
        assert_eq!(
            e2.iter()
                .filter(|p| Experiment::E2.is_template(**p))
                .count(),
            9
        );
    }

    #[test]
    fn random_draws_stay_in_range_and_off_the_grid() {
        for p in Experiment::E2.random_params(200, 3) {
            assert!(p[0] >= D_RANGE[0] && p[0] <= D_RANGE[1]);
            assert!(p[1] >= V_RANGE[0] && p[1] <= V_RANGE[1]);
        }
        assert_eq!(
            Experiment::E2.random_params(5, 3),
            Experiment::E2.random_params(5, 3)
        );
    }
}
