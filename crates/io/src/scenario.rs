//! Scenario files: TOML in, [`vibrissa_core::sim::Scenario`] out.
//!
//! A scenario is named by [`load`] as a built-in (`e1`, `e2`: the seed's experiments, see
//! docs/experiments.md) or as the path of a TOML file. Built-ins are TOML text too ([`builtin`]), read
//! by the same parser. `key=value` overrides (`--set` on the command line) are applied to the
//! document before it is read, so they obey the same schema.
//!
//! # File schema
//!
//! All quantities are SI (m, s, rad, Hz, Pa, kg/m³, N·m/rad). Every key is optional unless
//! marked; an absent key keeps the value of [`Scenario::default`] (the `w30` whisker, 20
//! segments, Gregory stiffness, dt = 1e-4 s and core's other integrator defaults, 150 ms at
//! 1 kHz, no objects, a fixed base, no noise, seed 0). Unknown keys are errors.
//!
//! ```toml
//! # A built-in experiment family: generates the box from d and v (and `objects` may add more).
//! experiment = "e2"          # "e1" | "e2"
//! d = 0.020                  # m, near edge of the box from the base along x (default 0.020)
//! v = 0.6                    # m/s, box speed along +y (default 0.6)
//!
//! duration = 0.15            # s, simulated time
//! sample_rate = 1000         # Hz, output samples (t = 0, 1/rate, … up to duration)
//! dt = 1e-4                  # s, integrator step
//! rho_inf = 0.99             # integrator: high-frequency spectral radius, [0.5, 1]
//! contact_rho_inf = 0.8      # integrator: the same for steps that begin in lasting contact
//!                            # (docs/contact.md, "The force of a tip held against a face")
//! tolerance = 1e-5           # integrator: geometric tolerance, rad
//! max_iterations = 6         # integrator: most geometric iterations per step, 1..=20
//! contact_substeps = 1       # integrator: substeps of a step near contact, 1..=1000 (1: none;
//!                            # e.g. dt = 1e-3 with 20; see docs/contact.md, "Long time steps")
//! fit_first_mode = false     # integrator: whole steps on a chain whose first mode rings at its
//!                            # own frequency at this dt (true | false; docs/contact.md)
//! hold_contacts = false      # integrator: keep a contact that carried force while it is still
//!                            # closing, instead of letting it flicker (docs/contact.md,
//!                            # "Held contacts")
//! segments = 20              # segment count N
//! discretisation = "gregory" # "gregory" | "trapezoid" | "seed"
//! process_noise = 0.0        # N·s^½·m^-½, random forces on every segment
//! seed = 1                   # seed of all randomness
//!
//! [whisker]                  # a preset, then any field overrides it
//! preset = "w30"             # "w30" | "rat" | "robot" (default: w30)
//! length = 0.030             # m
//! base_radius = 1e-4         # m
//! tip_radius = 1e-4          # m (< base_radius: conical taper)
//! rest_curvature = 0.0       # 1/m, counter-clockwise positive
//! youngs_modulus = 3.0e9     # Pa
//! density = 1100.0           # kg/m³
//! follicle = { kind = "clamped" }
//! # follicle = { kind = "spring", stiffness = 2e-5, damping = 1e-8 }   # N·m/rad, N·m·s/rad
//! damping = { kind = "modal_ratio", ratio = 0.05 }
//! # damping = { kind = "segment_q", q = 10.0 } | { kind = "stiffness_proportional", beta = 1e-4 }
//! # damping = { kind = "none" }
//!
//! [sensor_noise]             # standard deviation of Gaussian noise per observed channel
//! theta01 = 0.0              # rad (also theta12; m0 in N·m; fx, fy in N); a channel not named
//!                            # is 0 in a run, and estimators estimate it from the recordings
//!
//! [sensors]                  # gains and offsets: recorded = gain·true + offset (+ noise)
//! theta01 = { gain = 1.0, offset = 0.0 }  # gain finite and not 0 (default 1), offset in the
//!                            # channel's unit (default 0); also theta12, m0, fx, fy
//!
//! [calibration]              # written by `vibrissa calibrate`; a record, no effect on the run
//! labelled = "calib"         # the folder of labelled recordings fitted (relative to this
//!                            # file's directory, or absolute); training reads its residuals
//! recordings = 9             # how many
//! rms_before = { theta01 = 1.2e-2, m0 = 3.1e-6 }  # residual RMS per channel, nominal scenario
//! rms_after = { theta01 = 4.0e-4, m0 = 2.2e-7 }   # the same, fitted scenario
//! noise = { theta01 = 4.0e-4, m0 = 2.2e-7 }       # sensor noise sd per channel, as estimated
//! [[calibration.parameters]] # one entry per parameter the fit considered
//! key = "whisker.youngs_modulus"  # the scenario key it sets (or `time_offset`, s)
//! nominal = 3.3e9            # value in the nominal scenario
//! value = 3.05e9             # value in this file (the nominal one if not determined)
//! std_error = 2.1e7          # standard error, same unit (absent if not determined)
//! determined = true          # false: the recordings did not determine it; held
//! note = "..."               # optional: why it was held, how to read it
//! [calibration.correlation]  # correlations of the determined parameters' errors
//! keys = ["whisker.youngs_modulus", "whisker.density"]  # determined parameters' keys
//! matrix = [[1.0, 0.95], [0.95, 1.0]]  # symmetric, ones on the diagonal, entries in [-1, 1]
//!
//! [base]                     # prescribed base rotation (active whisking)
//! kind = "sinusoid"          # required: "fixed" | "sinusoid" | "ramp" | "trajectory"
//! amplitude = 0.3            # sinusoid (required), rad: offset + amplitude·sin(2π·frequency·t + phase)
//! frequency = 8.0            # sinusoid (required), Hz
//! phase = 0.0                # sinusoid, rad
//! offset = 0.0               # sinusoid, rad
//! # ramp: rate (required, rad/s), start = 0 s, stop = inf s, smoothing = 0.005 s
//! # trajectory: file = "whisk.csv" (required): CSV with the header `t,angle`, finite values,
//! #             strictly increasing t; the path is relative to the scenario file's folder
//!
//! [[objects]]                # any number of rigid objects
//! shape = "box"              # required: "box" | "circle" | "wall" | "polygon" | "square" | "triangle"
//! width = 0.01               # box (required), m, along the object's x
//! height = 0.01              # box (required), m, along the object's y
//! # circle: radius (required); wall: no keys (the half-plane y <= 0 of the object's frame);
//! # polygon: vertices = [[x, y], ...] (required; convex, counter-clockwise)
//! # square: side (required, m): a box with width = height = side
//! # triangle: side (required, m): equilateral, centred on its centroid, one vertex on the
//! #           object's +y axis (turn it with angle)
//! position = [0.025, -0.006] # m, the object's frame at t = 0 (required without waypoints)
//! angle = 0.0                # rad
//! friction = 0.0             # Coulomb coefficient against the whisker
//! velocity = [0.0, 0.6]      # m/s, constant
//! angular_velocity = 0.0     # rad/s, constant
//! # or, instead of position, angle, velocity and angular_velocity:
//! # waypoints = [[t, x, y, angle], ...]   # piecewise-linear path, times strictly increasing
//!
//! # A scenario family: the keys an estimator infers. Each key is any numeric key above,
//! # dotted as for --set (quote it or nest it: whisker.youngs_modulus = [2.4e9, 3.6e9]).
//! [unknowns]
//! d = [0.015, 0.030]                                   # range [lo, hi], SI
//! v = { range = [0.3, 1.5], margin = [0.1, 0.1] }      # and how far training may reach beyond it
//!                                                      # ([below, above]; default 1/12 of the width)
//! "objects.0.position.0" = { range = [0.018, 0.030], name = "x" }
//!                            # name: what it is reported by (default: its key); 1 to 32 ASCII
//!                            # letters, digits, _ . -, distinct, and no other unknown's key
//! [templates]                # values per unknown, by key or name; the runs under the paper's
//! d = [0.015, 0.023, 0.030]  # budget are every combination (default: each range's ends and middle)
//! v = [0.3, 0.9, 1.5]
//! x = [0.018, 0.024, 0.030]  # the unknown named x (or "objects.0.position.0" = [...], not both)
//! [grid]                     # values per unknown that `vibrissa experiment` scores, every
//! d = [0.015, 0.020, 0.025]  # combination (default: 6 evenly spaced values per range)
//! v = [0.3, 0.9, 1.5]
//! x = [0.020, 0.025, 0.030]
//! ```
//!
//! With `experiment`, the box ([`experiment_box`]) is appended after the file's own objects, so
//! those keep their indices. `e1` and `e2` generate the same box; they differ in their
//! `[unknowns]` (`d`; `d` and `v`).
//!
//! [`open`] also returns the parsed [`Document`], whose [`Document::with_values`] makes the run
//! at any values of the family's unknowns: the file with those keys set, read by this same
//! schema.
//!
//! # Errors
//!
//! A syntax error, an unknown key or a wrong type is reported with the file's name and the
//! parser's line, column, offending text and expectation (after overrides, the key path instead
//! of a line). A key given to a kind that does not take it names the key and the kind's keys; a
//! value out of range is core's [`Scenario::check`] verdict, prefixed with the file's name.

