//! Rigid objects that the whisker can strike: shapes, poses and prescribed (kinematic) motions.
//!
//! Objects move as prescribed; nothing the whisker does changes their motion. Each shape is
//! described in its own frame; a [`Pose`] places that frame in the world (the whisker's base
//! frame at rest: base at the origin, whisker along +x).

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};

mod geometry;

use geometry::box_vertices;
pub use geometry::{bounds, closest, contains, Closest};

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
        let (s, c) = turn(self.angle);
        [
            self.position[0] + c * l[0] - s * l[1],
            self.position[1] + s * l[0] + c * l[1],
        ]
    }

    /// Local coordinates of the world point `p`.
    pub fn to_local(&self, p: [f64; 2]) -> [f64; 2] {
        let (s, c) = turn(self.angle);
        let (dx, dy) = (p[0] - self.position[0], p[1] - self.position[1]);
        [c * dx + s * dy, -s * dx + c * dy]
    }
}

/// `(sin a, cos a)` of a pose's angle, without the library call for the common unturned pose.
#[inline]
pub(crate) fn turn(angle: f64) -> (f64, f64) {
    if angle == 0.0 {
        (0.0, 1.0)
    } else {
        angle.sin_cos()
    }
}

/// Fastest an object may move, m/s: whiskers meet objects at centimetres to metres per second;
/// a speed beyond this is a unit mistake (mm/s given as m/s) or nonsense, refused before a run
/// that could only diverge.
pub const MAX_SPEED: f64 = 1000.0;

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
    /// The object's extent across the whisker's plane and its motion across it (`None`: a
    /// prism through the plane, always cut by it).
    pub vertical: Option<Vertical>,
}

/// An object's extent normal to the whisker's plane (z, the plane at z = 0) and its constant
/// speed along z. The whisker can touch the object only while the plane cuts it:
/// `bottom + velocity·t ≤ 0 ≤ top + velocity·t`. An object that lifts out of the plane during
/// contact releases the whisker at once (the seed paper's plucking).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Vertical {
    /// z of the object's bottom at t = 0, m.
    pub bottom: f64,
    /// z of its top at t = 0, m.
    pub top: f64,
    /// Its speed along z, m/s.
    #[serde(default)]
    pub velocity: f64,
}

impl Vertical {
    /// Whether the plane z = 0 cuts the object at time `t`.
    pub fn cuts_plane(&self, t: f64) -> bool {
        let dz = self.velocity * t;
        self.bottom + dz <= 0.0 && 0.0 <= self.top + dz
    }

    /// The interval of times in which the plane cuts the object (`None`: never).
    pub fn in_plane(&self) -> Option<[f64; 2]> {
        if self.velocity == 0.0 {
            return self
                .cuts_plane(0.0)
                .then_some([f64::NEG_INFINITY, f64::INFINITY]);
        }
        let (a, b) = (-self.top / self.velocity, -self.bottom / self.velocity);
        Some([a.min(b), a.max(b)])
    }
}

impl Object {
    /// Whether the whisker's plane cuts the object at time `t` (so that they can touch).
    pub fn in_plane(&self, t: f64) -> bool {
        self.vertical.is_none_or(|v| v.cuts_plane(t))
    }

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

