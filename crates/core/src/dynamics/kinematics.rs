//! Stage: forward kinematics of the chain at the evaluation point and the external forces
//! (point loads, process noise) on its segments.

use super::inputs::{BaseMotion, Inputs};
use super::state::State;
use super::workspace::Workspace;
use crate::chain::Model;
use crate::planar::{fma, sin_cos};
use crate::rng::Rng;

impl Workspace {
    /// Stage: forward kinematics at joint angles `self.q`, rates `self.v`, base motion `base`.
    pub(crate) fn kinematics(&mut self, model: &Model, base: &BaseMotion) {
        let n = self.n;
        let (sb, cb) = if base.angle == 0.0 {
            (0.0, 1.0)
        } else {
            base.angle.sin_cos()
        };
        let (mut cs, mut sn) = (cb, sb);
        let mut w = base.rate;
        // Velocity and position of the current joint point.
        let (mut vx, mut vy) = (0.0, 0.0);
        let (mut px, mut py) = (0.0, 0.0);
        let (q, v, len) = (&self.q[..n], &self.v[..n], &model.len[..n]);
        let (mass, inertia, com) = (&model.mass[..n], &model.inertia[..n], &model.com[..n]);
        let (seg, node) = (&mut self.seg[..n], &mut self.node[1..=n]);
        for i in 0..n {
            let sg = &mut seg[i];
            // Segment pose: the parent's direction turned by the joint angle.
            let (sq, cq) = sin_cos(q[i]);
            (cs, sn) = (fma(cs, cq, -sn * sq), fma(sn, cq, cs * sq));
            sg.dir = [cs, sn];
            // Joint rate: spatial velocity about the joint and its velocity-product acceleration.
            let qd = v[i];
            w += qd;
            sg.vel = [w, vx, vy];
            sg.bias = [qd * vy, -qd * vx];
            // Spatial inertia about the joint.
            let (m, c) = (mass[i], com[i]);
            let cx = fma(cs, c[0], -sn * c[1]);
            let cy = fma(sn, c[0], cs * c[1]);
            sg.inertia = [fma(m, fma(cx, cx, cy * cy), inertia[i]), -m * cy, m * cx];
            sg.f_ext = [0.0; 3];
            // Next joint point and its velocity.
            let (dx, dy) = (len[i] * cs, len[i] * sn);
            vx = fma(-w, dy, vx);
            vy = fma(w, dx, vy);
            px += dx;
            py += dy;
            node[i] = [px, py];
        }
    }

    /// World position of segment `i`'s centre of mass (after [`Self::kinematics`]).
    fn com(&self, model: &Model, i: usize) -> [f64; 2] {
        let (p, [cs, sn], c) = (self.node[i], self.seg[i].dir, model.com[i]);
        [p[0] + cs * c[0] - sn * c[1], p[1] + sn * c[0] + cs * c[1]]
    }

    /// Draws this step's process-noise forces (once per step, whatever the iterations; within
    /// a step taken in substeps, once for the whole step: see [`Self::noise_held`]).
    pub(super) fn draw_noise(&mut self, model: &Model, noise: f64, rng: &mut Rng, h: f64) {
        if noise > 0.0 && !self.noise_held {
            let sigma = noise * (model.arc / h).sqrt();
            for f in self.noise.iter_mut() {
                *f = [sigma * rng.normal(), sigma * rng.normal()];
            }
        }
    }

    /// Stage: external forces from point loads and the drawn process noise.
    pub(crate) fn forces(&mut self, model: &Model, inputs: &Inputs) {
        for load in inputs.loads {
            let p = self.point(load.segment, load.along);
            self.add_force(load.segment, p, load.force);
        }
        if inputs.noise > 0.0 {
            for i in 0..self.n {
                let c = self.com(model, i);
                let f = self.noise[i];
                self.add_force(i, c, f);
            }
        }
    }

    /// Evaluates kinematics at a state's own configuration (for energies, momenta, sensors).
    pub fn evaluate(&mut self, model: &Model, state: &State) {
        self.q.copy_from_slice(state.q());
        self.v.copy_from_slice(state.v());
        self.kinematics(model, &state.base);
    }
}