mod adopt;
mod calibration;
mod classes;
mod document;
mod family;
mod overrides;
mod schema;

pub use adopt::{WhiskerSource, WhiskerSources, WHISKER_KEYS};
pub use calibration::{CalibratedParameter, Calibration, ChannelValues, Correlation};
pub use classes::read_classes;
pub use document::Document;
pub use family::{FamilySpec, UnknownSpec, DEFAULT_GRID_COUNT, DEFAULT_MARGIN_FRACTION};

use crate::error::{Error, Result};
use crate::series::parse_csv;
use serde::Deserialize;
use std::path::Path;
use vibrissa_core::objects::{Motion, Object, Shape};
use vibrissa_core::sim::Scenario;

/// Names of the built-in scenarios.
pub const BUILTINS: [&str; 2] = ["e1", "e2"];

/// Default near-edge distance of the experiments' box, m.
pub const DEFAULT_D: f64 = 0.020;

/// Default speed of the experiments' box, m/s.
pub const DEFAULT_V: f64 = 0.6;

/// Side of the experiments' square box, m.
pub const BOX_SIDE: f64 = 0.010;

/// Gap between the experiments' box and the whisker at t = 0, m.
pub const BOX_GAP: f64 = 0.001;

/// The seed's experiment families (docs/experiments.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Experiment {
    /// Distance only: the box's speed is known.
    E1,
    /// Distance and speed.
    E2,
}

