//! The file schema as serde types, and its translation into core's [`Scenario`].
//!
//! Tables whose keys depend on a `kind` (or `shape`) are read as flat structs and sorted out here,
//! so that a wrong type names its key and a key given to the wrong kind is reported by name.

use super::calibration::{Calibration, SensorsTable};
use super::family::FamilySpec;
use super::{
    experiment_box, read_trajectory, Experiment, ExperimentRun, Loaded, DEFAULT_D, DEFAULT_V,
};
use crate::error::{Error, Result};
use serde::Deserialize;
use std::path::Path;
use vibrissa_core::chain::Discretisation;
use vibrissa_core::dynamics::Integrator;
use vibrissa_core::error::check_finite;
use vibrissa_core::objects::{Motion, Object, Shape};
use vibrissa_core::sim::{BaseDrive, Scenario, SensorNoise};
use vibrissa_core::whisker::{Damping, Follicle, WhiskerParams};

/// Blend time of a ramp's corners when the file gives none, s.
pub(super) const DEFAULT_RAMP_SMOOTHING: f64 = 0.005;

/// The whole file.
#[derive(Debug, Default, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub(super) struct FileTable {
    experiment: Option<Experiment>,
    d: Option<f64>,
    v: Option<f64>,
    duration: Option<f64>,
    dt: Option<f64>,
    rho_inf: Option<f64>,
    contact_rho_inf: Option<f64>,
    tolerance: Option<f64>,
    max_iterations: Option<usize>,
    contact_substeps: Option<usize>,
    fit_first_mode: Option<bool>,
    hold_contacts: Option<bool>,
    sample_rate: Option<f64>,
    seed: Option<u64>,
    segments: Option<usize>,
    discretisation: Option<Discretisation>,
    process_noise: Option<f64>,
    whisker: Option<WhiskerTable>,
    sensor_noise: Option<SensorNoiseTable>,
    base: Option<BaseTable>,
    objects: Vec<ObjectTable>,
    whiskers: Vec<MountTable>,
    unknowns: Option<toml::Table>,
    templates: Option<toml::Table>,
    grid: Option<toml::Table>,
    // Sensor gains and offsets, and a calibration's record (calibration.rs).
    sensors: Option<SensorsTable>,
    calibration: Option<Calibration>,
}

/// `[[whiskers]]`: one whisker of an array.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MountTable {
    name: String,
    #[serde(default)]
    position: [f64; 2],
    #[serde(default)]
    angle: f64,
    /// Overrides of the scenario's `[whisker]` for this whisker.
    whisker: Option<WhiskerTable>,
    /// This whisker's base motion instead of the scenario's `[base]`.
    base: Option<BaseTable>,
    /// This whisker's sensors instead of the scenario's `[sensors]` (a channel not named has
    /// gain 1 and offset 0, as at the top level).
    sensors: Option<SensorsTable>,
}

/// `[whisker]`: a preset, then overrides of its fields.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct WhiskerTable {
    preset: Option<String>,
    length: Option<f64>,
    base_radius: Option<f64>,
    tip_radius: Option<f64>,
    rest_curvature: Option<f64>,
    youngs_modulus: Option<f64>,
    density: Option<f64>,
    follicle: Option<FollicleTable>,
    damping: Option<DampingTable>,
}

/// `whisker.follicle`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FollicleTable {
    kind: FollicleKind,
    stiffness: Option<f64>,
    damping: Option<f64>,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(rename_all = "snake_case")]
enum FollicleKind {
    Clamped,
    Spring,
}

/// `whisker.damping`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DampingTable {
    kind: DampingKind,
    ratio: Option<f64>,
    q: Option<f64>,
    beta: Option<f64>,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(rename_all = "snake_case")]
enum DampingKind {
    None,
    ModalRatio,
    SegmentQ,
    StiffnessProportional,
}

/// `[sensor_noise]`: standard deviations per channel (a channel not named is 0 in a run, and
/// not stated for estimators, which then estimate it from the recordings).
#[derive(Debug, Default, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct SensorNoiseTable {
    theta01: Option<f64>,
    theta12: Option<f64>,
    m0: Option<f64>,
    fx: Option<f64>,
    fy: Option<f64>,
}

impl SensorNoiseTable {
    /// The stated standard deviations, in the order of core's sensor channels.
    fn stated(&self) -> [Option<f64>; 5] {
        [self.theta01, self.theta12, self.m0, self.fx, self.fy]
    }
}