    /// Checks the object (`name` prefixes the field names in errors, e.g. `objects[0]`): among
    /// the rest, it may move at most [`MAX_SPEED`].
    pub fn check(&self, name: &str) -> Result<()> {
        let finite = |field: &str, x: f64| {
            if x.is_finite() {
                Ok(())
            } else {
                Err(Error::invalid(
                    format!("{name}.{field}"),
                    x,
                    "a finite number",
                ))
            }
        };
        let positive = |field: &str, x: f64| {
            if x.is_finite() && x > 0.0 {
                Ok(())
            } else {
                Err(Error::invalid(
                    format!("{name}.{field}"),
                    x,
                    "a finite number > 0 (m)",
                ))
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
        if let Some(v) = &self.vertical {
            finite("vertical.bottom", v.bottom)?;
            finite("vertical.top", v.top)?;
            finite("vertical.velocity", v.velocity)?;
            if v.top <= v.bottom {
                return Err(Error::invalid(
                    format!("{name}.vertical.top"),
                    v.top,
                    format!("a height above the bottom ({} m)", v.bottom),
                ));
            }
            if v.velocity.abs() > MAX_SPEED {
                return Err(Error::invalid(
                    format!("{name}.vertical.velocity"),
                    v.velocity,
                    format!("a speed of at most {MAX_SPEED} m/s (in m/s, not mm/s)"),
                ));
            }
        }
        if !(self.friction.is_finite() && self.friction >= 0.0) {
            return Err(Error::invalid(
                format!("{name}.friction"),
                self.friction,
                "a finite number >= 0",
            ));
        }
        match &self.motion {
            Motion::Constant {
                velocity,
                angular_velocity,
            } => {
                finite("motion.velocity[0]", velocity[0])?;
                finite("motion.velocity[1]", velocity[1])?;
                finite("motion.angular_velocity", *angular_velocity)?;
                let speed = velocity[0].hypot(velocity[1]);
                if speed > MAX_SPEED {
                    return Err(Error::invalid(
                        format!("{name}.motion.velocity"),
                        format!("{velocity:?} ({speed:.3e} m/s)"),
                        format!("a speed of at most {MAX_SPEED} m/s (in m/s, not mm/s)"),
                    ));
                }
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
                            format!(
                                "a time later than the previous waypoint's {}",
                                points[k - 1][0]
                            ),
                        ));
                    }
                    if k > 0 {
                        let q = points[k - 1];
                        let speed = (p[1] - q[1]).hypot(p[2] - q[2]) / (p[0] - q[0]);
                        if speed > MAX_SPEED {
                            return Err(Error::invalid(
                                format!("{name}.motion.points[{k}]"),
                                format!("{p:?}"),
                                format!(
                                    "a waypoint reached from the previous one at most \
                                     {MAX_SPEED} m/s (here {speed:.3e} m/s; times in s, \
                                     positions in m)"
                                ),
                            ));
                        }
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
        return Err(Error::invalid(
            field,
            format!("{v:?}"),
            "finite coordinates",
        ));
    }
    let n = v.len();
    let mut turning = 0.0;
    for i in 0..n {
        let (a, b, c) = (v[i], v[(i + 1) % n], v[(i + 2) % n]);
        let cross = (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]);
        if cross <= 0.0 {
            return Err(Error::invalid(
                field,
                format!("{v:?}"),
                format!(
                    "a convex polygon in counter-clockwise order (turn at vertex {} is not left)",
                    (i + 1) % n
                ),
            ));
        }
        let along = (b[0] - a[0]) * (c[0] - b[0]) + (b[1] - a[1]) * (c[1] - b[1]);
        turning += cross.atan2(along);
    }
    // Left turns everywhere still allow a star that winds more than once.
    if (turning - std::f64::consts::TAU).abs() > 1e-6 {
        return Err(Error::invalid(
            field,
            format!("{v:?}"),
            "a simple convex polygon (its boundary winds around more than once)",
        ));
    }
    Ok(())
}

impl Shape {
    /// Local vertices in counter-clockwise order (boxes and polygons; `None` otherwise).
    pub fn vertices(&self) -> Option<Vec<[f64; 2]>> {
        match self {
            Shape::Box { width, height } => Some(box_vertices(*width, *height).to_vec()),
            Shape::Polygon { vertices } => Some(vertices.clone()),
            Shape::Circle { .. } | Shape::Wall => None,
        }
    }

    /// The shape's least width: the narrowest strip between two parallel lines that holds it
    /// (a circle's diameter, a box's shorter side, a convex polygon's least height over its
    /// edges); `None` for a wall, which no strip holds.
    pub fn least_width(&self) -> Option<f64> {
        match self {
            Shape::Circle { radius } => Some(2.0 * radius),
            Shape::Wall => None,
            Shape::Box { .. } | Shape::Polygon { .. } => {
                let v = self.vertices()?;
                let n = v.len();
                // For a convex polygon the narrowest strip lies along one of its edges.
                (0..n)
                    .map(|i| {
                        let (a, b) = (v[i], v[(i + 1) % n]);
                        let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
                        let len = ex.hypot(ey);
                        v.iter()
                            .map(|p| ((p[0] - a[0]) * ey - (p[1] - a[1]) * ex).abs() / len)
                            .fold(0.0, f64::max)
                    })
                    .reduce(f64::min)
            }
        }
    }

