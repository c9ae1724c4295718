//! Whole runs: a scenario (whisker, objects, base motion, noise, timing) stepped and sampled into
//! the contract's time series.

use crate::chain::{Discretisation, Model};
use crate::contact::ContactReport;
use crate::dynamics::{
    initialize, step, BaseMotion, Inputs, Integrator, State, Stepper, Workspace,
};
use crate::error::{check_finite, check_non_negative, check_positive, Error, Result};
use crate::objects::{bounds, closest};
use crate::objects::{Motion, Object};
use crate::rng::Rng;
use crate::sensors::Sensors;
use crate::whisker::WhiskerParams;

/// The contract's time-series columns, in order.
pub const COLUMNS: [&str; 10] = [
    "t", "theta01", "theta12", "m0", "fx", "fy", "contact", "cx", "cy", "s",
];

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

/// Linear response of one observed channel: recorded = `gain`·true + `offset` (sensor noise is
/// added after it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Response {
    /// Gain, dimensionless; finite and not 0.
    pub gain: f64,
    /// Offset, in the channel's unit (rad, N·m or N).
    pub offset: f64,
}

impl Default for Response {
    fn default() -> Self {
        Response {
            gain: 1.0,
            offset: 0.0,
        }
    }
}

impl Response {
    /// The recorded value of the true value `x`. The identity response returns `x` bit for bit
    /// (a negative zero stays negative).
    pub fn apply(&self, x: f64) -> f64 {
        if self.offset == 0.0 {
            self.gain * x
        } else {
            self.gain * x + self.offset
        }
    }

    /// Whether this is the identity (gain 1, offset 0).
    pub fn is_identity(&self) -> bool {
        self.gain == 1.0 && self.offset == 0.0
    }
}

/// Linear responses of the five observed channels (gains and offsets of the sensors).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SensorResponse {
    /// Of `theta01` (offset in rad).
    pub theta01: Response,
    /// Of `theta12` (offset in rad).
    pub theta12: Response,
    /// Of `m0` (offset in N·m).
    pub m0: Response,
    /// Of `fx` (offset in N).
    pub fx: Response,
    /// Of `fy` (offset in N).
    pub fy: Response,
}

impl SensorResponse {
    /// The responses in [`crate::sensors::CHANNELS`] order.
    pub fn to_array(&self) -> [Response; 5] {
        [self.theta01, self.theta12, self.m0, self.fx, self.fy]
    }

    /// Responses given in [`crate::sensors::CHANNELS`] order.
    pub fn from_array(r: [Response; 5]) -> Self {
        let [theta01, theta12, m0, fx, fy] = r;
        SensorResponse {
            theta01,
            theta12,
            m0,
            fx,
            fy,
        }
    }

    /// Checks that every gain is finite and not 0 and every offset finite, naming the first bad
    /// one (`sensors.m0.gain`).
    pub fn check(&self) -> Result<()> {
        self.check_at("sensors")
    }

    /// [`SensorResponse::check`] of the table at `table` (`whiskers[1].sensors`), which the
    /// message names.
    pub fn check_at(&self, table: &str) -> Result<()> {
        for (name, r) in crate::sensors::CHANNELS.iter().zip(self.to_array()) {
            if !(r.gain.is_finite() && r.gain != 0.0) {
                return Err(Error::invalid(
                    format!("{table}.{name}.gain"),
                    r.gain,
                    "a finite number other than 0",
                ));
            }
            check_finite(&format!("{table}.{name}.offset"), r.offset)?;
        }
        Ok(())
    }
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
    /// Sensor gains and offsets, applied to the true channels before the noise.
    pub sensor_response: SensorResponse,
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
            sensor_response: SensorResponse::default(),
            seed: 0,
        }
    }
}

impl BaseDrive {
    /// The fastest the base turns, rad/s, over the whole drive: a sinusoid's amplitude times its
    /// angular frequency, a ramp's rate, and a trajectory's spline's fastest, read at nine points
    /// of each interval (its rate is quadratic there, so this misses its peak by little).
    pub fn fastest_rate(&self) -> f64 {
        match self {
            BaseDrive::Fixed => 0.0,
            BaseDrive::Sinusoid {
                amplitude,
                frequency,
                ..
            } => (amplitude * 2.0 * std::f64::consts::PI * frequency).abs(),
            BaseDrive::Ramp { rate, .. } => rate.abs(),
            BaseDrive::Trajectory { t, .. } => t
                .windows(2)
                .flat_map(|w| (0..=8).map(move |k| w[0] + (w[1] - w[0]) * k as f64 / 8.0))
                .map(|x| self.at(x).rate.abs())
                .fold(0.0, f64::max),
        }
    }