/// `[base]`: the prescribed base rotation.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BaseTable {
    kind: BaseKind,
    amplitude: Option<f64>,
    frequency: Option<f64>,
    phase: Option<f64>,
    offset: Option<f64>,
    rate: Option<f64>,
    start: Option<f64>,
    stop: Option<f64>,
    smoothing: Option<f64>,
    file: Option<String>,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(rename_all = "snake_case")]
enum BaseKind {
    Fixed,
    Sinusoid,
    Ramp,
    Trajectory,
}

/// One `[[objects]]` entry.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ObjectTable {
    shape: ShapeKind,
    width: Option<f64>,
    height: Option<f64>,
    radius: Option<f64>,
    vertices: Option<Vec<[f64; 2]>>,
    side: Option<f64>,
    position: Option<[f64; 2]>,
    angle: Option<f64>,
    friction: Option<f64>,
    velocity: Option<[f64; 2]>,
    angular_velocity: Option<f64>,
    waypoints: Option<Vec<[f64; 4]>>,
    vertical: Option<vibrissa_core::objects::Vertical>,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(rename_all = "snake_case")]
enum ShapeKind {
    Box,
    Circle,
    Wall,
    Polygon,
    /// A box with equal sides (`side`).
    Square,
    /// An equilateral triangle (`side`), see [`equilateral_triangle`].
    Triangle,
}

/// Where the file came from: its name for errors, its folder for relative paths.
pub(super) struct Ctx<'a> {
    pub origin: &'a str,
    pub base_dir: &'a Path,
}

impl Ctx<'_> {
    /// An error about one key.
    pub(super) fn field(&self, field: impl Into<String>, message: impl Into<String>) -> Error {
        Error::Field {
            origin: self.origin.to_string(),
            field: field.into(),
            message: message.into(),
        }
    }

    /// Core's verdict on a value, with the file's name.
    fn invalid(&self, error: vibrissa_core::Error) -> Error {
        Error::Invalid {
            origin: self.origin.to_string(),
            error,
        }
    }

    /// Rejects keys of `table` that `kind` does not take, then asks for those it needs.
    /// `given` lists every kind-dependent key of the table and whether the file set it.
    fn kind_keys(
        &self,
        table: &str,
        kind: &str,
        given: &[(&str, bool)],
        takes: &[&str],
        needs: &[&str],
    ) -> Result<()> {
        for &(name, present) in given {
            if present && !takes.contains(&name) {
                let list = if takes.is_empty() {
                    "no further keys".to_string()
                } else {
                    takes.join(", ")
                };
                return Err(self.field(
                    format!("{table}.{name}"),
                    format!("does not apply to {kind}, which takes {list}"),
                ));
            }
        }
        for &name in needs {
            if !given.iter().any(|&(n, present)| n == name && present) {
                return Err(
                    self.field(format!("{table}.{name}"), format!("is required for {kind}"))
                );
            }
        }
        Ok(())
    }
}

impl FileTable {
    /// Reads a parsed document into the schema.
    pub(super) fn deserialize_table(
        table: toml::Table,
    ) -> std::result::Result<FileTable, toml::de::Error> {
        FileTable::deserialize(toml::Value::Table(table))
    }