impl Experiment {
    /// The family's name (`e1`, `e2`).
    pub fn name(self) -> &'static str {
        match self {
            Experiment::E1 => "e1",
            Experiment::E2 => "e2",
        }
    }
}

/// An experiment family with its parameter values, as a scenario file set them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExperimentRun {
    /// The family.
    pub experiment: Experiment,
    /// Near-edge distance of the box from the base along x, m.
    pub d: f64,
    /// Box speed along +y, m/s.
    pub v: f64,
}

/// A loaded scenario with what the file said about it beyond the [`Scenario`].
#[derive(Debug, Clone, PartialEq)]
pub struct Loaded {
    /// The checked scenario.
    pub scenario: Scenario,
    /// The experiment family and parameters, if the file named one.
    pub experiment: Option<ExperimentRun>,
    /// The file's unknowns, templates and grid, if it has an `[unknowns]` table.
    pub family: Option<FamilySpec>,
    /// The file's path or the built-in's name, as used in messages.
    pub origin: String,
    /// The file's `[calibration]` record, if it has one.
    pub calibration: Option<Calibration>,
    /// The sensor noise the file states per channel (`theta01`, `theta12`, `m0`, `fx`, `fy`):
    /// `Some` for each channel its `[sensor_noise]` table names (validated: finite, >= 0).
    /// Estimators take a stated channel's noise as given and estimate the others from the
    /// recordings.
    pub stated_sensor_noise: [Option<f64>; 5],
    /// The file's `[[whiskers]]`: an array of whiskers, each run in its own frame against the
    /// objects (empty: the one whisker of `scenario`, at the origin).
    pub whiskers: Vec<vibrissa_core::array::Mount>,
}

/// TOML text of the built-in `e1`.
const E1: &str = r#"# The seed's experiment e1 (distance only): the w30 whisker struck by a 10 mm square box
# moving along +y at v; the box's near edge is at x = d, its top 1 mm below the whisker.
experiment = "e1"
d = 0.020
v = 0.6
duration = 0.15
sample_rate = 1000
dt = 1e-4
segments = 20

[whisker]
preset = "w30"

# What an estimator infers, with the range it covers and how far training runs may reach
# beyond it ([below, above], m: above 30 mm the box misses the whisker).
[unknowns]
d = { range = [0.015, 0.030], margin = [0.001, 0.0] }

