//! Nearest points, bounds and containment of the shapes: the geometry that contact asks of an
//! object at its pose.

use super::{turn, Pose, Shape};

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
///
/// The segment must have a non-zero length. The result satisfies
/// `on_whisker = a + u (b − a)` and `on_whisker ≈ on_object + distance · normal`.
///
/// - Circle: the segment point nearest the centre, pushed radially.
/// - Box and polygon, apart: the exact nearest pair. Where a vertex faces the segment's
///   interior the normal is the segment's own perpendicular; where an endpoint faces an
///   edge's interior it is the edge's outward normal. Near-ties (within rounding) go to the
///   smaller `u`.
/// - Box and polygon, touching or overlapping: the axis of least penetration among the
///   edge normals (for the part of the segment inside) and the segment's two normals; the
///   deepest segment point along it, pushed to the surface line along that axis.
/// - Wall: the endpoint lower in the wall's frame (`a` on exact ties), pushed along local +y.
pub fn closest(shape: &Shape, pose: &Pose, a: [f64; 2], b: [f64; 2]) -> Closest {
    let (la, lb) = (pose.to_local(a), pose.to_local(b));
    let local = match shape {
        Shape::Circle { radius } => closest_circle(*radius, la, lb),
        Shape::Wall => closest_wall(la, lb),
        Shape::Box { width, height } => closest_box(*width, *height, la, lb),
        Shape::Polygon { vertices } => closest_polygon(vertices, la, lb),
    };
    // Back to the world frame; the whisker point is taken on the world segment itself.
    let u = local.u;
    let on_whisker = if u == 0.0 {
        a
    } else if u == 1.0 {
        b
    } else {
        [a[0] + u * (b[0] - a[0]), a[1] + u * (b[1] - a[1])]
    };
    let (s, c) = turn(pose.angle);
    let n = local.normal;
    Closest {
        u,
        on_whisker,
        on_object: pose.to_world(local.on_object),
        normal: [c * n[0] - s * n[1], s * n[0] + c * n[1]],
        distance: local.distance,
    }
}

/// Axis-aligned bounding box of `shape` at `pose`, `[xmin, ymin, xmax, ymax]` (a wall's is
/// unbounded).
pub fn bounds(shape: &Shape, pose: &Pose) -> [f64; 4] {
    // Union of transformed vertices.
    let over = |v: &[[f64; 2]]| {
        v.iter().fold(
            [
                f64::INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
            ],
            |r, &l| {
                let p = pose.to_world(l);
                [
                    r[0].min(p[0]),
                    r[1].min(p[1]),
                    r[2].max(p[0]),
                    r[3].max(p[1]),
                ]
            },
        )
    };
    match shape {
        Shape::Circle { radius } => {
            let c = pose.position;
            [c[0] - radius, c[1] - radius, c[0] + radius, c[1] + radius]
        }
        Shape::Wall => [
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::INFINITY,
        ],
        Shape::Box { width, height } => over(&box_vertices(*width, *height)),
        Shape::Polygon { vertices } => over(vertices),
    }
}

/// Whether the world point `p` lies inside or on the boundary of `shape` at `pose`.
pub fn contains(shape: &Shape, pose: &Pose, p: [f64; 2]) -> bool {
    let l = pose.to_local(p);
    match shape {
        Shape::Circle { radius } => dot(l, l) <= radius * radius,
        Shape::Wall => l[1] <= 0.0,
        Shape::Box { width, height } => l[0].abs() <= 0.5 * width && l[1].abs() <= 0.5 * height,
        Shape::Polygon { vertices } => {
            let n = vertices.len();
            (0..n).all(|i| {
                let (v0, v1) = (vertices[i], vertices[(i + 1) % n]);
                cross(sub(v1, v0), sub(l, v0)) >= 0.0
            })
        }
    }
}

pub(super) fn box_vertices(width: f64, height: f64) -> [[f64; 2]; 4] {
    let (w, h) = (0.5 * width, 0.5 * height);
    [[-w, -h], [w, -h], [w, h], [-w, h]]
}

fn sub(p: [f64; 2], q: [f64; 2]) -> [f64; 2] {
    [p[0] - q[0], p[1] - q[1]]
}

fn dot(p: [f64; 2], q: [f64; 2]) -> f64 {
    p[0] * q[0] + p[1] * q[1]
}

fn cross(p: [f64; 2], q: [f64; 2]) -> f64 {
    p[0] * q[1] - p[1] * q[0]
}

/// Euclidean length of `v` (plain square root: lengths here are far from overflow, and libm's
/// `hypot` costs several times more in the narrow phase).
fn norm(v: [f64; 2]) -> f64 {
    (v[0] * v[0] + v[1] * v[1]).sqrt()
}