    /// Translates the file into a checked scenario.
    pub(super) fn into_loaded(self, ctx: &Ctx) -> Result<Loaded> {
        let defaults = Scenario::default();
        // A file that names an experiment and no unknowns is that experiment's family.
        let family =
            match FamilySpec::from_tables(ctx.origin, self.unknowns, self.templates, self.grid)? {
                None => self.experiment.map(super::builtin_family).transpose()?,
                given => given,
            };

        // Time stepping (core's own check of the integrator settings).
        let integrator = Integrator {
            dt: self.dt.unwrap_or(defaults.integrator.dt),
            rho_inf: self.rho_inf.unwrap_or(defaults.integrator.rho_inf),
            tolerance: self.tolerance.unwrap_or(defaults.integrator.tolerance),
            max_iterations: self
                .max_iterations
                .unwrap_or(defaults.integrator.max_iterations),
            contact_substeps: self
                .contact_substeps
                .unwrap_or(defaults.integrator.contact_substeps),
            fit_first_mode: self
                .fit_first_mode
                .unwrap_or(defaults.integrator.fit_first_mode),
            contact_rho_inf: self
                .contact_rho_inf
                .unwrap_or(defaults.integrator.contact_rho_inf),
            hold_contacts: self
                .hold_contacts
                .unwrap_or(defaults.integrator.hold_contacts),
        };
        integrator.check().map_err(|e| ctx.invalid(e))?;

        // Objects of the file, then the experiment's box.
        let mut objects = self
            .objects
            .into_iter()
            .enumerate()
            .map(|(k, o)| o.into_object(ctx, k))
            .collect::<Result<Vec<_>>>()?;
        let experiment = match self.experiment {
            Some(experiment) => {
                let d =
                    check_finite("d", self.d.unwrap_or(DEFAULT_D)).map_err(|e| ctx.invalid(e))?;
                if d <= 0.0 {
                    // At d = 0 the box's edge meets the whisker at its base joint, where the
                    // whisker cannot bend away; below, the box passes behind the base.
                    return Err(ctx.invalid(vibrissa_core::Error::invalid(
                        "d",
                        d,
                        "a distance from the base > 0 m (the box's near edge beyond the base)",
                    )));
                }
                let v =
                    check_finite("v", self.v.unwrap_or(DEFAULT_V)).map_err(|e| ctx.invalid(e))?;
                let fastest = vibrissa_core::objects::MAX_SPEED;
                if v.abs() > fastest {
                    return Err(ctx.invalid(vibrissa_core::Error::invalid(
                        "v",
                        v,
                        format!("a speed of at most {fastest} m/s (in m/s, not mm/s)"),
                    )));
                }
                objects.push(experiment_box(d, v));
                Some(ExperimentRun { experiment, d, v })
            }
            None => {
                for (name, given) in [("d", self.d.is_some()), ("v", self.v.is_some())] {
                    if given {
                        return Err(ctx.field(
                            name,
                            "applies only to an experiment: add experiment = \"e1\" or \"e2\"",
                        ));
                    }
                }
                None
            }
        };

        let scenario = Scenario {
            whisker: match self.whisker {
                Some(w) => w.into_params(ctx, defaults.whisker)?,
                None => defaults.whisker,
            },
            segments: self.segments.unwrap_or(defaults.segments),
            discretisation: self.discretisation.unwrap_or(defaults.discretisation),
            integrator,
            duration: self.duration.unwrap_or(defaults.duration),
            sample_rate: self.sample_rate.unwrap_or(defaults.sample_rate),
            objects,
            base: match self.base {
                Some(b) => b.into_drive(ctx)?,
                None => defaults.base,
            },
            process_noise: self.process_noise.unwrap_or(defaults.process_noise),
            sensor_noise: self
                .sensor_noise
                .as_ref()
                .map_or(defaults.sensor_noise, |n| SensorNoise {
                    theta01: n.theta01.unwrap_or(0.0),
                    theta12: n.theta12.unwrap_or(0.0),
                    m0: n.m0.unwrap_or(0.0),
                    fx: n.fx.unwrap_or(0.0),
                    fy: n.fy.unwrap_or(0.0),
                }),
            sensor_response: self
                .sensors
                .map_or(defaults.sensor_response, SensorsTable::into_response),
            seed: self.seed.unwrap_or(defaults.seed),
        };
        scenario.check().map_err(|e| ctx.invalid(e))?;
        let whiskers = self
            .whiskers
            .into_iter()
            .map(|m| {
                Ok(vibrissa_core::array::Mount {
                    name: m.name,
                    position: m.position,
                    angle: m.angle,
                    whisker: m
                        .whisker
                        .map(|w| w.into_params(ctx, scenario.whisker.clone()))
                        .transpose()?,
                    base: m.base.map(|b| b.into_drive(ctx)).transpose()?,
                    sensors: m.sensors.map(SensorsTable::into_response),
                })
            })
            .collect::<Result<Vec<_>>>()?;
        if !whiskers.is_empty() {
            vibrissa_core::array::check(&whiskers, &scenario).map_err(|e| ctx.invalid(e))?;
        }
        if let Some(c) = &self.calibration {
            c.check(ctx)?;
        }
        Ok(Loaded {
            scenario,
            experiment,
            family,
            origin: ctx.origin.to_string(),
            calibration: self.calibration,
            stated_sensor_noise: self
                .sensor_noise
                .as_ref()
                .map_or([None; 5], SensorNoiseTable::stated),
            whiskers,
        })
    }
}

