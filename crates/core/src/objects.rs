//! Rigid objects that the whisker can strike: shapes, poses and prescribed (kinematic) motions.
//!
//! Objects move as prescribed; nothing the whisker does changes their motion. Each shape is
//! described in its own frame; a [`Pose`] places that frame in the world (the whisker's base
//! frame at rest: base at the origin, whisker along +x).

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

/// A convex rigid shape in its own frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "shape", rename_all = "snake_case", deny_unknown_fields)]
pub enum Shape {
    /// Rectangle of `width` (along local x) by `height` (along local y), centred on the origin.
    Box {
        /// Extent along local x, m.
        width: f64,
        /// Extent along local y, m.
        height: f64,
    },
    /// Disc (a peg or pole seen end-on) of `radius`, centred on the origin.
    Circle {
        /// Radius, m.
        radius: f64,
    },
    /// Half-plane `y <= 0` of the local frame (its surface is the local x axis, its outward
    /// normal local +y).
    Wall,
    /// Convex polygon with vertices in counter-clockwise order, in the local frame.
    Polygon {
        /// Vertices, m.
        vertices: Vec<[f64; 2]>,
    },
}

/// Where an object is and how it moves at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Pose {
    /// Origin of the object's frame, m.
    pub position: [f64; 2],
    /// Rotation of the object's frame, rad.
    pub angle: f64,
    /// Velocity of the frame's origin, m/s.
    pub velocity: [f64; 2],
    /// Angular velocity, rad/s.
    pub angular_velocity: f64,
}

impl Pose {
    /// World velocity of the object's material point at world position `p`.
    pub fn velocity_at(&self, p: [f64; 2]) -> [f64; 2] {
        let (dx, dy) = (p[0] - self.position[0], p[1] - self.position[1]);
        [
            self.velocity[0] - self.angular_velocity * dy,
            self.velocity[1] + self.angular_velocity * dx,
        ]
    }

    /// World position of the local point `l`.
    pub fn to_world(&self, l: [f64; 2]) -> [f64; 2] {
        let (s, c) = self.angle.sin_cos();
        [
            self.position[0] + c * l[0] - s * l[1],
            self.position[1] + s * l[0] + c * l[1],
        ]
    }

    /// Local coordinates of the world point `p`.
    pub fn to_local(&self, p: [f64; 2]) -> [f64; 2] {
        let (s, c) = self.angle.sin_cos();
        let (dx, dy) = (p[0] - self.position[0], p[1] - self.position[1]);
        [c * dx + s * dy, -s * dx + c * dy]
    }
}

/// A prescribed motion.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Motion {
    /// Constant linear and angular velocity from the initial pose.
    Constant {
        /// Velocity, m/s.
        #[serde(default)]
        velocity: [f64; 2],
        /// Angular velocity, rad/s.
        #[serde(default)]
        angular_velocity: f64,
    },
    /// Piecewise-linear path through `(t, x, y, angle)` waypoints (times strictly increasing);
    /// held at the first waypoint before it and at the last after it.
    Waypoints {
        /// `[t s, x m, y m, angle rad]` rows.
        points: Vec<[f64; 4]>,
    },
}

impl Default for Motion {
    fn default() -> Self {
        Motion::Constant {
            velocity: [0.0; 2],
            angular_velocity: 0.0,
        }
    }
}

/// A kinematic rigid object.
#[derive(Debug, Clone, PartialEq)]
pub struct Object {
    /// Its shape.
    pub shape: Shape,
    /// Position of the shape's frame at t = 0, m (ignored by waypoint motion).
    pub position: [f64; 2],
    /// Rotation of the shape's frame at t = 0, rad (ignored by waypoint motion).
    pub angle: f64,
    /// How it moves.
    pub motion: Motion,
    /// Coulomb friction coefficient against the whisker.
    pub friction: f64,
}

impl Object {
    /// The object's pose at time `t`.
    pub fn pose(&self, t: f64) -> Pose {
        match &self.motion {
            Motion::Constant {
                velocity,
                angular_velocity,
            } => Pose {
                position: [
                    self.position[0] + velocity[0] * t,
                    self.position[1] + velocity[1] * t,
                ],
                angle: self.angle + angular_velocity * t,
                velocity: *velocity,
                angular_velocity: *angular_velocity,
            },
            Motion::Waypoints { points } => {
                let first = points[0];
                let last = points[points.len() - 1];
                if t <= first[0] || points.len() == 1 {
                    return Pose {
                        position: [first[1], first[2]],
                        angle: first[3],
                        ..Default::default()
                    };
                }
                if t >= last[0] {
                    return Pose {
                        position: [last[1], last[2]],
                        angle: last[3],
                        ..Default::default()
                    };
                }
                let k = points.partition_point(|p| p[0] <= t).max(1);
                let (a, b) = (points[k - 1], points[k]);
                let dt = b[0] - a[0];
                let f = (t - a[0]) / dt;
                Pose {
                    position: [a[1] + f * (b[1] - a[1]), a[2] + f * (b[2] - a[2])],
                    angle: a[3] + f * (b[3] - a[3]),
                    velocity: [(b[1] - a[1]) / dt, (b[2] - a[2]) / dt],
                    angular_velocity: (b[3] - a[3]) / dt,
                }
            }
        }
    }