    /// How far the outline reaches from the shape's own origin, m: what a turn of the shape
    /// about its origin moves its outline by per radian. 0 for a circle (turning about its
    /// centre leaves its outline in place) and for a wall (`None`: a turning half-plane moves
    /// its far points without bound).
    fn turning_reach(&self) -> Option<f64> {
        match self {
            Shape::Circle { .. } => Some(0.0),
            Shape::Wall => None,
            Shape::Box { .. } | Shape::Polygon { .. } => self
                .vertices()
                .map(|v| v.iter().map(|p| p[0].hypot(p[1])).fold(0.0, f64::max)),
        }
    }
}

impl Object {
    /// The fastest that any point of the object's outline moves in the whisker's plane, m/s:
    /// its translation's speed plus its turning rate times its farthest vertex from its origin,
    /// taken over the whole prescribed motion (each leg of a waypoint path); `None` for a wall.
    pub fn fastest_outline_speed(&self) -> Option<f64> {
        let reach = self.shape.turning_reach()?;
        Some(match &self.motion {
            Motion::Constant {
                velocity,
                angular_velocity,
            } => velocity[0].hypot(velocity[1]) + angular_velocity.abs() * reach,
            Motion::Waypoints { points } => points
                .windows(2)
                .map(|w| {
                    let dt = w[1][0] - w[0][0];
                    ((w[1][1] - w[0][1]).hypot(w[1][2] - w[0][2])
                        + (w[1][3] - w[0][3]).abs() * reach)
                        / dt
                })
                .fold(0.0, f64::max),
        })
    }

    /// What bounds the object's contact step against a whisker whose points move at up to
    /// `whisker_speed` (m/s): in the plane, its least width against its outline's speed plus the
    /// whisker's; across the plane, its vertical extent against its vertical speed. The binding
    /// one (the shorter step), or `None` when nothing bounds it (a wall, or an object at rest
    /// against a whisker at rest).
    pub fn step_limit(&self, whisker_speed: f64) -> Option<StepLimit> {
        let in_plane = self
            .shape
            .least_width()
            .zip(self.fastest_outline_speed())
            .map(|(size, speed)| StepLimit {
                size,
                speed: speed + whisker_speed,
                across_plane: false,
            });
        let across = self.vertical.map(|v| StepLimit {
            size: v.top - v.bottom,
            speed: v.velocity.abs(),
            across_plane: true,
        });
        [in_plane, across]
            .into_iter()
            .flatten()
            .filter(|l| l.speed > 0.0)
            .min_by(|a, b| a.longest().total_cmp(&b.longest()))
    }

    /// The longest contact step, s, at which contact with the object is resolved
    /// ([`Object::step_limit`]'s [`StepLimit::longest`]).
    pub fn longest_contact_step(&self, whisker_speed: f64) -> Option<f64> {
        self.step_limit(whisker_speed).map(|l| l.longest())
    }
}

/// What bounds an object's contact step ([`Object::step_limit`]): contact with it is resolved
/// while it and the whisker close by no more than `size` per step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepLimit {
    /// The object's least width in the plane, or its height across it, m.
    pub size: f64,
    /// How fast it and the whisker close over that size, m/s (> 0).
    pub speed: f64,
    /// Whether the bound is its crossing of the whisker's plane (its `vertical` motion).
    pub across_plane: bool,
}