impl WhiskerTable {
    /// The preset (or `default`) with the file's fields laid over it.
    fn into_params(self, ctx: &Ctx, default: WhiskerParams) -> Result<WhiskerParams> {
        let mut p = match &self.preset {
            Some(name) => WhiskerParams::preset(name).map_err(|e| ctx.invalid(e))?,
            None => default,
        };
        for (slot, value) in [
            (&mut p.length, self.length),
            (&mut p.base_radius, self.base_radius),
            (&mut p.tip_radius, self.tip_radius),
            (&mut p.rest_curvature, self.rest_curvature),
            (&mut p.youngs_modulus, self.youngs_modulus),
            (&mut p.density, self.density),
        ] {
            if let Some(x) = value {
                *slot = x;
            }
        }
        if let Some(f) = self.follicle {
            p.follicle = f.into_follicle(ctx)?;
        }
        if let Some(d) = self.damping {
            p.damping = d.into_damping(ctx)?;
        }
        Ok(p)
    }
}

impl FollicleTable {
    fn into_follicle(self, ctx: &Ctx) -> Result<Follicle> {
        let given = [
            ("stiffness", self.stiffness.is_some()),
            ("damping", self.damping.is_some()),
        ];
        let table = "whisker.follicle";
        Ok(match self.kind {
            FollicleKind::Clamped => {
                ctx.kind_keys(table, "kind = \"clamped\"", &given, &[], &[])?;
                Follicle::Clamped
            }
            FollicleKind::Spring => {
                let keys = ["stiffness", "damping"];
                ctx.kind_keys(table, "kind = \"spring\"", &given, &keys, &keys)?;
                Follicle::Spring {
                    stiffness: self.stiffness.unwrap_or_default(),
                    damping: self.damping.unwrap_or_default(),
                }
            }
        })
    }
}

impl DampingTable {
    fn into_damping(self, ctx: &Ctx) -> Result<Damping> {
        let given = [
            ("ratio", self.ratio.is_some()),
            ("q", self.q.is_some()),
            ("beta", self.beta.is_some()),
        ];
        let table = "whisker.damping";
        // The one key each kind takes (none for `none`).
        let (kind, key) = match self.kind {
            DampingKind::None => ("kind = \"none\"", None),
            DampingKind::ModalRatio => ("kind = \"modal_ratio\"", Some("ratio")),
            DampingKind::SegmentQ => ("kind = \"segment_q\"", Some("q")),
            DampingKind::StiffnessProportional => {
                ("kind = \"stiffness_proportional\"", Some("beta"))
            }
        };
        let keys: Vec<&str> = key.into_iter().collect();
        ctx.kind_keys(table, kind, &given, &keys, &keys)?;
        Ok(match self.kind {
            DampingKind::None => Damping::None,
            DampingKind::ModalRatio => Damping::ModalRatio {
                ratio: self.ratio.unwrap_or_default(),
            },
            DampingKind::SegmentQ => Damping::SegmentQ {
                q: self.q.unwrap_or_default(),
            },
            DampingKind::StiffnessProportional => Damping::StiffnessProportional {
                beta: self.beta.unwrap_or_default(),
            },
        })
    }
}

impl BaseTable {
    fn into_drive(self, ctx: &Ctx) -> Result<BaseDrive> {
        let given = [
            ("amplitude", self.amplitude.is_some()),
            ("frequency", self.frequency.is_some()),
            ("phase", self.phase.is_some()),
            ("offset", self.offset.is_some()),
            ("rate", self.rate.is_some()),
            ("start", self.start.is_some()),
            ("stop", self.stop.is_some()),
            ("smoothing", self.smoothing.is_some()),
            ("file", self.file.is_some()),
        ];
        let table = "base";
        Ok(match self.kind {
            BaseKind::Fixed => {
                ctx.kind_keys(table, "kind = \"fixed\"", &given, &[], &[])?;
                BaseDrive::Fixed
            }
            BaseKind::Sinusoid => {
                ctx.kind_keys(
                    table,
                    "kind = \"sinusoid\"",
                    &given,
                    &["amplitude", "frequency", "phase", "offset"],
                    &["amplitude", "frequency"],
                )?;
                BaseDrive::Sinusoid {
                    amplitude: self.amplitude.unwrap_or_default(),
                    frequency: self.frequency.unwrap_or_default(),
                    phase: self.phase.unwrap_or(0.0),
                    offset: self.offset.unwrap_or(0.0),
                }
            }
            BaseKind::Ramp => {
                ctx.kind_keys(
                    table,
                    "kind = \"ramp\"",
                    &given,
                    &["rate", "start", "stop", "smoothing"],
                    &["rate"],
                )?;
                BaseDrive::Ramp {
                    rate: self.rate.unwrap_or_default(),
                    start: self.start.unwrap_or(0.0),
                    stop: self.stop.unwrap_or(f64::INFINITY),
                    smoothing: self.smoothing.unwrap_or(DEFAULT_RAMP_SMOOTHING),
                }
            }
            BaseKind::Trajectory => {
                ctx.kind_keys(table, "kind = \"trajectory\"", &given, &["file"], &["file"])?;
                let path = ctx.base_dir.join(self.file.unwrap_or_default());
                let (t, angle) = read_trajectory(&path)?;
                BaseDrive::Trajectory { t, angle }
            }
        })
    }
}