fn along(a: [f64; 2], d: [f64; 2], u: f64) -> [f64; 2] {
    [a[0] + u * d[0], a[1] + u * d[1]]
}

/// Unit left normal of the segment `a → a + d`.
fn left_normal(d: [f64; 2]) -> [f64; 2] {
    let len = norm(d);
    [-d[1] / len, d[0] / len]
}

/// Unit outward normal of the edge `v0 → v1` of a counter-clockwise polygon.
fn outward_normal(v0: [f64; 2], v1: [f64; 2]) -> [f64; 2] {
    let e = sub(v1, v0);
    let len = norm(e);
    [e[1] / len, -e[0] / len]
}

/// A result in the shape's frame.
fn local_result(u: f64, p: [f64; 2], q: [f64; 2], normal: [f64; 2], distance: f64) -> Closest {
    Closest {
        u,
        on_whisker: p,
        on_object: q,
        normal,
        distance,
    }
}

fn closest_circle(radius: f64, a: [f64; 2], b: [f64; 2]) -> Closest {
    // Segment point nearest the centre.
    let d = sub(b, a);
    let u = (-dot(a, d) / dot(d, d)).clamp(0.0, 1.0);
    let p = along(a, d, u);
    let r = norm(p);
    // Radial normal; the segment's left normal when the axis passes through the centre.
    let normal = if r > 0.0 {
        [p[0] / r, p[1] / r]
    } else {
        left_normal(d)
    };
    let q = [radius * normal[0], radius * normal[1]];
    local_result(u, p, q, normal, r - radius)
}

fn closest_wall(a: [f64; 2], b: [f64; 2]) -> Closest {
    // Lower endpoint, `a` on ties.
    let (u, p) = if b[1] < a[1] { (1.0, b) } else { (0.0, a) };
    local_result(u, p, [p[0], 0.0], [0.0, 1.0], p[1])
}

/// Keeps the better of two candidates: smaller `key`, or smaller `u` within `tol`.
fn better(best: &mut Option<(f64, Closest)>, key: f64, c: Closest, tol: f64) {
    let take = match best {
        None => true,
        Some((k, o)) => key < *k - tol || (key <= *k + tol && c.u < o.u),
    };
    if take {
        *best = Some((key, c));
    }
}

/// [`closest_polygon`] for a box centred on the origin, with the same candidates and ties: when
/// the segment is clear of the box, each endpoint's nearest box point is the endpoint clamped
/// into the box, which saves the edge-by-edge search. Overlapping or touching segments take the
/// general path.
fn closest_box(width: f64, height: f64, a: [f64; 2], b: [f64; 2]) -> Closest {
    let (hw, hh) = (0.5 * width, 0.5 * height);
    let d = sub(b, a);
    let m = left_normal(d);
    // Separating axes: the box's edge normals (the axes) and the segment's normal.
    let apart_axes =
        a[0].min(b[0]) > hw || a[0].max(b[0]) < -hw || a[1].min(b[1]) > hh || a[1].max(b[1]) < -hh;
    let half = m[0].abs() * hw + m[1].abs() * hh;
    let ma = dot(m, a);
    let v = box_vertices(width, height);
    if !(apart_axes || ma > half || ma < -half) {
        return closest_polygon(&v, a, b);
    }
    let size = hw
        .max(hh)
        .max(a[0].abs())
        .max(a[1].abs())
        .max(b[0].abs())
        .max(b[1].abs());
    let tol = 1e-12 * size;
    let mut best = None;
    for (u, p) in [(0.0, a), (1.0, b)] {
        let q = [p[0].clamp(-hw, hw), p[1].clamp(-hh, hh)];
        let gap = sub(p, q);
        let dist = norm(gap);
        if dist == 0.0 {
            return closest_polygon(&v, a, b);
        }
        better(
            &mut best,
            dist,
            local_result(u, p, q, [gap[0] / dist, gap[1] / dist], dist),
            tol,
        );
    }
    vertices_against_interior(&v, a, b, tol, &mut best);
    best.expect("a segment has two endpoints").1
}

fn closest_polygon(v: &[[f64; 2]], a: [f64; 2], b: [f64; 2]) -> Closest {
    let n = v.len();
    let d = sub(b, a);
    let m = left_normal(d);
    // Rounding tolerance for ties, from the size of the configuration.
    let size = v
        .iter()
        .chain([&a, &b])
        .fold(0.0f64, |s, p| s.max(p[0].abs()).max(p[1].abs()));
    let tol = 1e-12 * size;

    // Separating-axis test over the edge normals and the segment's normal.
    let edge_apart = (0..n).any(|i| {
        let e = outward_normal(v[i], v[(i + 1) % n]);
        dot(e, a).min(dot(e, b)) > dot(e, v[i])
    });
    let ma = dot(m, a);
    let (lo, hi) = v
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &p| {
            let s = dot(m, p);
            (lo.min(s), hi.max(s))
        });
    if edge_apart || lo > ma || hi < ma {
        polygon_apart(v, a, b, tol)
    } else {
        polygon_overlap(v, a, b, (lo, hi), tol)
    }
}