    /// Angle, rate and acceleration at time `t`.
    pub fn at(&self, t: f64) -> BaseMotion {
        match self {
            BaseDrive::Fixed => BaseMotion::default(),
            BaseDrive::Sinusoid {
                amplitude,
                frequency,
                phase,
                offset,
            } => {
                let w = 2.0 * std::f64::consts::PI * frequency;
                let (s, c) = (w * t + phase).sin_cos();
                BaseMotion {
                    angle: offset + amplitude * s,
                    rate: amplitude * w * c,
                    accel: -amplitude * w * w * s,
                }
            }
            BaseDrive::Ramp {
                rate,
                start,
                stop,
                smoothing,
            } => ramp(*rate, *start, *stop, *smoothing, t),
            BaseDrive::Trajectory { t: ts, angle } => hermite(ts, angle, t),
        }
    }

    /// Checks the drive's parameters.
    pub fn check(&self) -> Result<()> {
        match self {
            BaseDrive::Fixed => Ok(()),
            BaseDrive::Sinusoid {
                amplitude,
                frequency,
                phase,
                offset,
            } => {
                check_finite("base.amplitude", *amplitude)?;
                check_non_negative("base.frequency", *frequency)?;
                check_finite("base.phase", *phase)?;
                check_finite("base.offset", *offset).map(|_| ())
            }
            BaseDrive::Ramp {
                rate,
                start,
                stop,
                smoothing,
            } => {
                check_finite("base.rate", *rate)?;
                check_finite("base.start", *start)?;
                check_non_negative("base.smoothing", *smoothing)?;
                if stop.is_nan() || *stop < start + smoothing {
                    return Err(Error::invalid(
                        "base.stop",
                        stop,
                        format!(
                            "a time >= base.start + base.smoothing = {} (or omitted)",
                            start + smoothing
                        ),
                    ));
                }
                Ok(())
            }
            BaseDrive::Trajectory { t, angle } => {
                if t.len() != angle.len() || t.len() < 2 {
                    return Err(Error::invalid(
                        "base.trajectory",
                        format!("{} times, {} angles", t.len(), angle.len()),
                        "at least two (t, angle) rows",
                    ));
                }
                for k in 0..t.len() {
                    if !(t[k].is_finite() && angle[k].is_finite()) {
                        return Err(Error::invalid(
                            format!("base.trajectory row {}", k + 1),
                            format!("({}, {})", t[k], angle[k]),
                            "finite numbers",
                        ));
                    }
                    if k > 0 && t[k] <= t[k - 1] {
                        return Err(Error::invalid(
                            format!("base.trajectory row {} t", k + 1),
                            t[k],
                            format!("a time later than the previous row's {}", t[k - 1]),
                        ));
                    }
                }
                Ok(())
            }
        }
    }
}

/// A ramp of rate `r` from `t0` to `t1` with linear-velocity blends of `tau` at both corners.
fn ramp(r: f64, t0: f64, t1: f64, tau: f64, t: f64) -> BaseMotion {
    let motion = |angle, rate, accel| BaseMotion { angle, rate, accel };
    if t <= t0 {
        return motion(0.0, 0.0, 0.0);
    }
    let a1 = if tau > 0.0 { 0.5 * r * tau } else { 0.0 };
    if tau > 0.0 && t < t0 + tau {
        let x = t - t0;
        return motion(0.5 * r * x * x / tau, r * x / tau, r / tau);
    }
    if t < t1 {
        return motion(a1 + r * (t - t0 - tau), r, 0.0);
    }
    let a2 = a1 + r * (t1 - t0 - tau);
    if tau > 0.0 && t < t1 + tau {
        let x = t - t1;
        return motion(
            a2 + r * (x - 0.5 * x * x / tau),
            r * (1.0 - x / tau),
            -r / tau,
        );
    }
    motion(a2 + a1, 0.0, 0.0)
}

