//! The stages of a free step (no objects, no point loads) on [`LANES`] states at once: forward
//! kinematics, process-noise forces and the articulated-body solve, each the single-state stage
//! ([`kinematics`](super::super::kinematics), [`articulated`](super::super::articulated)) written
//! over lanes with the same operations in the same order.

use super::vector::{sin_cos, Wide, LANES};
use crate::chain::Model;

/// A lane group's base motion at the evaluation point.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct LaneBase {
    pub(super) angle: Wide,
    pub(super) rate: Wide,
    pub(super) accel: Wide,
}

/// Per-segment scratch of a lane group (as the single-state step's).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct LaneSeg {
    pub(super) dir: [Wide; 2],
    pub(super) vel: [Wide; 3],
    pub(super) bias: [Wide; 2],
    pub(super) inertia: [Wide; 3],
    pub(super) f_ext: [Wide; 3],
    pub(super) u_vec: [Wide; 3],
    pub(super) inv_d: Wide,
    pub(super) u: Wide,
    pub(super) acc: [Wide; 3],
}

/// Scratch of the stages for a chain of `n` segments.
#[derive(Debug, Clone)]
pub(super) struct LaneScratch {
    /// Joint angles and rates at the evaluation point.
    pub(super) q: Vec<Wide>,
    pub(super) v: Vec<Wide>,
    pub(super) node: Vec<[Wide; 2]>,
    pub(super) seg: Vec<LaneSeg>,
    pub(super) tau: Vec<Wide>,
    /// The armature (per lane: a lane in lasting contact steps with other coefficients).
    pub(super) arm: Vec<Wide>,
    pub(super) qdd: Vec<Wide>,
    pub(super) ia0: [Wide; 6],
    pub(super) pa0: [Wide; 3],
    /// Process-noise forces of the step, world frame.
    pub(super) noise: Vec<[Wide; 2]>,
}

impl LaneScratch {
    pub(super) fn new(n: usize) -> LaneScratch {
        LaneScratch {
            q: vec![Wide::default(); n],
            v: vec![Wide::default(); n],
            node: vec![[Wide::default(); 2]; n + 1],
            seg: vec![LaneSeg::default(); n],
            tau: vec![Wide::default(); n],
            arm: vec![Wide::default(); n],
            qdd: vec![Wide::default(); n],
            ia0: [Wide::default(); 6],
            pa0: [Wide::default(); 3],
            noise: vec![[Wide::default(); 2]; n],
        }
    }

    /// Forward kinematics at `self.q`, `self.v` and base motion `base`.
    #[inline(always)]
    pub(super) fn kinematics(&mut self, model: &Model, base: &LaneBase) {
        let n = model.n;
        let (mut sb, mut cb) = (Wide::default(), Wide::default());
        for l in 0..LANES {
            let angle = base.angle.0[l];
            (sb.0[l], cb.0[l]) = if angle == 0.0 {
                (0.0, 1.0)
            } else {
                angle.sin_cos()
            };
        }
        let (mut cs, mut sn) = (cb, sb);
        let mut w = base.rate;
        let zero = Wide::splat(0.0);
        let (mut vx, mut vy) = (zero, zero);
        let (mut px, mut py) = (zero, zero);
        let (q, v) = (&self.q[..n], &self.v[..n]);
        let (seg, node) = (&mut self.seg[..n], &mut self.node[1..=n]);
        for i in 0..n {
            let sg = &mut seg[i];
            let (sq, cq) = sin_cos(q[i]);
            (cs, sn) = (Wide::fma(cs, cq, -sn * sq), Wide::fma(sn, cq, cs * sq));
            sg.dir = [cs, sn];
            let qd = v[i];
            w += qd;
            sg.vel = [w, vx, vy];
            sg.bias = [qd * vy, -qd * vx];
            let (m, c, len) = (model.mass[i], model.com[i], model.len[i]);
            let (c0, c1) = (Wide::splat(c[0]), Wide::splat(c[1]));
            let cx = Wide::fma(cs, c0, -sn * c1);
            let cy = Wide::fma(sn, c0, cs * c1);
            let ms = Wide::splat(m);
            sg.inertia = [
                Wide::fma(
                    ms,
                    Wide::fma(cx, cx, cy * cy),
                    Wide::splat(model.inertia[i]),
                ),
                Wide::splat(-m) * cy,
                ms * cx,
            ];
            sg.f_ext = [zero; 3];
            let ls = Wide::splat(len);
            let (dx, dy) = (ls * cs, ls * sn);
            vx = Wide::fma(-w, dy, vx);
            vy = Wide::fma(w, dx, vy);
            px += dx;
            py += dy;
            node[i] = [px, py];
        }
    }

    /// Adds the step's process-noise forces at the segments' centres of mass.
    #[inline(always)]
    pub(super) fn noise_forces(&mut self, model: &Model) {
        for i in 0..model.n {
            let (p, [cs, sn], c) = (self.node[i], self.seg[i].dir, model.com[i]);
            let (c0, c1) = (Wide::splat(c[0]), Wide::splat(c[1]));
            let com = [p[0] + cs * c0 - sn * c1, p[1] + sn * c0 + cs * c1];
            let f = self.noise[i];
            let e = &mut self.seg[i].f_ext;
            e[0] += (com[0] - p[0]) * f[1] - (com[1] - p[1]) * f[0];
            e[1] += f[0];
            e[2] += f[1];
        }
    }