fn polygon_apart(v: &[[f64; 2]], a: [f64; 2], b: [f64; 2], tol: f64) -> Closest {
    let n = v.len();
    let mut best = None;
    // Each endpoint against each edge.
    for (u, p) in [(0.0, a), (1.0, b)] {
        for i in 0..n {
            let (v0, v1) = (v[i], v[(i + 1) % n]);
            let e = sub(v1, v0);
            let t = (dot(sub(p, v0), e) / dot(e, e)).clamp(0.0, 1.0);
            let q = along(v0, e, t);
            let gap = sub(p, q);
            let dist = norm(gap);
            // Edge normal facing an edge's interior, else from the vertex to the endpoint.
            let normal = if (t > 0.0 && t < 1.0) || dist == 0.0 {
                outward_normal(v0, v1)
            } else {
                [gap[0] / dist, gap[1] / dist]
            };
            better(&mut best, dist, local_result(u, p, q, normal, dist), tol);
        }
    }
    vertices_against_interior(v, a, b, tol, &mut best);
    best.expect("a polygon has at least one edge").1
}

/// Candidates of a polygon clear of the segment `a → b`: each vertex against the segment's
/// interior, pushed along the segment's perpendicular.
fn vertices_against_interior(
    v: &[[f64; 2]],
    a: [f64; 2],
    b: [f64; 2],
    tol: f64,
    best: &mut Option<(f64, Closest)>,
) {
    let d = sub(b, a);
    let len2 = dot(d, d);
    let m = left_normal(d);
    for &q in v {
        let u = dot(sub(q, a), d) / len2;
        if u > 0.0 && u < 1.0 {
            let side = dot(m, sub(a, q));
            let normal = if side >= 0.0 { m } else { [-m[0], -m[1]] };
            let dist = side.abs();
            better(
                best,
                dist,
                local_result(u, along(a, d, u), q, normal, dist),
                tol,
            );
        }
    }
}