/// Cubic Hermite interpolation of `(ts, ys)` with finite-difference slopes, and its first two
/// derivatives; constant outside the samples.
fn hermite(ts: &[f64], ys: &[f64], t: f64) -> BaseMotion {
    let n = ts.len();
    if t <= ts[0] {
        return BaseMotion {
            angle: ys[0],
            ..Default::default()
        };
    }
    if t >= ts[n - 1] {
        return BaseMotion {
            angle: ys[n - 1],
            ..Default::default()
        };
    }
    let k = ts.partition_point(|&x| x <= t).clamp(1, n - 1) - 1;
    let slope = |i: usize| {
        let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
        (ys[b] - ys[a]) / (ts[b] - ts[a])
    };
    let h = ts[k + 1] - ts[k];
    let x = (t - ts[k]) / h;
    let (y0, y1, m0, m1) = (ys[k], ys[k + 1], slope(k) * h, slope(k + 1) * h);
    let (x2, x3) = (x * x, x * x * x);
    let angle = (2.0 * x3 - 3.0 * x2 + 1.0) * y0
        + (x3 - 2.0 * x2 + x) * m0
        + (-2.0 * x3 + 3.0 * x2) * y1
        + (x3 - x2) * m1;
    let d1 = (6.0 * x2 - 6.0 * x) * y0
        + (3.0 * x2 - 4.0 * x + 1.0) * m0
        + (-6.0 * x2 + 6.0 * x) * y1
        + (3.0 * x2 - 2.0 * x) * m1;
    let d2 = (12.0 * x - 6.0) * y0
        + (6.0 * x - 4.0) * m0
        + (-12.0 * x + 6.0) * y1
        + (6.0 * x - 2.0) * m1;
    BaseMotion {
        angle,
        rate: d1 / h,
        accel: d2 / (h * h),
    }
}

impl Scenario {
    /// Checks every field (objects included), naming the first bad one.
    pub fn check(&self) -> Result<()> {
        self.whisker.check()?;
        if !(2..=crate::chain::MAX_SEGMENTS).contains(&self.segments) {
            return Err(Error::invalid(
                "segments",
                self.segments,
                format!("an integer from 2 to {}", crate::chain::MAX_SEGMENTS),
            ));
        }
        self.integrator.check()?;
        check_positive("duration", self.duration)?;
        check_positive("sample_rate", self.sample_rate)?;
        if self.sample_rate > MAX_SAMPLE_RATE {
            return Err(Error::invalid(
                "sample_rate",
                self.sample_rate,
                format!(
                    "at most {MAX_SAMPLE_RATE:e} Hz (a sample period of at least 1 µs; every \
                     sample takes at least one step)"
                ),
            ));
        }
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
        self.sensor_response.check()?;
        for (k, o) in self.objects.iter().enumerate() {
            o.check(&format!("objects[{k}]"))?;
        }
        self.base.check()?;
        let samples = self.duration * self.sample_rate;
        if samples > MAX_SAMPLES {
            return Err(Error::invalid(
                "duration",
                self.duration,
                format!(
                    "at most {MAX_SAMPLES:e} samples in all (duration × sample_rate = {samples:e})"
                ),
            ));
        }
        if samples < 1.0 {
            return Err(Error::invalid(
                "duration",
                self.duration,
                format!(
                    "at least two samples: duration × sample_rate ≥ 1 (here {samples}; \
                     sample_rate = {} Hz)",
                    self.sample_rate
                ),
            ));
        }
        // Every sample period takes at least one step, and steps no longer than `dt`.
        let steps = self.duration / self.integrator.dt.min(1.0 / self.sample_rate);
        if steps > MAX_STEPS {
            return Err(Error::invalid(
                "dt",
                self.integrator.dt,
                format!(
                    "at most {MAX_STEPS:e} steps in all (duration / dt = {steps:.3e}; a run that \
                     long would take many minutes): shorten the duration or lengthen the step"
                ),
            ));
        }
        self.check_contact_step()
    }

