//! What every experiment shares: the observed channels, runs as samples, and the variants'
//! noise. The experiments themselves are scenario families ([`crate::Family`]).

use crate::error::{Error, Result};
use serde::Serialize;

/// Observed channels, in the order of [`Sample::series`].
pub const CHANNELS: [&str; 5] = ["theta01", "theta12", "m0", "fx", "fy"];
/// Index of `theta12` in [`CHANNELS`].
pub const THETA12: usize = 1;
/// Process-noise intensity of the `noisy` variant, N·s^½·m^-½ (random forces on every segment).
pub const PROCESS_NOISE: f64 = 2.0e-5;
/// Sensor noise of the `noisy` variant as a fraction of each channel's peak-to-peak range over
/// the clean `e2` runs.
pub const SENSOR_NOISE_FRACTION: f64 = 0.05;

/// One run's observations and the parameters that produced it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Sample {
    /// Observed channels, channel-major: `[CHANNELS][samples]` (theta01, theta12 in rad; m0 in
    /// N·m; fx, fy in N).
    pub series: Vec<Vec<f64>>,
    /// The values of the family's unknowns, in its order (`[d]` for `e1`, `[d, v]` for `e2`).
    pub params: Vec<f64>,
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
}