fn polygon_overlap(
    v: &[[f64; 2]],
    a: [f64; 2],
    b: [f64; 2],
    (lo, hi): (f64, f64),
    tol: f64,
) -> Closest {
    let n = v.len();
    let d = sub(b, a);
    let len2 = dot(d, d);
    let m = left_normal(d);
    // Part of the segment inside the polygon, [u0, u1].
    let (mut u0, mut u1) = (0.0f64, 1.0f64);
    for i in 0..n {
        let e = outward_normal(v[i], v[(i + 1) % n]);
        let (fa, fd) = (dot(e, a) - dot(e, v[i]), dot(e, d));
        if fd > 0.0 {
            u1 = u1.min(-fa / fd);
        } else if fd < 0.0 {
            u0 = u0.max(-fa / fd);
        }
    }
    // Rounding can leave an empty interval when only touching.
    if u0 > u1 {
        let mid = (0.5 * (u0 + u1)).clamp(0.0, 1.0);
        (u0, u1) = (mid, mid);
    }
    let mut best = None;
    // Edge axes: the deepest inside point below each edge's line.
    for i in 0..n {
        let e = outward_normal(v[i], v[(i + 1) % n]);
        let h = dot(e, v[i]);
        let (p0, p1) = (along(a, d, u0), along(a, d, u1));
        let (u, p) = if dot(e, p1) < dot(e, p0) {
            (u1, p1)
        } else {
            (u0, p0)
        };
        let depth = h - dot(e, p);
        let q = [p[0] + depth * e[0], p[1] + depth * e[1]];
        better(&mut best, depth, local_result(u, p, q, e, -depth), tol);
    }
    // Segment axes: the vertex reaching furthest across the axis, on either side.
    let ma = dot(m, a);
    for (sign, reach) in [(1.0, hi), (-1.0, lo)] {
        let normal = [sign * m[0], sign * m[1]];
        let depth = sign * (reach - ma);
        // Among vertices that reach equally far, the one over the smaller u.
        let u = v
            .iter()
            .filter(|&&q| (dot(m, q) - reach).abs() <= tol)
            .map(|&q| (dot(sub(q, a), d) / len2).clamp(0.0, 1.0))
            .fold(f64::INFINITY, f64::min);
        let p = along(a, d, u);
        let q = [p[0] + depth * normal[0], p[1] + depth * normal[1]];
        better(&mut best, depth, local_result(u, p, q, normal, -depth), tol);
    }
    best.expect("a polygon has at least one edge").1
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::objects::check_convex_ccw;

    #[test]
    fn box_shortcut_matches_the_general_polygon() {
        let mut rng = crate::rng::Rng::stream(11, 0);
        let (w, h) = (0.6, 0.3);
        let v = box_vertices(w, h);
        for _ in 0..20_000 {
            let mut p = || [2.0 * rng.uniform() - 1.0, 2.0 * rng.uniform() - 1.0];
            let (a, b) = (p(), p());
            let (fast, slow) = (closest_box(w, h, a, b), closest_polygon(&v, a, b));
            assert_close(fast.distance, slow.distance, 1e-12);
            assert_close(fast.u, slow.u, 1e-9);
            assert_near(fast.on_object, slow.on_object, 1e-9);
            assert_near(fast.on_whisker, slow.on_whisker, 1e-9);
            assert_near(fast.normal, slow.normal, 1e-9);
        }
    }
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, SQRT_2};

    // Tiny deterministic generator of uniforms in [0, 1).
    struct Lcg(u64);

    impl Lcg {
        fn next(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }

        fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * self.next()
        }
    }

    fn at(x: f64, y: f64, angle: f64) -> Pose {
        Pose {
            position: [x, y],
            angle,
            ..Default::default()
        }
    }

    fn near(p: [f64; 2], q: [f64; 2], tol: f64) -> bool {
        (p[0] - q[0]).hypot(p[1] - q[1]) <= tol
    }

    fn assert_near(p: [f64; 2], q: [f64; 2], tol: f64) {
        assert!(near(p, q, tol), "{p:?} vs {q:?}");
    }

    fn assert_close(x: f64, y: f64, tol: f64) {
        assert!((x - y).abs() <= tol, "{x} vs {y}");
    }

    // The invariants every result keeps.
    fn consistent(c: &Closest, a: [f64; 2], b: [f64; 2]) {
        assert!((0.0..=1.0).contains(&c.u), "{c:?}");
        assert_close(c.normal[0].hypot(c.normal[1]), 1.0, 1e-12);
        assert_near(c.on_whisker, along(a, sub(b, a), c.u), 1e-12);
        let back = [
            c.on_object[0] + c.distance * c.normal[0],
            c.on_object[1] + c.distance * c.normal[1],
        ];
        assert_near(c.on_whisker, back, 1e-9);
    }

    fn diamond(half_diagonal: f64) -> Shape {
        Shape::Box {
            width: half_diagonal * SQRT_2,
            height: half_diagonal * SQRT_2,
        }
    }

    #[test]
    fn box_corner_below_and_above_a_segment() {
        let (a, b) = ([0.0, 0.0], [1.0, 0.0]);
        // Corner at (0.4, -0.05) under the segment: push the whisker up.
        let c = closest(&diamond(0.1), &at(0.4, -0.15, FRAC_PI_4), a, b);
        consistent(&c, a, b);
        assert_close(c.u, 0.4, 1e-12);
        assert_close(c.distance, 0.05, 1e-12);
        assert_near(c.normal, [0.0, 1.0], 1e-12);
        assert_near(c.on_object, [0.4, -0.05], 1e-12);
        assert_near(c.on_whisker, [0.4, 0.0], 1e-12);
        // Above: push down.
        let c = closest(&diamond(0.1), &at(0.4, 0.15, FRAC_PI_4), a, b);
        consistent(&c, a, b);
        assert_close(c.distance, 0.05, 1e-12);
        assert_near(c.normal, [0.0, -1.0], 1e-12);
        // The reversed segment gives the same pair.
        let c = closest(&diamond(0.1), &at(0.4, -0.15, FRAC_PI_4), b, a);
        consistent(&c, b, a);
        assert_close(c.u, 0.6, 1e-12);
        assert_near(c.normal, [0.0, 1.0], 1e-12);
    }

    #[test]
    fn box_face_parallel_to_a_segment() {
        let shape = Shape::Box {
            width: 1.0,
            height: 1.0,
        };
        let pose = at(1.0, 0.0, 0.0);
        // Face shorter than the segment: its first vertex, at the smaller u.
        let (a, b) = ([0.0, 1.0], [2.0, 1.0]);
        let c = closest(&shape, &pose, a, b);
        consistent(&c, a, b);
        assert_close(c.distance, 0.5, 1e-12);
        assert_close(c.u, 0.25, 1e-12);
        assert_near(c.on_object, [0.5, 0.5], 1e-12);
        assert_near(c.normal, [0.0, 1.0], 1e-12);
        // Segment wholly over the face: its start.
        let (a, b) = ([0.7, 1.0], [1.2, 1.0]);
        let c = closest(&shape, &pose, a, b);
        consistent(&c, a, b);
        assert_eq!(c.u, 0.0);
        assert_close(c.distance, 0.5, 1e-12);
        assert_near(c.on_object, [0.7, 0.5], 1e-12);
        // Same when the face is tilted with the whole configuration.
        let tilt = at(0.2, -0.3, 0.7);
        let pose = at(1.0, 0.0, 0.0);
        let moved = at_composed(&tilt, &pose);
        let (a2, b2) = (tilt.to_world(a), tilt.to_world(b));
        let c = closest(&shape, &moved, a2, b2);
        assert_eq!(c.u, 0.0);
        assert_close(c.distance, 0.5, 1e-12);
    }

    // The pose of `inner` seen from a frame placed at `outer`.
    fn at_composed(outer: &Pose, inner: &Pose) -> Pose {
        Pose {
            position: outer.to_world(inner.position),
            angle: outer.angle + inner.angle,
            ..Default::default()
        }
    }

    #[test]
    fn circle_tangent_penetrating_and_through_the_centre() {
        let shape = Shape::Circle { radius: 0.3 };
        let pose = at(1.0, 2.0, 0.9);
        let (a, b) = ([0.0, 2.3], [2.0, 2.3]);
        let c = closest(&shape, &pose, a, b);
        consistent(&c, a, b);
        assert_close(c.u, 0.5, 1e-12);
        assert_close(c.distance, 0.0, 1e-12);
        assert_near(c.normal, [0.0, 1.0], 1e-12);
        assert_near(c.on_object, [1.0, 2.3], 1e-12);
        // Apart, nearest at an endpoint.
        let (a, b) = ([2.0, 2.0], [3.0, 2.0]);
        let c = closest(&shape, &pose, a, b);
        consistent(&c, a, b);
        assert_eq!(c.u, 0.0);
        assert_close(c.distance, 0.7, 1e-12);
        assert_near(c.normal, [1.0, 0.0], 1e-12);
        // Entered by 0.2.
        let (a, b) = ([0.0, 2.1], [2.0, 2.1]);
        let c = closest(&shape, &pose, a, b);
        consistent(&c, a, b);
        assert_close(c.distance, -0.2, 1e-12);
        assert_near(c.on_object, [1.0, 2.3], 1e-12);
        // Through the centre: the segment's left normal.
        let (a, b) = ([0.0, 2.0], [2.0, 2.0]);
        let c = closest(&shape, &at(1.0, 2.0, 0.0), a, b);
        consistent(&c, a, b);
        assert_close(c.distance, -0.3, 1e-12);
        assert_near(c.normal, [0.0, 1.0], 1e-12);
    }

    #[test]
    fn segment_entering_a_box_reports_the_least_penetration() {
        let square = Shape::Box {
            width: 2.0,
            height: 2.0,
        };
        // Tip 0.1 below the top face; the side faces are much further.
        let (a, b) = ([0.0, 3.0], [0.3, 0.9]);
        let c = closest(&square, &Pose::default(), a, b);
        consistent(&c, a, b);
        assert_eq!(c.u, 1.0);
        assert_close(c.distance, -0.1, 1e-12);
        assert_near(c.normal, [0.0, 1.0], 1e-12);
        assert_near(c.on_object, [0.3, 1.0], 1e-12);
        // Same, with the whole configuration moved.
        let frame = at(-1.0, 0.5, 2.0);
        let c = closest(&square, &frame, frame.to_world(a), frame.to_world(b));
        assert_close(c.distance, -0.1, 1e-12);
        assert_near(c.on_object, frame.to_world([0.3, 1.0]), 1e-12);
        // Corner 0.02 into the segment's side: the segment's normal is the best axis.
        let (a, b) = ([0.0, 0.0], [1.0, 0.0]);
        let c = closest(&diamond(0.1), &at(0.4, -0.08, FRAC_PI_4), a, b);
        consistent(&c, a, b);
        assert_close(c.u, 0.4, 1e-12);
        assert_close(c.distance, -0.02, 1e-12);
        assert_near(c.normal, [0.0, 1.0], 1e-12);
        assert_near(c.on_object, [0.4, 0.02], 1e-12);
        // Crossing a box: 0.1 below the top face, first point inside.
        let unit = Shape::Box {
            width: 1.0,
            height: 1.0,
        };
        let (a, b) = ([-2.0, 0.4], [2.0, 0.4]);
        let c = closest(&unit, &Pose::default(), a, b);
        consistent(&c, a, b);
        assert_close(c.distance, -0.1, 1e-12);
        assert_close(c.u, 0.375, 1e-12);
        assert_near(c.normal, [0.0, 1.0], 1e-12);
        assert_near(c.on_object, [-0.5, 0.5], 1e-12);
    }

    #[test]
    fn touching_is_distance_zero_from_both_sides() {
        let (a, b) = ([0.0, 0.0], [1.0, 0.0]);
        for dy in [-1e-9, 0.0, 1e-9] {
            let c = closest(&diamond(0.1), &at(0.4, -0.1 + dy, FRAC_PI_4), a, b);
            consistent(&c, a, b);
            assert_close(c.distance, -dy, 1e-12);
            assert_close(c.u, 0.4, 1e-9);
            assert_near(c.normal, [0.0, 1.0], 1e-9);
        }
    }

    #[test]
    fn wall() {
        // Surface y = -1, outward +y.
        let (a, b) = ([0.0, 0.0], [1.0, -1.5]);
        let c = closest(&Shape::Wall, &at(0.0, -1.0, 0.0), a, b);
        consistent(&c, a, b);
        assert_eq!(c.u, 1.0);
        assert_close(c.distance, -0.5, 1e-12);
        assert_near(c.on_object, [1.0, -1.0], 1e-12);
        assert_near(c.normal, [0.0, 1.0], 1e-12);
        // Turned a quarter: the wall fills x >= 1.5 and faces -x.
        let (a, b) = ([0.0, 0.0], [2.0, 0.0]);
        let c = closest(&Shape::Wall, &at(1.5, 0.0, FRAC_PI_2), a, b);
        consistent(&c, a, b);
        assert_eq!(c.u, 1.0);
        assert_close(c.distance, -0.5, 1e-12);
        assert_near(c.normal, [-1.0, 0.0], 1e-12);
        assert_near(c.on_object, [1.5, 0.0], 1e-12);
        // Parallel: the start.
        let (a, b) = ([0.0, 1.0], [1.0, 1.0]);
        let c = closest(&Shape::Wall, &Pose::default(), a, b);
        assert_eq!(c.u, 0.0);
        assert_close(c.distance, 1.0, 0.0);
        assert_near(c.on_object, [0.0, 0.0], 0.0);
    }

    fn shapes() -> Vec<Shape> {
        vec![
            Shape::Box {
                width: 0.6,
                height: 0.3,
            },
            Shape::Circle { radius: 0.25 },
            Shape::Polygon {
                vertices: vec![[-0.3, -0.2], [0.4, -0.1], [0.2, 0.3], [-0.2, 0.25]],
            },
            Shape::Wall,
        ]
    }

    #[test]
    fn rigid_motion_of_everything_moves_the_result_with_it() {
        let segments = [
            ([-1.0, 0.6], [1.0, 0.7]),
            ([0.5, 0.5], [1.5, -0.2]),
            ([-0.8, -0.6], [0.1, 0.05]),
            ([-0.7, 0.1], [0.7, -0.05]),
        ];
        let pose = at(0.1, -0.05, 0.3);
        let frame = at(2.0, -3.0, 1.1);
        let moved = at_composed(&frame, &pose);
        let (s, c) = turn(frame.angle);
        let turn = |n: [f64; 2]| [c * n[0] - s * n[1], s * n[0] + c * n[1]];
        for shape in shapes() {
            for &(a, b) in &segments {
                let c0 = closest(&shape, &pose, a, b);
                consistent(&c0, a, b);
                let (a1, b1) = (frame.to_world(a), frame.to_world(b));
                let c1 = closest(&shape, &moved, a1, b1);
                consistent(&c1, a1, b1);
                assert_close(c1.u, c0.u, 1e-9);
                assert_close(c1.distance, c0.distance, 1e-9);
                assert_near(c1.on_whisker, frame.to_world(c0.on_whisker), 1e-9);
                assert_near(c1.on_object, frame.to_world(c0.on_object), 1e-9);
                assert_near(c1.normal, turn(c0.normal), 1e-9);
                // The same computed in the shape's own frame, mapped back.
                let cl = closest(&shape, &Pose::default(), pose.to_local(a), pose.to_local(b));
                assert_close(cl.u, c0.u, 1e-9);
                assert_close(cl.distance, c0.distance, 1e-9);
                assert_near(pose.to_world(cl.on_object), c0.on_object, 1e-9);
            }
        }
    }

    #[test]
    fn sliding_a_corner_along_the_segment_is_continuous() {
        let (a, b) = ([0.0, 0.0], [1.0, 0.0]);
        let step = 1e-3;
        let shape = diamond(0.1);
        let mut last: Option<Closest> = None;
        for k in 0..=2000 {
            let x = -0.5 + k as f64 * step;
            let c = closest(&shape, &at(x, -0.15, FRAC_PI_4 + 0.05), a, b);
            consistent(&c, a, b);
            assert!(c.distance > 0.0);
            if let Some(p) = last {
                assert!(
                    near(c.on_whisker, p.on_whisker, step + 1e-12),
                    "{k}: {p:?} -> {c:?}"
                );
                assert_close(c.distance, p.distance, step + 1e-12);
                assert!(
                    near(c.normal, p.normal, 2.0 * step / 0.04),
                    "{k}: {p:?} -> {c:?}"
                );
            }
            last = Some(c);
        }
        // Turning a polygon under the segment changes the distance no faster than its points move.
        let poly = &shapes()[2];
        let (centre, reach, dtheta) = ([0.5, -0.5], 0.6, 1e-3);
        let mut last: Option<Closest> = None;
        for k in 0..=6300 {
            let c = closest(poly, &at(centre[0], centre[1], k as f64 * dtheta), a, b);
            consistent(&c, a, b);
            if let Some(p) = last {
                assert_close(c.distance, p.distance, reach * dtheta);
            }
            last = Some(c);
        }
    }

    // A random convex polygon: points on a circle, stretched and turned.
    fn random_polygon(rng: &mut Lcg) -> Vec<[f64; 2]> {
        let k = 3 + (rng.next() * 6.0) as usize;
        let mut angles: Vec<f64> = (0..k)
            .map(|_| rng.range(0.0, std::f64::consts::TAU))
            .collect();
        angles.sort_by(f64::total_cmp);
        let (sx, sy, turn) = (
            rng.range(0.2, 1.0),
            rng.range(0.2, 1.0),
            rng.range(0.0, 6.3),
        );
        let (s, c) = f64::sin_cos(turn);
        angles
            .iter()
            .map(|t| {
                let (x, y) = (sx * t.cos(), sy * t.sin());
                [c * x - s * y, s * x + c * y]
            })
            .collect()
    }

    fn point_to_segment(p: [f64; 2], v0: [f64; 2], v1: [f64; 2]) -> f64 {
        let e = sub(v1, v0);
        let t = (dot(sub(p, v0), e) / dot(e, e)).clamp(0.0, 1.0);
        let g = sub(p, along(v0, e, t));
        g[0].hypot(g[1])
    }

    #[test]
    fn random_polygons_match_brute_force() {
        let mut rng = Lcg(7);
        let spacing = 2e-3;
        let (mut apart, mut overlapping) = (0, 0);
        while apart < 60 {
            let local = random_polygon(&mut rng);
            if check_convex_ccw("p", &local).is_err() {
                continue;
            }
            let pose = at(
                rng.range(-0.5, 0.5),
                rng.range(-0.5, 0.5),
                rng.range(-4.0, 4.0),
            );
            let world: Vec<_> = local.iter().map(|&l| pose.to_world(l)).collect();
            let shape = Shape::Polygon { vertices: local };
            let a = [rng.range(-2.0, 2.0), rng.range(-2.0, 2.0)];
            let b = [rng.range(-2.0, 2.0), rng.range(-2.0, 2.0)];
            let len = sub(b, a)[0].hypot(sub(b, a)[1]);
            if len < 0.1 {
                continue;
            }
            let c = closest(&shape, &pose, a, b);
            consistent(&c, a, b);
            // The object point is on the boundary.
            let n = world.len();
            let off = (0..n)
                .map(|i| point_to_segment(c.on_object, world[i], world[(i + 1) % n]))
                .fold(f64::INFINITY, f64::min);
            if c.distance <= 0.0 {
                overlapping += 1;
                continue;
            }
            assert!(off < 1e-9, "{off}");
            assert!(contains(&shape, &pose, c.on_object) || off < 1e-9);
            // Brute force over samples of the segment and the boundary.
            let ns = (len / spacing).ceil() as usize;
            let whisker: Vec<_> = (0..=ns)
                .map(|j| along(a, sub(b, a), j as f64 / ns as f64))
                .collect();
            let mut boundary = Vec::new();
            for i in 0..n {
                let e = sub(world[(i + 1) % n], world[i]);
                let ne = (e[0].hypot(e[1]) / spacing).ceil() as usize;
                boundary.extend((0..ne).map(|j| along(world[i], e, j as f64 / ne as f64)));
            }
            let brute = whisker
                .iter()
                .flat_map(|p| boundary.iter().map(move |q| sub(*p, *q)))
                .map(|g| g[0] * g[0] + g[1] * g[1])
                .fold(f64::INFINITY, f64::min)
                .sqrt();
            assert!(c.distance <= brute + 1e-12, "{} > {brute}", c.distance);
            // One of the nearest pair is a vertex or an endpoint, which is sampled exactly; the
            // other is at most half a spacing from a sample, off the gap's direction.
            let sampling = spacing * spacing / (4.0 * c.distance);
            assert!(
                brute - c.distance <= sampling.min(spacing) + 1e-12,
                "{} vs {brute}",
                c.distance
            );
            apart += 1;
        }
        assert!(overlapping > 5, "{overlapping}");
    }

    #[test]
    fn translating_random_polygons_moves_the_nearest_points_smoothly() {
        let mut rng = Lcg(11);
        let (a, b) = ([-0.5, 0.0], [0.5, 0.0]);
        let step = 1e-3;
        let mut runs = 0;
        while runs < 30 {
            let local = random_polygon(&mut rng);
            if check_convex_ccw("p", &local).is_err() {
                continue;
            }
            let shape = Shape::Polygon { vertices: local };
            // A straight path past the segment, at least 0.05 away throughout.
            let angle = rng.range(-4.0, 4.0);
            let start = [rng.range(-2.0, 2.0), rng.range(1.2, 2.0)];
            let heading = rng.range(-0.3, 0.3) - FRAC_PI_2;
            let dir = [heading.cos(), heading.sin()];
            let path: Vec<_> = (0..3000)
                .map(|k| {
                    closest(
                        &shape,
                        &at(
                            start[0] + k as f64 * step * dir[0],
                            start[1] + k as f64 * step * dir[1],
                            angle,
                        ),
                        a,
                        b,
                    )
                })
                .collect();
            if path.iter().any(|c| c.distance < 0.05) {
                continue;
            }
            for (p, c) in path.iter().zip(&path[1..]) {
                consistent(c, a, b);
                assert!(
                    near(c.on_whisker, p.on_whisker, step + 1e-12),
                    "{p:?} -> {c:?}"
                );
                assert_close(c.distance, p.distance, step + 1e-12);
            }
            runs += 1;
        }
    }

    #[test]
    fn degenerate_contacts_stay_finite() {
        let unit = Shape::Box {
            width: 1.0,
            height: 1.0,
        };
        let cases = [
            // Along a face, overlapping it.
            ([-1.0, 0.5], [1.0, 0.5]),
            // From a corner outwards.
            ([0.5, 0.5], [1.5, 1.5]),
            // Through two corners.
            ([-1.0, -1.0], [1.0, 1.0]),
            // Wholly inside.
            ([-0.1, 0.0], [0.1, 0.05]),
            // Ending on a face.
            ([0.0, 2.0], [0.0, 0.5]),
        ];
        for (a, b) in cases {
            let c = closest(&unit, &Pose::default(), a, b);
            consistent(&c, a, b);
            assert!(c.distance <= 0.0 && c.distance.is_finite(), "{c:?}");
        }
        // Along a face: touching, at the start of the overlap.
        let c = closest(&unit, &Pose::default(), [-1.0, 0.5], [1.0, 0.5]);
        assert_close(c.distance, 0.0, 0.0);
        assert_close(c.u, 0.25, 1e-12);
        // Wholly inside: all of it out through the top face, led by its lower end.
        let c = closest(&unit, &Pose::default(), [-0.1, 0.0], [0.1, 0.05]);
        assert_close(c.distance, -0.5, 1e-12);
        assert_eq!(c.u, 0.0);
        assert_near(c.normal, [0.0, 1.0], 1e-12);
    }

    #[test]
    fn bounds_and_containment() {
        let circle = Shape::Circle { radius: 0.5 };
        assert_eq!(bounds(&circle, &at(1.0, 2.0, 0.3)), [0.5, 1.5, 1.5, 2.5]);
        let rect = Shape::Box {
            width: 2.0,
            height: 1.0,
        };
        let r = bounds(&rect, &at(1.0, 1.0, FRAC_PI_2));
        for (x, y) in r.iter().zip([0.5, 0.0, 1.5, 2.0]) {
            assert_close(*x, y, 1e-12);
        }
        let triangle = Shape::Polygon {
            vertices: vec![[0.0, 0.0], [1.0, 0.0], [0.0, 2.0]],
        };
        assert_eq!(
            bounds(&triangle, &at(-1.0, 1.0, 0.0)),
            [-1.0, 1.0, 0.0, 3.0]
        );
        let w = bounds(&Shape::Wall, &at(3.0, 1.0, 0.2));
        assert!(w[0] == f64::NEG_INFINITY && w[3] == f64::INFINITY);
        // Inside, on and outside.
        assert!(contains(&rect, &at(1.0, 1.0, FRAC_PI_2), [1.4, 1.9]));
        assert!(!contains(&rect, &at(1.0, 1.0, FRAC_PI_2), [1.6, 1.0]));
        assert!(contains(&triangle, &Pose::default(), [0.5, 0.0]));
        assert!(contains(&triangle, &Pose::default(), [0.2, 0.2]));
        assert!(!contains(&triangle, &Pose::default(), [0.6, 1.0]));
        assert!(contains(&circle, &at(1.0, 2.0, 0.0), [1.5, 2.0]));
        assert!(!contains(&circle, &at(1.0, 2.0, 0.0), [1.4, 2.4]));
        assert!(contains(&Shape::Wall, &at(0.0, 1.0, 0.0), [5.0, 1.0]));
        assert!(!contains(&Shape::Wall, &at(0.0, 1.0, 0.0), [5.0, 1.1]));
        assert_eq!(triangle.vertices().unwrap().len(), 3);
        assert_eq!(rect.vertices().unwrap()[0], [-1.0, -0.5]);
        assert!(circle.vertices().is_none());
    }
}