    /// Refuses a time step at which an object moves farther in one contact step
    /// (`dt / contact_substeps`, `dt` shortened to divide the sample period) than its own least
    /// width, or farther across the whisker's plane than its vertical extent
    /// ([`Object::longest_contact_step`], with the whisker's tip sweeping at the base drive's
    /// fastest rate times its length): contact with it would last less than a step. The error
    /// names the largest `dt` that resolves it.
    fn check_contact_step(&self) -> Result<()> {
        let (stepper, _, _) = timing(self)?;
        let substeps = self.integrator.contact_substeps;
        let step = stepper.dt / substeps as f64;
        // The whisker's tip sweeps at the base's fastest rate times its length.
        let sweep = self.base.fastest_rate() * self.whisker.length;
        for (k, o) in self.objects.iter().enumerate() {
            let Some(limit) = o.step_limit(sweep) else {
                continue;
            };
            let longest = limit.longest();
            if step <= longest * (1.0 + 1e-9) {
                continue;
            }
            let (size, speed) = (limit.size, limit.speed);
            let what = if limit.across_plane {
                format!("{:.3} mm tall, crossing the whisker's plane at", size * 1e3)
            } else if sweep > 0.0 {
                format!(
                    "{:.3} mm across at its narrowest, and it and the whisker's tip (the base \
                     turning at up to {:.3} rad/s) close at up to",
                    size * 1e3,
                    self.base.fastest_rate()
                )
            } else {
                format!(
                    "{:.3} mm across at its narrowest, its outline moving at up to",
                    size * 1e3
                )
            };
            return Err(Error::invalid(
                "dt",
                self.integrator.dt,
                format!(
                    "a step at which objects[{k}] is resolved: it is {what} {speed:.3} m/s, so in \
                     one contact step of {step:.3e} s it moves {:.3} mm, more than its own {:.3} \
                     mm: contact with it would last less than a step and not be resolved. The \
                     largest dt that resolves it is {:.3e} s with contact_substeps = {substeps}{}",
                    speed * step * 1e3,
                    size * 1e3,
                    longest * substeps as f64,
                    match crate::dynamics::equal_steps(stepper.dt, longest) {
                        n if n <= crate::dynamics::MAX_CONTACT_SUBSTEPS => {
                            format!("; or keep dt and set contact_substeps = {n}")
                        }
                        _ => String::new(),
                    },
                ),
            ));
        }
        Ok(())
    }
}

/// One run's output: rows of [`COLUMNS`] at the sample times, and how it was computed.
#[derive(Debug, Clone, PartialEq)]
pub struct Output {
    /// Rows `[t, theta01, theta12, m0, fx, fy, contact, cx, cy, s]`.
    pub rows: Vec<[f64; 10]>,
    /// Segment count.
    pub segments: usize,
    /// Time step actually used, s (the requested one shortened to divide the sample period).
    pub dt: f64,
    /// Steps taken.
    pub steps: usize,
    /// Largest penetration of the whisker's surface into an object at the end of any step in
    /// contact, m.
    pub max_penetration: f64,
}

/// Most samples of one run (a CSV of about 3 GB).
pub const MAX_SAMPLES: f64 = 2e7;

/// Most time steps of one run (a few minutes of computing at a million steps per second).
pub const MAX_STEPS: f64 = 2e8;

/// Highest output sample rate, Hz: every sample period takes at least one step, and whisker
/// recordings are sampled at kilohertz, not megahertz.
pub const MAX_SAMPLE_RATE: f64 = 1e6;

/// Object speed above which a divergence is put down to the objects, m/s: whiskers meet objects
/// at centimetres to metres per second.
const FAST_OBJECT: f64 = 50.0;

/// Process-noise intensity above which a divergence is put down to the random forces: the
/// experiments use 2e-5 N·s^½·m^-½.
const STRONG_PROCESS_NOISE: f64 = 1e-2;