impl StepLimit {
    /// The longest contact step that keeps within the bound, s.
    pub fn longest(&self) -> f64 {
        self.size / self.speed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn object(shape: Shape, motion: Motion) -> Object {
        Object {
            shape,
            position: [1.0, 2.0],
            angle: 0.5,
            motion,
            friction: 0.3,
            vertical: None,
        }
    }

    #[test]
    fn poses_under_constant_and_waypoint_motion() {
        let o = object(
            Shape::Circle { radius: 0.1 },
            Motion::Constant {
                velocity: [0.5, -1.0],
                angular_velocity: 2.0,
            },
        );
        let p = o.pose(2.0);
        assert_eq!(p.position, [2.0, 0.0]);
        assert_eq!(p.angle, 4.5);
        assert_eq!(p.velocity, [0.5, -1.0]);
        assert_eq!(p.angular_velocity, 2.0);
        assert_eq!(p.velocity_at([3.0, 0.0]), [0.5, 1.0]);

        let o = object(
            Shape::Circle { radius: 0.1 },
            Motion::Waypoints {
                points: vec![
                    [1.0, 0.0, 0.0, 0.0],
                    [3.0, 2.0, 4.0, 1.0],
                    [4.0, 2.0, 4.0, 1.0],
                ],
            },
        );
        // Held before the first.
        let p = o.pose(0.0);
        assert_eq!(
            (p.position, p.angle, p.velocity),
            ([0.0, 0.0], 0.0, [0.0, 0.0])
        );
        // Between the first two.
        let p = o.pose(2.0);
        assert_eq!(p.position, [1.0, 2.0]);
        assert_eq!(p.angle, 0.5);
        assert_eq!(p.velocity, [1.0, 2.0]);
        assert_eq!(p.angular_velocity, 0.5);
        // Exactly at a middle waypoint, then at rest.
        let p = o.pose(3.0);
        assert_eq!(p.position, [2.0, 4.0]);
        assert_eq!(p.velocity, [0.0, 0.0]);
        // Held after the last.
        let p = o.pose(9.0);
        assert_eq!(
            (p.position, p.angle, p.angular_velocity),
            ([2.0, 4.0], 1.0, 0.0)
        );
        // A single waypoint.
        let o = object(
            Shape::Wall,
            Motion::Waypoints {
                points: vec![[1.0, 3.0, 4.0, 0.1]],
            },
        );
        assert_eq!(o.pose(5.0).position, [3.0, 4.0]);
        assert!(o.check("o").is_ok());
    }

    fn error_name(o: &Object) -> String {
        match o.check("objects[0]") {
            Err(Error::InvalidParameter { name, .. }) => name,
            other => panic!("expected an invalid parameter, got {other:?}"),
        }
    }

    #[test]
    fn check_names_the_bad_field() {
        let still = Motion::default();
        let poly = |vertices: Vec<[f64; 2]>| object(Shape::Polygon { vertices }, Motion::default());
        assert!(poly(vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
            .check("o")
            .is_ok());
        // Non-convex, clockwise, too few, and a star winding twice.
        let dart = vec![[0.0, 0.0], [2.0, 0.0], [1.0, 0.3], [1.0, 2.0]];
        assert_eq!(error_name(&poly(dart)), "objects[0].vertices");
        let clockwise = vec![[0.0, 0.0], [0.0, 1.0], [1.0, 0.0]];
        assert_eq!(error_name(&poly(clockwise)), "objects[0].vertices");
        assert_eq!(
            error_name(&poly(vec![[0.0, 0.0], [1.0, 0.0]])),
            "objects[0].vertices"
        );
        let star = (0..5)
            .map(|k| {
                let t = (2 * k) as f64 * std::f64::consts::TAU / 5.0;
                [t.cos(), t.sin()]
            })
            .collect();
        assert_eq!(error_name(&poly(star)), "objects[0].vertices");
        // Sizes.
        let o = object(Shape::Circle { radius: -1.0 }, still.clone());
        assert_eq!(error_name(&o), "objects[0].radius");
        let o = object(
            Shape::Box {
                width: 1.0,
                height: 0.0,
            },
            still.clone(),
        );
        assert_eq!(error_name(&o), "objects[0].height");
        // Placement, friction and motion.
        let mut o = object(Shape::Wall, still.clone());
        o.position[1] = f64::NAN;
        assert_eq!(error_name(&o), "objects[0].position[1]");
        let mut o = object(Shape::Wall, still);
        o.friction = -0.1;
        assert_eq!(error_name(&o), "objects[0].friction");
        let o = object(
            Shape::Wall,
            Motion::Waypoints {
                points: vec![
                    [0.0, 0.0, 0.0, 0.0],
                    [1.0, 0.0, 0.0, 0.0],
                    [0.5, 0.0, 0.0, 0.0],
                ],
            },
        );
        assert_eq!(error_name(&o), "objects[0].motion.points[2][0]");
        let o = object(Shape::Wall, Motion::Waypoints { points: vec![] });
        assert_eq!(error_name(&o), "objects[0].motion.points");
        let o = object(
            Shape::Wall,
            Motion::Constant {
                velocity: [0.0, f64::INFINITY],
                angular_velocity: 0.0,
            },
        );
        assert_eq!(error_name(&o), "objects[0].motion.velocity[1]");
    }

    #[test]
    fn least_widths_of_the_shapes() {
        let close = |a: Option<f64>, b: f64| (a.unwrap() - b).abs() < 1e-12;
        assert!(close(Shape::Circle { radius: 0.003 }.least_width(), 0.006));
        let plate = Shape::Box {
            width: 0.01,
            height: 0.002,
        };
        assert!(close(plate.least_width(), 0.002));
        // An equilateral triangle of side 2: its height, √3.
        let tri = Shape::Polygon {
            vertices: vec![[0.0, 0.0], [2.0, 0.0], [1.0, 3f64.sqrt()]],
        };
        assert!(close(tri.least_width(), 3f64.sqrt()));
        assert_eq!(Shape::Wall.least_width(), None);
    }

    #[test]
    fn the_outline_s_fastest_speed_counts_turning_and_every_leg() {
        let turning_box = object(
            Shape::Box {
                width: 0.006,
                height: 0.008,
            },
            Motion::Constant {
                velocity: [0.3, 0.4],
                angular_velocity: -2.0,
            },
        );
        // 0.5 m/s, plus 2 rad/s times the half-diagonal 5 mm.
        let v = turning_box.fastest_outline_speed().unwrap();
        assert!((v - 0.51).abs() < 1e-12, "{v}");
        // A disc turning about its centre moves its outline only by its translation.
        let disc = object(
            Shape::Circle { radius: 0.004 },
            Motion::Constant {
                velocity: [0.0, 1.0],
                angular_velocity: 50.0,
            },
        );
        assert_eq!(disc.fastest_outline_speed(), Some(1.0));
        // The fastest leg of a path: 3 mm in 1 ms.
        let path = object(
            Shape::Circle { radius: 0.004 },
            Motion::Waypoints {
                points: vec![
                    [0.0, 0.0, 0.0, 0.0],
                    [0.01, 0.001, 0.0, 0.0],
                    [0.011, 0.001, 0.003, 0.0],
                ],
            },
        );
        assert!((path.fastest_outline_speed().unwrap() - 3.0).abs() < 1e-9);
        // Its longest contact step: 8 mm at 3 m/s; at rest, or a wall, nothing bounds it.
        assert!((path.longest_contact_step(0.0).unwrap() - 0.008 / 3.0).abs() < 1e-12);
        let still = object(Shape::Circle { radius: 0.004 }, Motion::default());
        assert_eq!(still.longest_contact_step(0.0), None);
        // The same peg against a whisker sweeping at 2 m/s: 8 mm at 2 m/s.
        assert!((still.longest_contact_step(2.0).unwrap() - 4e-3).abs() < 1e-15);
        let wall = object(Shape::Wall, Motion::default());
        assert_eq!(wall.longest_contact_step(1.0), None);
        // An object 2 mm tall crossing the plane at 4 m/s: 0.5 ms, whatever its width.
        let mut lifting = wall;
        lifting.vertical = Some(Vertical {
            bottom: -0.001,
            top: 0.001,
            velocity: 4.0,
        });
        assert!((lifting.longest_contact_step(0.0).unwrap() - 5e-4).abs() < 1e-15);
    }
}