    /// Articulated-body solve of `(M + diag(arm)) q̈ = tau - c - (external)`.
    #[inline(always)]
    pub(super) fn solve(&mut self, model: &Model, base: &LaneBase) {
        let n = model.n;
        let (seg, node) = (&mut self.seg[..n], &self.node[..=n]);
        let (tau, arm) = (&self.tau[..n], &self.arm[..n]);
        let zero = Wide::splat(0.0);
        let mut ia_c = [zero; 6];
        let mut pa_c = [zero; 3];
        for i in (0..n).rev() {
            let sg = &mut seg[i];
            let m = Wide::splat(model.mass[i]);
            let [w, vx, vy] = sg.vel;
            let [a, b, c] = sg.inertia;
            let h1 = Wide::fma(b, w, m * vx);
            let h2 = Wide::fma(c, w, m * vy);
            let fe = sg.f_ext;
            let ia = [
                a + ia_c[0],
                b + ia_c[1],
                c + ia_c[2],
                m + ia_c[3],
                ia_c[4],
                m + ia_c[5],
            ];
            let pa = [
                Wide::fma(vx, h2, -vy * h1) - fe[0] + pa_c[0],
                -w * h2 - fe[1] + pa_c[1],
                w * h1 - fe[2] + pa_c[2],
            ];
            let uv = [ia[0], ia[1], ia[2]];
            let inv_d = Wide::splat(1.0) / (ia[0] + arm[i]);
            let u = tau[i] - pa[0];
            sg.u_vec = uv;
            sg.inv_d = inv_d;
            sg.u = u;
            if i == 0 {
                self.ia0 = ia;
                self.pa0 = pa;
                break;
            }
            let (s0, s1, s2) = (uv[0] * inv_d, uv[1] * inv_d, uv[2] * inv_d);
            let ia_a = [
                Wide::fma(-uv[0], s0, ia[0]),
                Wide::fma(-uv[0], s1, ia[1]),
                Wide::fma(-uv[0], s2, ia[2]),
                Wide::fma(-uv[1], s1, ia[3]),
                Wide::fma(-uv[1], s2, ia[4]),
                Wide::fma(-uv[2], s2, ia[5]),
            ];
            let [c1, c2] = sg.bias;
            let ud = u * inv_d;
            let pa_a = [
                Wide::fma(
                    ia_a[1],
                    c1,
                    Wide::fma(ia_a[2], c2, Wide::fma(uv[0], ud, pa[0])),
                ),
                Wide::fma(
                    ia_a[3],
                    c1,
                    Wide::fma(ia_a[4], c2, Wide::fma(uv[1], ud, pa[1])),
                ),
                Wide::fma(
                    ia_a[4],
                    c1,
                    Wide::fma(ia_a[5], c2, Wide::fma(uv[2], ud, pa[2])),
                ),
            ];
            let (pp, pi) = (node[i - 1], node[i]);
            let (dx, dy) = (pp[0] - pi[0], pp[1] - pi[1]);
            ia_c = shift_inertia(&ia_a, dx, dy);
            pa_c = shift_force(pa_a, dx, dy);
        }
        let mut acc = [base.accel, zero, zero];
        let qdd = &mut self.qdd[..n];
        for i in 0..n {
            let sg = &mut seg[i];
            if i > 0 {
                let (p, o) = (node[i - 1], node[i]);
                let (dx, dy) = (o[0] - p[0], o[1] - p[1]);
                acc = [
                    acc[0],
                    Wide::fma(-acc[0], dy, acc[1]),
                    Wide::fma(acc[0], dx, acc[2]),
                ];
            }
            let [c1, c2] = sg.bias;
            let ap = [acc[0], acc[1] + c1, acc[2] + c2];
            let uv = sg.u_vec;
            let x =
                (sg.u - Wide::fma(uv[0], ap[0], Wide::fma(uv[1], ap[1], uv[2] * ap[2]))) * sg.inv_d;
            acc = [ap[0] + x, ap[1], ap[2]];
            qdd[i] = x;
            sg.acc = acc;
        }
    }

    /// Wrench transmitted from the base to segment 0 after [`Self::solve`], about the base.
    #[inline(always)]
    pub(super) fn base_wrench(&self) -> [Wide; 3] {
        let (a, v) = (&self.ia0, self.seg[0].acc);
        let f = [
            a[0] * v[0] + a[1] * v[1] + a[2] * v[2],
            a[1] * v[0] + a[3] * v[1] + a[4] * v[2],
            a[2] * v[0] + a[4] * v[1] + a[5] * v[2],
        ];
        [f[0] + self.pa0[0], f[1] + self.pa0[1], f[2] + self.pa0[2]]
    }
}

/// [`planar::shift_inertia`](crate::planar::shift_inertia) per lane.
#[inline(always)]
fn shift_inertia(i: &[Wide; 6], dx: Wide, dy: Wide) -> [Wide; 6] {
    let [a, b, c, d, e, f] = *i;
    let (p, q) = (dy, -dx);
    let t1 = Wide::fma(d, p, Wide::fma(e, q, b));
    let t2 = Wide::fma(e, p, Wide::fma(f, q, c));
    let t0 = Wide::fma(b, p, Wide::fma(c, q, a));
    [Wide::fma(p, t1, Wide::fma(q, t2, t0)), t1, t2, d, e, f]
}

/// [`planar::shift_force`](crate::planar::shift_force) per lane.
#[inline(always)]
fn shift_force(f: [Wide; 3], dx: Wide, dy: Wide) -> [Wide; 3] {
    [Wide::fma(dy, f[1], Wide::fma(-dx, f[2], f[0])), f[1], f[2]]
}