/// A divergence of `scenario`'s run with its likely cause added: an object far faster than a
/// whisker is ever struck, random forces far stronger than the experiments', or else the step.
fn explain_divergence(e: Error, scenario: &Scenario, dt: f64) -> Error {
    let Error::Diverged { t, detail } = e else {
        return e;
    };
    let speed = |o: &Object| match &o.motion {
        Motion::Constant { velocity, .. } => velocity[0].hypot(velocity[1]),
        Motion::Waypoints { points } => points
            .windows(2)
            .map(|w| (w[1][1] - w[0][1]).hypot(w[1][2] - w[0][2]) / (w[1][0] - w[0][0]))
            .fold(0.0, f64::max),
    };
    let fastest = scenario
        .objects
        .iter()
        .enumerate()
        .map(|(k, o)| (k, speed(o)))
        .max_by(|a, b| a.1.total_cmp(&b.1));
    let cause = match fastest {
        Some((k, v)) if v > FAST_OBJECT => format!(
            "objects[{k}] moves at {} m/s, far faster than a whisker is ever struck (below \
             about 10 m/s); give its speed in m/s",
            crate::error::readable(v)
        ),
        _ if scenario.process_noise > STRONG_PROCESS_NOISE => format!(
            "process_noise = {} N·s^½·m^-½ pushes the whisker far harder than any experiment \
             (2e-5); lower it",
            crate::error::readable(scenario.process_noise)
        ),
        _ => match step_that_runs(scenario, t, dt) {
            Some(works) => format!(
                "the time step dt = {} s is too long for this run; the longest of its halves, \
                 quarters, … that runs to t = {} s is dt = {} s (`--set dt={}`)",
                crate::error::readable(dt),
                crate::error::readable(probe_end(scenario, t)),
                crate::error::readable(works),
                works
            ),
            None => format!(
                "the time step dt = {} s may be too long for this whisker, but no step down to \
                 {} s runs past t = {} s either: look at the objects' motion and the base's",
                crate::error::readable(dt),
                crate::error::readable(dt / (1u64 << PROBE_HALVINGS) as f64),
                crate::error::readable(probe_end(scenario, t))
            ),
        },
    };
    Error::Diverged {
        t,
        detail: format!("{detail}; likely cause: {cause}"),
    }
}

/// How many times [`step_that_runs`] halves a step that diverged.
const PROBE_HALVINGS: u32 = 6;

/// Most steps [`step_that_runs`] spends on one probe: beyond it the search stops (an error's
/// explanation must not take minutes).
const PROBE_MAX_STEPS: f64 = 5e6;

/// Where a probe of a run that diverged at `t` ends: half as far again past the failure and at
/// least 10 ms past it, within the run.
fn probe_end(scenario: &Scenario, t: f64) -> f64 {
    (1.5 * t).max(t + 0.01).min(scenario.duration)
}

/// The longest of `dt/2`, `dt/4`, … (down to `dt/2^PROBE_HALVINGS`) at which `scenario` runs
/// without diverging past [`probe_end`] of the time `t` at which `dt` diverged, if any: what a
/// refused step is told to use instead.
fn step_that_runs(scenario: &Scenario, t: f64, dt: f64) -> Option<f64> {
    let end = probe_end(scenario, t);
    (1..=PROBE_HALVINGS)
        .map(|k| dt / (1u64 << k) as f64)
        .take_while(|h| end / h <= PROBE_MAX_STEPS)
        .find(|&h| {
            let mut probe = scenario.clone();
            probe.duration = end;
            probe.integrator.dt = h;
            run_steps(&probe, &mut |_| {}, None, false).is_ok()
        })
}

pub use crate::sim_many::{run_many, run_together};

/// Runs `scenario`, calling `progress` with the fraction done now and then.
pub fn run(scenario: &Scenario, progress: &mut dyn FnMut(f64)) -> Result<Output> {
    run_observed(scenario, progress, None)
}

/// The whisker at one output sample, as [`run_observed`] shows it.
#[derive(Debug, Clone, Copy)]
pub struct Snapshot<'a> {
    /// Sample index.
    pub k: usize,
    /// Sample time, s.
    pub t: f64,
    /// Node positions of the whisker, base first, world frame, m (`[N+1]`).
    pub nodes: &'a [[f64; 2]],
}

