//! The contact stage's broad phase: whether any object can touch the whisker within a step.
//!
//! An object can touch the whisker in a step only if its bounding box at the step's start comes
//! within reach of the whisker's bounding box at the evaluation point: the whisker's largest
//! radius plus twice what the object and the whisker can move in a step. The contact stage
//! ([`super::contact`]) applies this test to every object before it looks for candidates; lane
//! groups ([`super::lanes`]) apply it first, lane by lane, so that a lane with no object in reach
//! skips the contact stage with the result it would have had (no candidates).

use crate::chain::Model;
use crate::objects::{bounds, Object};

/// The whisker's bounding box `[x_min, y_min, x_max, y_max]` over the nodes `node(0..=n)`.
pub(crate) fn whisker_bounds(n: usize, node: impl Fn(usize) -> [f64; 2]) -> [f64; 4] {
    let mut wb = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for i in 0..=n {
        let p = node(i);
        wb = [
            wb[0].min(p[0]),
            wb[1].min(p[1]),
            wb[2].max(p[0]),
            wb[3].max(p[1]),
        ];
    }
    wb
}

/// The whisker's largest radius, m.
pub(crate) fn largest_radius(model: &Model) -> f64 {
    model.radius.iter().cloned().fold(0.0, f64::max)
}

/// The fastest any point of the whisker moves, m/s: over its segments moving at `vel(i)`
/// (angular, then linear; at the evaluation point), each segment's linear speed plus its angular
/// speed times the whisker's length.
pub(crate) fn whisker_speed(model: &Model, vel: impl Fn(usize) -> [f64; 3]) -> f64 {
    (0..model.n).fold(0.0f64, |m, i| {
        let v = vel(i);
        m.max((v[1] * v[1] + v[2] * v[2]).sqrt() + v[0].abs() * model.whisker_length())
    })
}

/// How far from the whisker's bounding box an object moving at `velocity` and
/// `angular_velocity` can touch it within a step of `h`, the whisker's fastest point moving at
/// `wmax` and its largest radius `rmax`.
pub(crate) fn reach(
    rmax: f64,
    h: f64,
    velocity: [f64; 2],
    angular_velocity: f64,
    wmax: f64,
) -> f64 {
    let speed = (velocity[0] * velocity[0] + velocity[1] * velocity[1]).sqrt()
        + angular_velocity.abs() * 0.1;
    rmax + 2.0 * h * (speed + wmax) + 1e-6
}

/// Whether a box `ob` lies beyond `reach` of the whisker's bounding box `wb`.
pub(crate) fn beyond(ob: [f64; 4], wb: [f64; 4], reach: f64) -> bool {
    ob[0] > wb[2] + reach || ob[2] < wb[0] - reach || ob[1] > wb[3] + reach || ob[3] < wb[1] - reach
}

/// Whether no object of `objects` can touch the whisker in the step of `h` from `t0`, the
/// whisker's bounding box at the evaluation point `wb` ([`whisker_bounds`]) and its fastest point
/// moving at `wmax` ([`whisker_speed`]): every object is out of the whisker's plane at the end of
/// the step or beyond reach, as the contact stage decides before it looks for candidates.
pub(crate) fn none_in_reach(
    model: &Model,
    objects: &[Object],
    t0: f64,
    h: f64,
    wb: [f64; 4],
    wmax: f64,
) -> bool {
    let rmax = largest_radius(model);
    let t_end = t0 + h;
    objects.iter().all(|obj| {
        if !obj.in_plane(t_end) {
            return true;
        }
        let pose = obj.pose(t0);
        let reach = reach(rmax, h, pose.velocity, pose.angular_velocity, wmax);
        beyond(bounds(&obj.shape, &pose), wb, reach)
    })
}
