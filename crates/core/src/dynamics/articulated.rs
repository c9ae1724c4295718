//! Stage: the articulated-body solve of `(M + A) q̈ = τ` with a diagonal armature `A`, one O(N)
//! recursion, and the base reaction it implies.

use super::inputs::BaseMotion;
use super::workspace::Workspace;
use crate::chain::Model;
use crate::planar::{fma, shift_force, shift_inertia, sym_mul};

impl Workspace {
    /// Stage: articulated-body solve of `(M + diag(arm)) q̈ = tau - c - (external)`.
    /// Fills `qdd`, the spatial accelerations and the articulated quantities of body 0.
    pub(crate) fn solve(&mut self, model: &Model, base: &BaseMotion) {
        let n = self.n;
        let (seg, node) = (&mut self.seg[..n], &self.node[..=n]);
        let (mass, tau, arm) = (&model.mass[..n], &self.tau[..n], &self.arm[..n]);
        // Inward pass: articulated inertias and bias forces, tip to base, each about its joint.
        let mut ia_c = [0.0f64; 6];
        let mut pa_c = [0.0f64; 3];
        for i in (0..n).rev() {
            let sg = &mut seg[i];
            let m = mass[i];
            let [w, vx, vy] = sg.vel;
            let [a, b, c] = sg.inertia;
            // Gyroscopic bias force v ×* (I v) of the rigid segment.
            let h1 = fma(b, w, m * vx);
            let h2 = fma(c, w, m * vy);
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
                fma(vx, h2, -vy * h1) - fe[0] + pa_c[0],
                -w * h2 - fe[1] + pa_c[1],
                w * h1 - fe[2] + pa_c[2],
            ];
            // Joint motion vector (1, 0, 0): U is IA's first column, D its corner plus armature.
            let uv = [ia[0], ia[1], ia[2]];
            let inv_d = 1.0 / (ia[0] + arm[i]);
            let u = tau[i] - pa[0];
            sg.u_vec = uv;
            sg.inv_d = inv_d;
            sg.u = u;
            if i == 0 {
                self.ia0 = ia;
                self.pa0 = pa;
                break;
            }
            // What this subtree passes to its parent: IA - U Uᵀ/D and pA + Ia·c + U·u/D ...
            let (s0, s1, s2) = (uv[0] * inv_d, uv[1] * inv_d, uv[2] * inv_d);
            let ia_a = [
                fma(-uv[0], s0, ia[0]),
                fma(-uv[0], s1, ia[1]),
                fma(-uv[0], s2, ia[2]),
                fma(-uv[1], s1, ia[3]),
                fma(-uv[1], s2, ia[4]),
                fma(-uv[2], s2, ia[5]),
            ];
            let [c1, c2] = sg.bias;
            let pa_a = [
                fma(ia_a[1], c1, fma(ia_a[2], c2, fma(uv[0], u * inv_d, pa[0]))),
                fma(ia_a[3], c1, fma(ia_a[4], c2, fma(uv[1], u * inv_d, pa[1]))),
                fma(ia_a[4], c1, fma(ia_a[5], c2, fma(uv[2], u * inv_d, pa[2]))),
            ];
            // ... moved to the parent's joint.
            let (pp, pi) = (node[i - 1], node[i]);
            let (dx, dy) = (pp[0] - pi[0], pp[1] - pi[1]);
            ia_c = shift_inertia(&ia_a, dx, dy);
            pa_c = shift_force(pa_a, dx, dy);
        }
        // Outward pass: joint and spatial accelerations, base to tip.
        let mut acc = [base.accel, 0.0, 0.0];
        let qdd = &mut self.qdd[..n];
        for i in 0..n {
            let sg = &mut seg[i];
            if i > 0 {
                // Move the parent's acceleration to this joint.
                let (p, o) = (node[i - 1], node[i]);
                let (dx, dy) = (o[0] - p[0], o[1] - p[1]);
                acc = [acc[0], fma(-acc[0], dy, acc[1]), fma(acc[0], dx, acc[2])];
            }
            let [c1, c2] = sg.bias;
            let ap = [acc[0], acc[1] + c1, acc[2] + c2];
            let uv = sg.u_vec;
            let x = (sg.u - fma(uv[0], ap[0], fma(uv[1], ap[1], uv[2] * ap[2]))) * sg.inv_d;
            acc = [ap[0] + x, ap[1], ap[2]];
            qdd[i] = x;
            sg.acc = acc;
        }
    }

    /// Wrench transmitted from the base to segment 0 after [`Self::solve`], about the base.
    pub(crate) fn base_wrench(&self) -> [f64; 3] {
        let f = sym_mul(&self.ia0, self.seg[0].acc);
        [f[0] + self.pa0[0], f[1] + self.pa0[1], f[2] + self.pa0[2]]
    }
}
