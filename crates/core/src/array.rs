//! Arrays of whiskers: several whiskers, each with its own base position, orientation, whisker,
//! sensors and base motion, striking the same objects.
//!
//! Objects move as prescribed and whiskers never touch each other, so the whiskers of an array
//! do not interact: each is run as a single-whisker scenario in its own frame (its base at the
//! origin, pointing along +x at rest), with the objects carried into that frame, and the runs go
//! in parallel. Every whisker's channels are in its own frame, as a single whisker's are: `m0`,
//! `fx`, `fy` the wrench its base applies to it, `cx`, `cy` the contact point. Whisker `k` (from 0)
//! draws its random forces and sensor noise from streams seeded by the scenario's seed and `k`.

use crate::dynamics::{State, Workspace};
use crate::error::{Error, Result};
use crate::objects::{Motion, Object};
use crate::sim::{self, BaseDrive, Output, Scenario, SensorResponse};
use crate::whisker::WhiskerParams;
use crate::Model;
use rayon::prelude::*;

/// One whisker of an array.
#[derive(Debug, Clone, PartialEq)]
pub struct Mount {
    /// Its name, the prefix of its columns (`c1` gives `c1.theta01`, ...): letters, digits, `_`
    /// and `-`.
    pub name: String,
    /// Its base, in the scene's frame, m.
    pub position: [f64; 2],
    /// The direction it points at rest (before its base motion), from the scene's +x, rad.
    pub angle: f64,
    /// Its whisker (`None`: the scenario's).
    pub whisker: Option<WhiskerParams>,
    /// Its base motion (`None`: the scenario's).
    pub base: Option<BaseDrive>,
    /// Its sensors' gains and offsets (`None`: the scenario's): each whisker of a real array
    /// is read by sensors of its own.
    pub sensors: Option<SensorResponse>,
}

/// Whether `name` can name a whisker of an array.
pub fn is_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 32
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

impl Mount {
    /// `p` (scene frame) in the whisker's frame.
    fn to_local(&self, p: [f64; 2]) -> [f64; 2] {
        let (s, c) = self.angle.sin_cos();
        let (dx, dy) = (p[0] - self.position[0], p[1] - self.position[1]);
        [c * dx + s * dy, -s * dx + c * dy]
    }

    /// A vector `v` (scene frame) in the whisker's frame.
    fn turn_to_local(&self, v: [f64; 2]) -> [f64; 2] {
        let (s, c) = self.angle.sin_cos();
        [c * v[0] + s * v[1], -s * v[0] + c * v[1]]
    }

    /// `object` as the whisker sees it: its pose and motion in the whisker's frame.
    pub fn carry(&self, object: &Object) -> Object {
        let motion = match &object.motion {
            Motion::Constant {
                velocity,
                angular_velocity,
            } => Motion::Constant {
                velocity: self.turn_to_local(*velocity),
                angular_velocity: *angular_velocity,
            },
            Motion::Waypoints { points } => Motion::Waypoints {
                points: points
                    .iter()
                    .map(|&[t, x, y, a]| {
                        let p = self.to_local([x, y]);
                        [t, p[0], p[1], a - self.angle]
                    })
                    .collect(),
            },
        };
        Object {
            position: self.to_local(object.position),
            angle: object.angle - self.angle,
            motion,
            ..object.clone()
        }
    }

    /// The single-whisker scenario of this whisker, the `k`th of `scenario`'s array.
    pub fn scenario(&self, scenario: &Scenario, k: usize) -> Scenario {
        Scenario {
            whisker: self
                .whisker
                .clone()
                .unwrap_or_else(|| scenario.whisker.clone()),
            base: self.base.clone().unwrap_or_else(|| scenario.base.clone()),
            sensor_response: self.sensors.unwrap_or(scenario.sensor_response),
            objects: scenario.objects.iter().map(|o| self.carry(o)).collect(),
            seed: stream_seed(scenario.seed, k),
            ..scenario.clone()
        }
    }
}

/// The seed of whisker `k`'s streams.
fn stream_seed(seed: u64, k: usize) -> u64 {
    seed ^ (k as u64)
        .wrapping_add(1)
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
}