# The paper's three templates, and the 16 runs the experiment scores.
[templates]
d = [0.015, 0.023, 0.030]

[grid]
d = [0.015, 0.016, 0.017, 0.018, 0.019, 0.020, 0.021, 0.022, 0.023, 0.024, 0.025, 0.026, 0.027, 0.028, 0.029, 0.030]
"#;

/// TOML text of the built-in `e2`.
const E2: &str = r#"# The seed's experiment e2 (distance and speed): the w30 whisker struck by a 10 mm square box
# moving along +y at v; the box's near edge is at x = d, its top 1 mm below the whisker.
experiment = "e2"
d = 0.020
v = 0.6
duration = 0.15
sample_rate = 1000
dt = 1e-4
segments = 20

[whisker]
preset = "w30"

# What an estimator infers, with the range it covers and how far training runs may reach
# beyond it ([below, above]; m and m/s: above 30 mm the box misses the whisker).
[unknowns]
d = { range = [0.015, 0.030], margin = [0.001, 0.0] }
v = { range = [0.3, 1.5], margin = [0.1, 0.1] }

# The paper's nine templates (every combination), and the 80 runs the experiment scores.
[templates]
d = [0.015, 0.023, 0.030]
v = [0.3, 0.9, 1.5]

[grid]
d = [0.015, 0.016, 0.017, 0.018, 0.019, 0.020, 0.021, 0.022, 0.023, 0.024, 0.025, 0.026, 0.027, 0.028, 0.029, 0.030]
v = [0.3, 0.6, 0.9, 1.2, 1.5]
"#;

/// The TOML text of a built-in scenario (see [`BUILTINS`]).
pub fn builtin(name: &str) -> Option<&'static str> {
    match name {
        "e1" => Some(E1),
        "e2" => Some(E2),
        _ => None,
    }
}

/// The unknowns, templates and grid of a built-in experiment, from its text.
pub(crate) fn builtin_family(experiment: Experiment) -> Result<FamilySpec> {
    let text = builtin(experiment.name()).unwrap_or_default();
    let (_, loaded) = parse(text, experiment.name(), Path::new(""), &[])?;
    Ok(loaded.family.unwrap_or_default())
}

/// The experiments' box: 10 mm × 10 mm, frictionless, its top-left corner at (d, −1 mm) at
/// t = 0 (centre at (d + 5 mm, −6 mm)), moving along +y at `v`.
pub fn experiment_box(d: f64, v: f64) -> Object {
    Object {
        shape: Shape::Box {
            width: BOX_SIDE,
            height: BOX_SIDE,
        },
        position: [d + 0.5 * BOX_SIDE, -BOX_GAP - 0.5 * BOX_SIDE],
        angle: 0.0,
        motion: Motion::Constant {
            velocity: [0.0, v],
            angular_velocity: 0.0,
        },
        friction: 0.0,
        vertical: None,
    }
}

/// Loads a scenario: `spec` is a built-in name ([`BUILTINS`]) or the path of a TOML file, and
/// `sets` are `key=value` overrides applied in order (`whisker.length=0.04`,
/// `objects.0.friction=0.3`, `d=0.023`; values are TOML, or bare strings).
pub fn load(spec: &str, sets: &[String]) -> Result<Scenario> {
    load_full(spec, sets).map(|l| l.scenario)
}

/// As [`load`], and also returns the experiment family and the scenario's origin.
pub fn load_full(spec: &str, sets: &[String]) -> Result<Loaded> {
    open(spec, sets).map(|(_, loaded)| loaded)
}

/// As [`load_full`], and also returns the parsed [`Document`], from which the scenario at any
/// values of its unknowns is made. Every unknown's key is checked by setting it to the middle
/// of its range.
pub fn open(spec: &str, sets: &[String]) -> Result<(Document, Loaded)> {
    let (doc, loaded) = open_unchecked(spec, sets)?;
    checked_family(doc, loaded)
}

/// As [`open`], for a scenario given as TOML text; `origin` names it in errors, and relative
/// paths in it are taken from `origin`'s folder.
pub fn open_str(text: &str, origin: &str, sets: &[String]) -> Result<(Document, Loaded)> {
    let dir = Path::new(origin).parent().unwrap_or(Path::new(""));
    let (doc, loaded) = parse(text, origin, dir, sets)?;
    checked_family(doc, loaded)
}

