//! Whole runs: a scenario (whisker, objects, base motion, noise, timing) stepped and sampled into
//! the contract's time series.

use crate::chain::Discretisation;
use crate::dynamics::{BaseMotion, Integrator};
use crate::error::{check_non_negative, check_positive, Error, Result};
use crate::objects::Object;
use crate::whisker::WhiskerParams;

/// The contract's time-series columns, in order.
pub const COLUMNS: [&str; 10] = ["t", "theta01", "theta12", "m0", "fx", "fy", "contact", "cx", "cy", "s"];

/// Prescribed rotation of the whisker's base (active whisking).
#[derive(Debug, Clone, PartialEq, Default)]
pub enum BaseDrive {
    /// The base does not move.
    #[default]
    Fixed,
    /// `angle(t) = offset + amplitude·sin(2π·frequency·t + phase)`.
    Sinusoid {
        /// Amplitude, rad.
        amplitude: f64,
        /// Frequency, Hz.
        frequency: f64,
        /// Phase, rad.
        phase: f64,
        /// Mean angle, rad.
        offset: f64,
    },
    /// Constant angular rate from `start` (s) to `stop` (s), held before and after; the corners
    /// are rounded over `smoothing` seconds (a cubic blend) so the acceleration stays finite.
    Ramp {
        /// Angular rate, rad/s.
        rate: f64,
        /// Start time, s.
        start: f64,
        /// Stop time, s (infinite: never stops).
        stop: f64,
        /// Blend duration at each corner, s.
        smoothing: f64,
    },
    /// A sampled trajectory `(t, angle)`, interpolated by cubic Hermite splines with
    /// finite-difference slopes; held constant outside its time range.
    Trajectory {
        /// Sample times, s, strictly increasing.
        t: Vec<f64>,
        /// Angles, rad.
        angle: Vec<f64>,
    },
}

/// Standard deviations of Gaussian noise added to each observed channel.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SensorNoise {
    /// On `theta01`, rad.
    pub theta01: f64,
    /// On `theta12`, rad.
    pub theta12: f64,
    /// On `m0`, N·m.
    pub m0: f64,
    /// On `fx`, N.
    pub fx: f64,
    /// On `fy`, N.
    pub fy: f64,
}

/// Everything that defines one run. Check it with [`Scenario::check`] (done by [`run`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// The whisker.
    pub whisker: WhiskerParams,
    /// Segment count N.
    pub segments: usize,
    /// Stiffness rule.
    pub discretisation: Discretisation,
    /// Time stepping (its `dt` is shortened if needed so that it divides the sample period).
    pub integrator: Integrator,
    /// Simulated time, s.
    pub duration: f64,
    /// Output samples per second, Hz (samples at t = 0, 1/rate, …, up to `duration`).
    pub sample_rate: f64,
    /// Objects.
    pub objects: Vec<Object>,
    /// Base motion.
    pub base: BaseDrive,
    /// Process-noise intensity, N·s^½·m^-½ (see [`crate::dynamics::Inputs::noise`]).
    pub process_noise: f64,
    /// Sensor noise.
    pub sensor_noise: SensorNoise,
    /// Seed of all randomness in the run.
    pub seed: u64,
}

impl Default for Scenario {
    fn default() -> Self {
        Scenario {
            whisker: WhiskerParams::w30(),
            segments: 20,
            discretisation: Discretisation::default(),
            integrator: Integrator::default(),
            duration: 0.15,
            sample_rate: 1000.0,
            objects: Vec::new(),
            base: BaseDrive::Fixed,
            process_noise: 0.0,
            sensor_noise: SensorNoise::default(),
            seed: 0,
        }
    }
}

impl BaseDrive {
    /// Angle, rate and acceleration at time `t`.
    pub fn at(&self, t: f64) -> BaseMotion {
        let _ = t;
        unimplemented!("written next")
    }

    /// Checks the drive's parameters.
    pub fn check(&self) -> Result<()> {
        Ok(())
    }
}

impl Scenario {
    /// Checks every field (objects included), naming the first bad one.
    pub fn check(&self) -> Result<()> {
        self.whisker.check()?;
        check_positive("duration", self.duration)?;
        check_positive("sample_rate", self.sample_rate)?;
        check_non_negative("process_noise", self.process_noise)?;
        let sn = &self.sensor_noise;
        for (name, x) in [
            ("sensor_noise.theta01", sn.theta01),
            ("sensor_noise.theta12", sn.theta12),
            ("sensor_noise.m0", sn.m0),
            ("sensor_noise.fx", sn.fx),
            ("sensor_noise.fy", sn.fy),
        ] {
            check_non_negative(name, x)?;
        }
        for (k, o) in self.objects.iter().enumerate() {
            o.check(&format!("objects[{k}]"))?;
        }
        self.base.check()?;
        if self.duration * self.sample_rate > 1e8 {
            return Err(Error::invalid(
                "sample_rate",
                self.sample_rate,
                "at most 1e8 samples in all (duration × sample_rate)",
            ));
        }
        Ok(())
    }
}