/// The whisker's nodes at rest in the scene's frame.
fn rest_nodes(mount: &Mount, scenario: &Scenario) -> Result<Vec<[f64; 2]>> {
    let whisker = mount
        .whisker
        .as_ref()
        .unwrap_or(&scenario.whisker)
        .check()?;
    let model = Model::new(&whisker, scenario.segments, scenario.discretisation)?;
    let state = State::at_rest(&model, 0);
    let mut ws = Workspace::new(&model);
    ws.evaluate(&model, &state);
    let (s, c) = mount.angle.sin_cos();
    Ok(ws
        .nodes()
        .iter()
        .map(|p| {
            [
                mount.position[0] + c * p[0] - s * p[1],
                mount.position[1] + s * p[0] + c * p[1],
            ]
        })
        .collect())
}

/// Whether segments `a0 a1` and `b0 b1` cross or touch.
fn segments_meet(a0: [f64; 2], a1: [f64; 2], b0: [f64; 2], b1: [f64; 2]) -> bool {
    let cross = |o: [f64; 2], p: [f64; 2], q: [f64; 2]| {
        (p[0] - o[0]) * (q[1] - o[1]) - (p[1] - o[1]) * (q[0] - o[0])
    };
    let (d1, d2) = (cross(b0, b1, a0), cross(b0, b1, a1));
    let (d3, d4) = (cross(a0, a1, b0), cross(a0, a1, b1));
    (d1 * d2 <= 0.0) && (d3 * d4 <= 0.0)
}

/// Checks an array: at least one whisker, names valid and distinct, finite poses, and whiskers
/// that at rest neither share a base point nor cross each other.
pub fn check(mounts: &[Mount], scenario: &Scenario) -> Result<()> {
    if mounts.is_empty() {
        return Err(Error::invalid(
            "whiskers",
            "an empty list",
            "at least one whisker",
        ));
    }
    let mut shapes = Vec::with_capacity(mounts.len());
    for (k, m) in mounts.iter().enumerate() {
        let field = |f: &str| format!("whiskers[{k}].{f}");
        if !is_name(&m.name) {
            return Err(Error::invalid(
                field("name"),
                format!("{:?}", m.name),
                "1 to 32 letters, digits, `_` or `-` (the prefix of its columns)",
            ));
        }
        if let Some(j) = mounts[..k].iter().position(|o| o.name == m.name) {
            return Err(Error::invalid(
                field("name"),
                format!("{:?}", m.name),
                format!("a name no other whisker has (whiskers[{j}] has it)"),
            ));
        }
        for (f, x) in [
            ("position[0]", m.position[0]),
            ("position[1]", m.position[1]),
            ("angle", m.angle),
        ] {
            if !x.is_finite() {
                return Err(Error::invalid(field(f), x, "a finite number"));
            }
        }
        if let Some(w) = &m.whisker {
            w.check()?;
        }
        if let Some(b) = &m.base {
            b.check()?;
        }
        if let Some(r) = &m.sensors {
            r.check_at(&field("sensors"))?;
        }
        shapes.push(rest_nodes(m, scenario)?);
    }
    for k in 0..mounts.len() {
        for j in 0..k {
            let (a, b) = (&shapes[k], &shapes[j]);
            let meet = a
                .windows(2)
                .any(|p| b.windows(2).any(|q| segments_meet(p[0], p[1], q[0], q[1])));
            if meet {
                return Err(Error::invalid(
                    format!("whiskers[{k}]"),
                    format!(
                        "`{}` at {:?}, angle {} rad",
                        mounts[k].name, mounts[k].position, mounts[k].angle
                    ),
                    format!(
                        "whiskers that neither share a base nor cross at rest (it meets \
                         whiskers[{j}], `{}`)",
                        mounts[j].name
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Runs every whisker of the array (in parallel) and returns their outputs, in order.
pub fn run(scenario: &Scenario, mounts: &[Mount]) -> Result<Vec<Output>> {
    check(mounts, scenario)?;
    mounts
        .par_iter()
        .enumerate()
        .map(|(k, m)| {
            sim::run(&m.scenario(scenario, k), &mut |_| {}).map_err(|e| Error::Whisker {
                name: m.name.clone(),
                detail: e.to_string(),
            })
        })
        .collect()
}