impl ObjectTable {
    fn into_object(self, ctx: &Ctx, k: usize) -> Result<Object> {
        let table = format!("objects[{k}]");

        // The shape and its own keys.
        let given = [
            ("width", self.width.is_some()),
            ("height", self.height.is_some()),
            ("radius", self.radius.is_some()),
            ("vertices", self.vertices.is_some()),
            ("side", self.side.is_some()),
        ];
        // A square's or triangle's side, checked here so that an error names the key the file
        // gave (core would name a box's width, and a triangle's vertices need a usable side).
        let side = |kind: &str| -> Result<f64> {
            ctx.kind_keys(&table, kind, &given, &["side"], &["side"])?;
            let side = self.side.unwrap_or_default();
            if side.is_finite() && side > 0.0 {
                Ok(side)
            } else {
                Err(ctx.invalid(vibrissa_core::Error::invalid(
                    format!("{table}.side"),
                    side,
                    "a finite number > 0 (m)",
                )))
            }
        };
        let shape = match self.shape {
            ShapeKind::Box => {
                let keys = ["width", "height"];
                ctx.kind_keys(&table, "shape = \"box\"", &given, &keys, &keys)?;
                Shape::Box {
                    width: self.width.unwrap_or_default(),
                    height: self.height.unwrap_or_default(),
                }
            }
            ShapeKind::Circle => {
                let keys = ["radius"];
                ctx.kind_keys(&table, "shape = \"circle\"", &given, &keys, &keys)?;
                Shape::Circle {
                    radius: self.radius.unwrap_or_default(),
                }
            }
            ShapeKind::Wall => {
                ctx.kind_keys(&table, "shape = \"wall\"", &given, &[], &[])?;
                Shape::Wall
            }
            ShapeKind::Polygon => {
                let keys = ["vertices"];
                ctx.kind_keys(&table, "shape = \"polygon\"", &given, &keys, &keys)?;
                Shape::Polygon {
                    vertices: self.vertices.unwrap_or_default(),
                }
            }
            ShapeKind::Square => {
                let side = side("shape = \"square\"")?;
                Shape::Box {
                    width: side,
                    height: side,
                }
            }
            ShapeKind::Triangle => Shape::Polygon {
                vertices: equilateral_triangle(side("shape = \"triangle\"")?).to_vec(),
            },
        };

        // The motion: waypoints carry the pose; otherwise an initial pose and constant velocity.
        let (position, angle, motion) = match self.waypoints {
            Some(points) => {
                for (name, given) in [
                    ("position", self.position.is_some()),
                    ("angle", self.angle.is_some()),
                    ("velocity", self.velocity.is_some()),
                    ("angular_velocity", self.angular_velocity.is_some()),
                ] {
                    if given {
                        return Err(ctx.field(
                            format!("{table}.{name}"),
                            "conflicts with waypoints, which give the pose at every time",
                        ));
                    }
                }
                let first = points.first().copied().unwrap_or_default();
                ([first[1], first[2]], first[3], Motion::Waypoints { points })
            }
            None => {
                let position = self.position.ok_or_else(|| {
                    ctx.field(
                        format!("{table}.position"),
                        "is required (or give waypoints = [[t, x, y, angle], ...])",
                    )
                })?;
                let motion = Motion::Constant {
                    velocity: self.velocity.unwrap_or_default(),
                    angular_velocity: self.angular_velocity.unwrap_or(0.0),
                };
                (position, self.angle.unwrap_or(0.0), motion)
            }
        };
        Ok(Object {
            shape,
            position,
            angle,
            motion,
            friction: self.friction.unwrap_or(0.0),
            vertical: self.vertical,
        })
    }
}

/// The vertices of an equilateral triangle of side `side`, centred on its centroid, with one
/// vertex on the local +y axis, in counter-clockwise order (top, lower left, lower right).
fn equilateral_triangle(side: f64) -> [[f64; 2]; 3] {
    // The circumradius is side/√3; the other two vertices lie 120° on either side of +y, at
    // height −r/2 and half a side out.
    let r = side / 3f64.sqrt();
    [[0.0, r], [-0.5 * side, -0.5 * r], [0.5 * side, -0.5 * r]]
}