    /// Checks the object (`name` prefixes the field names in errors, e.g. `objects[0]`).
    pub fn check(&self, name: &str) -> Result<()> {
        let finite = |field: &str, x: f64| {
            if x.is_finite() {
                Ok(())
            } else {
                Err(Error::invalid(format!("{name}.{field}"), x, "a finite number"))
            }
        };
        let positive = |field: &str, x: f64| {
            if x.is_finite() && x > 0.0 {
                Ok(())
            } else {
                Err(Error::invalid(format!("{name}.{field}"), x, "a finite number > 0 (m)"))
            }
        };
        match &self.shape {
            Shape::Box { width, height } => {
                positive("width", *width)?;
                positive("height", *height)?;
            }
            Shape::Circle { radius } => positive("radius", *radius)?,
            Shape::Wall => {}
            Shape::Polygon { vertices } => check_convex_ccw(name, vertices)?,
        }
        finite("position[0]", self.position[0])?;
        finite("position[1]", self.position[1])?;
        finite("angle", self.angle)?;
        if !(self.friction.is_finite() && self.friction >= 0.0) {
            return Err(Error::invalid(format!("{name}.friction"), self.friction, "a finite number >= 0"));
        }
        match &self.motion {
            Motion::Constant {
                velocity,
                angular_velocity,
            } => {
                finite("motion.velocity[0]", velocity[0])?;
                finite("motion.velocity[1]", velocity[1])?;
                finite("motion.angular_velocity", *angular_velocity)?;
            }
            Motion::Waypoints { points } => {
                if points.is_empty() {
                    return Err(Error::invalid(
                        format!("{name}.motion.points"),
                        "[]",
                        "at least one [t, x, y, angle] row",
                    ));
                }
                for (k, p) in points.iter().enumerate() {
                    if !p.iter().all(|x| x.is_finite()) {
                        return Err(Error::invalid(
                            format!("{name}.motion.points[{k}]"),
                            format!("{p:?}"),
                            "four finite numbers [t, x, y, angle]",
                        ));
                    }
                    if k > 0 && p[0] <= points[k - 1][0] {
                        return Err(Error::invalid(
                            format!("{name}.motion.points[{k}][0]"),
                            p[0],
                            format!("a time later than the previous waypoint's {}", points[k - 1][0]),
                        ));
                    }
                }
            }
        }
        Ok(())
    }
}

fn check_convex_ccw(name: &str, v: &[[f64; 2]]) -> Result<()> {
    let field = format!("{name}.vertices");
    if v.len() < 3 {
        return Err(Error::invalid(field, v.len(), "at least 3 vertices"));
    }
    if !v.iter().flatten().all(|x| x.is_finite()) {
        return Err(Error::invalid(field, format!("{v:?}"), "finite coordinates"));
    }
    let n = v.len();
    for i in 0..n {
        let (a, b, c) = (v[i], v[(i + 1) % n], v[(i + 2) % n]);
        let cross = (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]);
        if cross <= 0.0 {
            return Err(Error::invalid(
                field,
                format!("{v:?}"),
                format!("a convex polygon in counter-clockwise order (turn at vertex {} is not left)", (i + 1) % n),
            ));
        }
    }
    Ok(())
}

/// The nearest points of a whisker segment and an object.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Closest {
    /// Position of the whisker point along the segment, as a fraction of `a → b` in [0, 1].
    pub u: f64,
    /// The whisker point (on the segment's axis), world frame, m.
    pub on_whisker: [f64; 2],
    /// The object point, world frame, m.
    pub on_object: [f64; 2],
    /// Unit normal pointing from the object towards the whisker (the direction the whisker must
    /// move to separate).
    pub normal: [f64; 2],
    /// Signed distance from the object's surface to the segment's axis along `normal`, m:
    /// positive when apart, negative when the axis has entered the object.
    pub distance: f64,
}

/// Nearest points of the segment `a → b` and `shape` placed at `pose` (see [`Closest`]).
pub fn closest(shape: &Shape, pose: &Pose, a: [f64; 2], b: [f64; 2]) -> Closest {
    let _ = (shape, pose, a, b);
    unimplemented!("written next")
}

/// Axis-aligned bounding box of `shape` at `pose`, `[xmin, ymin, xmax, ymax]` (a wall's is
/// unbounded).
pub fn bounds(shape: &Shape, pose: &Pose) -> [f64; 4] {
    let _ = (shape, pose);
    unimplemented!("written next")
}