/// As [`open`] or [`open_str`] (`text` given), with the whiskers of `whisker`, if any, given to
/// the scenario's whiskers before `sets` are applied ([`Document::adopt_all`]).
pub fn open_adopting(
    spec: &str,
    text: Option<&str>,
    sets: &[String],
    whisker: Option<&WhiskerSources>,
) -> Result<(Document, Loaded)> {
    let mut doc = match text {
        Some(text) => {
            let dir = Path::new(spec).parent().unwrap_or(Path::new(""));
            Document::parse(text, spec, dir, &[])?
        }
        None => Document::load(spec, &[])?,
    };
    if let Some(whisker) = whisker {
        doc.adopt_all(whisker)?;
    }
    for set in sets {
        doc.set(set)?;
    }
    let loaded = doc.loaded()?;
    checked_family(doc, loaded)
}

/// A family's scenario must simulate at the middle of its unknowns' ranges.
fn checked_family(doc: Document, loaded: Loaded) -> Result<(Document, Loaded)> {
    if let Some(family) = &loaded.family {
        let mid: Vec<(&str, f64)> = family
            .unknowns
            .iter()
            .map(|u| (u.key.as_str(), 0.5 * (u.range[0] + u.range[1])))
            .collect();
        doc.with_values(&mid)?;
    }
    Ok((doc, loaded))
}

fn open_unchecked(spec: &str, sets: &[String]) -> Result<(Document, Loaded)> {
    let document = Document::load(spec, sets)?;
    let loaded = document.loaded()?;
    Ok((document, loaded))
}

/// Loads a scenario from TOML text; `origin` names it in errors, and relative paths in it
/// (a base trajectory) are taken from `origin`'s folder.
pub fn load_str(text: &str, origin: &str, sets: &[String]) -> Result<Scenario> {
    let dir = Path::new(origin).parent().unwrap_or(Path::new(""));
    parse(text, origin, dir, sets).map(|(_, l)| l.scenario)
}

/// Reads a base trajectory CSV: the header `t,angle`, then rows of two finite numbers with t
/// strictly increasing. Errors name the file and the line.
pub fn read_trajectory(path: &Path) -> Result<(Vec<f64>, Vec<f64>)> {
    let origin = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| Error::io("read", path, e))?;
    let (series, lines) = parse_csv(&text, &origin)?;
    if series.columns != ["t", "angle"] {
        return Err(Error::data(
            &origin,
            0,
            format!(
                "the header must be `t,angle` (time in s, base angle in rad), not `{}`",
                series.columns.join(",")
            ),
        ));
    }
    let (t, angle) = (&series.data[0], &series.data[1]);
    if t.is_empty() {
        return Err(Error::data(
            &origin,
            0,
            "no rows after the header `t,angle`",
        ));
    }
    for (k, &line) in lines.iter().enumerate() {
        if t[k].is_nan() || angle[k].is_nan() {
            return Err(Error::data(
                &origin,
                line,
                "NaN is not allowed in a trajectory",
            ));
        }
        if k > 0 && t[k] <= t[k - 1] {
            return Err(Error::data(
                &origin,
                line,
                format!(
                    "t = {} does not increase (the previous row has t = {})",
                    t[k],
                    t[k - 1]
                ),
            ));
        }
    }
    Ok((t.clone(), angle.clone()))
}

/// Parses, applies the overrides, reads the schema and checks the result.
fn parse(text: &str, origin: &str, base_dir: &Path, sets: &[String]) -> Result<(Document, Loaded)> {
    let document = Document::parse(text, origin, base_dir, sets)?;
    let loaded = document.loaded()?;
    Ok((document, loaded))
}

/// Reads a scenario file; a missing file whose name looks like a built-in's is reported as an
/// unknown scenario name.
pub(crate) fn read_scenario_text(spec: &str, path: &Path) -> Result<String> {
    std::fs::read_to_string(path).map_err(|e| {
        // A bare word that is no file was probably meant as a built-in name.
        let word = !spec.contains(['/', '\\', '.']);
        if e.kind() == std::io::ErrorKind::NotFound && word {
            Error::UnknownScenario {
                spec: spec.to_string(),
                builtins: BUILTINS.iter().map(|b| b.to_string()).collect(),
            }
        } else {
            Error::io("read", path, e)
        }
    })
}