/// [`run`], showing the whisker's shape at every output sample to `observe` (for animations).
/// The shape is computed in a workspace of its own, so the run's output is [`run`]'s, bit for
/// bit.
pub fn run_observed(
    scenario: &Scenario,
    progress: &mut dyn FnMut(f64),
    observe: Option<&mut dyn FnMut(Snapshot<'_>)>,
) -> Result<Output> {
    run_steps(scenario, progress, observe, true)
}

/// [`run_observed`]; with `explain`, a divergence is returned with its likely cause, and a step
/// that was too long with the longest shorter one that runs ([`step_that_runs`]).
fn run_steps(
    scenario: &Scenario,
    progress: &mut dyn FnMut(f64),
    mut observe: Option<&mut dyn FnMut(Snapshot<'_>)>,
    explain: bool,
) -> Result<Output> {
    scenario.check()?;
    let whisker = scenario.whisker.check()?;
    let model = Model::new(&whisker, scenario.segments, scenario.discretisation)?;
    let period = 1.0 / scenario.sample_rate;
    let (stepper, per_sample, samples) = timing(scenario)?;

    // The whisker at rest, clear of every object.
    let mut state = State::at_rest(&model, scenario.seed);
    let mut ws = Workspace::new(&model);
    let base0 = scenario.base.at(0.0);
    state.base = base0;
    let mut inputs = Inputs {
        base: base0,
        loads: &[],
        noise: scenario.process_noise,
        objects: &scenario.objects,
    };
    initialize(&model, &mut state, &inputs, &mut ws)?;
    check_clear(&model, &ws, &scenario.objects, 0.0)?;

    let mut sensor_rng = Rng::stream(scenario.seed, 1);
    let mut rows = Vec::with_capacity(samples);
    let mut max_penetration = 0.0f64;
    let mut steps = 0;
    let mut shape = observe.as_ref().map(|_| Workspace::new(&model));
    for k in 0..samples {
        // The last contact of the steps since the previous sample: a contact held through the
        // sample period can carry no force in the very step that ends it (the method's force
        // then rests on the steps before), and is still a contact.
        let mut touched = None;
        if k > 0 {
            for j in 1..=per_sample {
                let t = ((k - 1) * per_sample + j) as f64 * stepper.dt;
                inputs.base = scenario.base.at(t);
                let entering = entering(&scenario.objects, state.t, t);
                step(&model, &stepper, &mut state, &inputs, &mut ws).map_err(|e| {
                    if explain {
                        explain_divergence(e, scenario, stepper.dt)
                    } else {
                        e
                    }
                })?;
                steps += 1;
                if entering {
                    ws.evaluate(&model, &state);
                    check_clear(&model, &ws, &scenario.objects, state.t)?;
                }
                if state.contact.is_some() {
                    let p = penetration(&model, &state, &mut ws, &scenario.objects);
                    max_penetration = max_penetration.max(p);
                    touched = state.contact;
                }
            }
        }
        if let (Some(observe), Some(ws)) = (observe.as_mut(), shape.as_mut()) {
            ws.evaluate(&model, &state);
            observe(Snapshot {
                k,
                t: k as f64 * period,
                nodes: ws.nodes(),
            });
        }
        rows.push(sample(
            &state,
            state.contact.or(touched),
            k as f64 * period,
            &scenario.sensor_noise,
            &scenario.sensor_response,
            &mut sensor_rng,
        ));
        if k % 64 == 0 {
            progress(k as f64 / samples as f64);
        }
    }
    progress(1.0);
    Ok(Output {
        rows,
        segments: model.n,
        dt: stepper.dt,
        steps,
        max_penetration,
    })
}

/// A run's stepping: the time step (the scenario's, shortened to divide the sample period), the
/// steps per sample period, and the number of output samples.
pub(crate) fn timing(scenario: &Scenario) -> Result<(Stepper, usize, usize)> {
    let period = 1.0 / scenario.sample_rate;
    let per_sample = (period / scenario.integrator.dt * (1.0 - 1e-12))
        .ceil()
        .max(1.0) as usize;
    let stepper = Integrator {
        dt: period / per_sample as f64,
        ..scenario.integrator
    }
    .check()?;
    let samples = (scenario.duration * scenario.sample_rate + 1e-9).floor() as usize + 1;
    Ok((stepper, per_sample, samples))
}

/// The contract's row for `state` at sample time `t`, through the sensors' gains and offsets,
/// with sensor noise; `contact` is the last contact since the previous sample.
pub(crate) fn sample(
    state: &State,
    contact: Option<ContactReport>,
    t: f64,
    noise: &SensorNoise,
    response: &SensorResponse,
    rng: &mut Rng,
) -> [f64; 10] {
    let s = Sensors::read(state);
    let mut add = |x: f64, r: &Response, sd: f64| {
        let y = r.apply(x);
        if sd > 0.0 {
            y + sd * rng.normal()
        } else {
            y
        }
    };
    let r = response;
    let (theta01, theta12) = (
        add(s.theta01, &r.theta01, noise.theta01),
        add(s.theta12, &r.theta12, noise.theta12),
    );
    let (m0, fx, fy) = (
        add(s.m0, &r.m0, noise.m0),
        add(s.fx, &r.fx, noise.fx),
        add(s.fy, &r.fy, noise.fy),
    );
    let (contact, cx, cy, arc) = match contact {
        Some(c) => {
            // The contact point in the (possibly rotated) base frame.
            let (sn, cs) = state.base.angle.sin_cos();
            let p = c.point;
            (1.0, cs * p[0] + sn * p[1], -sn * p[0] + cs * p[1], c.s)
        }
        None => (0.0, f64::NAN, f64::NAN, f64::NAN),
    };
    [t, theta01, theta12, m0, fx, fy, contact, cx, cy, arc]
}

/// Whether an object enters the whisker's plane within the step from `t0` to `t1`.
pub(crate) fn entering(objects: &[Object], t0: f64, t1: f64) -> bool {
    objects.iter().any(|o| !o.in_plane(t0) && o.in_plane(t1))
}

/// Refuses objects in the whisker's plane that overlap the whisker at time `t` (the start, or
/// when an object enters the plane: a planar whisker cannot be struck from out of its plane).
pub(crate) fn check_clear(model: &Model, ws: &Workspace, objects: &[Object], t: f64) -> Result<()> {
    for (k, o) in objects.iter().enumerate() {
        if !o.in_plane(t) {
            continue;
        }
        let pose = o.pose(t);
        for i in 0..model.n {
            let nodes = ws.nodes();
            let c = closest(&o.shape, &pose, nodes[i], nodes[i + 1]);
            let r = model.radius[i] + c.u * (model.radius[i + 1] - model.radius[i]);
            if c.distance < r {
                return Err(if t == 0.0 {
                    Error::invalid(
                        format!("objects[{k}]"),
                        format!(
                            "an object overlapping the whisker at t = 0 (segment {i}, gap {:.3e} m)",
                            c.distance - r
                        ),
                        "objects clear of the whisker's surface at t = 0",
                    )
                } else {
                    Error::invalid(
                        format!("objects[{k}].vertical"),
                        format!(
                            "an object entering the whisker's plane on the whisker at t = {t:.4} \
                             s (segment {i}, gap {:.3e} m)",
                            c.distance - r
                        ),
                        "objects that enter the plane clear of the whisker (a planar whisker \
                         cannot be struck from above or below)",
                    )
                });
            }
        }
    }
    Ok(())
}

/// Deepest penetration of the whisker's surface into any object at the state's configuration
/// and time, m (0 when clear).
pub fn penetration(model: &Model, state: &State, ws: &mut Workspace, objects: &[Object]) -> f64 {
    ws.evaluate(model, state);
    let nodes = ws.nodes();
    let mut worst = 0.0f64;
    for o in objects.iter().filter(|o| o.in_plane(state.t)) {
        let pose = o.pose(state.t);
        let ob = bounds(&o.shape, &pose);
        for i in 0..model.n {
            // A segment whose bounding box is farther than its radius from the object's cannot
            // reach into it (it would only lower the maximum below zero).
            let (a, b) = (nodes[i], nodes[i + 1]);
            let r = model.radius[i].max(model.radius[i + 1]);
            if a[0].min(b[0]) > ob[2] + r
                || a[0].max(b[0]) < ob[0] - r
                || a[1].min(b[1]) > ob[3] + r
                || a[1].max(b[1]) < ob[1] - r
            {
                continue;
            }
            let c = closest(&o.shape, &pose, nodes[i], nodes[i + 1]);
            let r = model.radius[i] + c.u * (model.radius[i + 1] - model.radius[i]);
            worst = worst.max(r - c.distance);
        }
    }
    worst
}
