//! Time stepping of the segment chain.
//!
//! The equations of motion in joint coordinates are
//! `M(q) q̈ + c(q, q̇) = -K (q - q_rest) - D q̇ + τ_ext`, with `K` and `D` diagonal (one spring and
//! one damper per joint). They are integrated by the Hilber–Hughes–Taylor (HHT-α) member of the
//! generalized-α family: second-order accurate, unconditionally stable for the linear
//! spring–damper part, with a little high-frequency dissipation set by `rho_inf` (1 = trapezoidal
//! rule). Forces balance at the intermediate time `t_{n+1-αf}`, `αf = (1 - ρ∞)/(1 + ρ∞)`.
//!
//! Why this member: with large rotations and large steps, members that balance forces near the
//! middle of the step (the trapezoidal rule, Chung–Hulbert's αm ≠ 0) let energy grow (×2.6 over
//! 10 s for N = 10 at dt = 1 ms after release from a tip-load shape with W = EI/L²), and
//! stronger high-frequency dissipation overshoots after a kick of the heavily damped stiff modes
//! (see [`DEFAULT_RHO_INF`]); HHT at ρ∞ = 0.99 does neither in those tests.
//!
//! The stiff, linear spring and damper forces are treated implicitly and exactly. The geometric
//! terms (the configuration-dependent mass matrix, velocity-product forces and external forces)
//! are evaluated at the intermediate time from positions and rates predicted without the
//! acceleration terms (which the stiff modes would amplify), and refined by a few fixed-point
//! iterations until the geometry stops moving. Each solve is `(M + A) b = τ` with a diagonal
//! `A`, exactly what the articulated-body algorithm solves with joint "armature", so an iteration
//! is one O(N) recursion and allocates nothing.
//!
//! Spatial vectors are planar and expressed in the world frame about the origin (the whisker
//! base): motion `(ω, vx, vy)`, force `(n, fx, fy)` with `n` the moment about the origin.

use crate::chain::Model;
use crate::contact::{self, ContactReport};
use crate::error::{check_finite, readable, Error, Result};
use crate::objects::Object;
use crate::planar::{dot3, fma, shift_force, shift_inertia, sin_cos, sym_mul};
use crate::rng::Rng;

/// Largest time step accepted, s.
pub const MAX_DT: f64 = 1.0e-3;

/// Generalized-α settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Integrator {
    /// Time step, s, in (0, [`MAX_DT`]].
    pub dt: f64,
    /// Spectral radius at infinite frequency, in [0.5, 1]: 1 keeps every mode undamped.
    pub rho_inf: f64,
    /// Convergence tolerance of the geometric iterations, rad: a step is repeated with updated
    /// geometry until no segment's direction moves by more than this between evaluation point
    /// and result. 0 always uses `max_iterations`.
    pub tolerance: f64,
    /// Most geometric iterations per step (1 = linearly implicit, one solve per step).
    pub max_iterations: usize,
}

impl Default for Integrator {
    fn default() -> Self {
        Integrator {
            dt: 1.0e-4,
            rho_inf: DEFAULT_RHO_INF,
            tolerance: DEFAULT_TOLERANCE,
            max_iterations: DEFAULT_MAX_ITERATIONS,
        }
    }
}

impl Integrator {
    /// Default settings with time step `dt`.
    pub fn with_dt(dt: f64) -> Self {
        Integrator {
            dt,
            ..Default::default()
        }
    }
}

/// Default geometric tolerance, rad.
pub const DEFAULT_TOLERANCE: f64 = 1.0e-5;

/// Default cap on geometric iterations per step.
pub const DEFAULT_MAX_ITERATIONS: usize = 6;

/// Default high-frequency spectral radius. Smaller values damp unresolved stiff modes faster but
/// make the method overshoot when a stiff, heavily damped mode is kicked (a release, an impact):
/// at N = 100 and dt = 1 ms, a release from a large deflection briefly multiplies the energy by
/// 16 at 0.9 and by 2 at 0.95, and not at all at 0.99.
pub const DEFAULT_RHO_INF: f64 = 0.99;

impl Integrator {
    /// Checks the settings and derives the method's coefficients.
    pub fn check(&self) -> Result<Stepper> {
        let h = self.dt;
        if !(h.is_finite() && h > 0.0 && h <= MAX_DT) {
            return Err(Error::invalid(
                "dt",
                h,
                format!("a time step in (0, {MAX_DT}] s"),
            ));
        }
        let r = self.rho_inf;
        if !(r.is_finite() && (0.5..=1.0).contains(&r)) {
            return Err(Error::invalid("rho_inf", r, "a number in [0.5, 1]"));
        }
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0) {
            return Err(Error::invalid(
                "tolerance",
                self.tolerance,
                "a finite number >= 0 (rad)",
            ));
        }
        if !(1..=20).contains(&self.max_iterations) {
            return Err(Error::invalid(
                "max_iterations",
                self.max_iterations,
                "an integer from 1 to 20",
            ));
        }
        // Hilber–Hughes–Taylor parameters in the generalized-α family (αm = 0).
        let alpha_m = 0.0;
        let alpha_f = (1.0 - r) / (1.0 + r);
        let gamma = 0.5 + alpha_f - alpha_m;
        let beta = 0.25 * (gamma + 0.5).powi(2);
        let ratio = (1.0 - alpha_f) / (1.0 - alpha_m);
        Ok(Stepper {
            dt: h,
            rho_inf: r,
            tolerance: self.tolerance,
            max_iterations: self.max_iterations,
            alpha_m,
            alpha_f,
            gamma,
            beta,
            dq: h * h * beta * ratio,
            dv: h * gamma * ratio,
        })
    }
}

/// Checked integrator settings with derived coefficients. Obtain from [`Integrator::check`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stepper {
    /// Time step, s.
    pub dt: f64,
    /// Spectral radius at infinite frequency.
    pub rho_inf: f64,
    /// Geometric tolerance, rad.
    pub tolerance: f64,
    /// Most geometric iterations per step.
    pub max_iterations: usize,
    alpha_m: f64,
    alpha_f: f64,
    gamma: f64,
    beta: f64,
    /// ∂q_{n+1}/∂q̈_{n+1}, s².
    dq: f64,
    /// ∂v_{n+1}/∂q̈_{n+1}, s.
    dv: f64,
}

impl Stepper {
    /// The method's αf: forces balance at `t_{n+1} - αf·dt`.
    pub fn alpha_f(&self) -> f64 {
        self.alpha_f
    }
    pub(crate) fn beta_coef(&self) -> f64 {
        self.beta
    }
    pub(crate) fn gamma_coef(&self) -> f64 {
        self.gamma
    }
    pub(crate) fn alpha_m_coef(&self) -> f64 {
        self.alpha_m
    }
}

/// Prescribed rotation of the base (the follicle's mount) about the origin.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BaseMotion {
    /// Angle, rad.
    pub angle: f64,
    /// Angular rate, rad/s.
    pub rate: f64,
    /// Angular acceleration, rad/s².
    pub accel: f64,
}

/// A force applied at a point of a segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointLoad {
    /// Segment index, 0 at the base.
    pub segment: usize,
    /// Distance along the segment's chord from its proximal node, m.
    pub along: f64,
    /// Force in the world frame, N (a dead load: its direction does not follow the whisker).
    pub force: [f64; 2],
}

/// What drives one step besides the state itself.
#[derive(Debug, Clone, Copy, Default)]
pub struct Inputs<'a> {
    /// Base rotation at the end of the step.
    pub base: BaseMotion,
    /// Point loads held over the step.
    pub loads: &'a [PointLoad],
    /// White-noise process force intensity per unit length, N·s^½·m^-½: over a step `h` each
    /// segment of arc length `l` receives an independent Gaussian force with standard deviation
    /// `intensity·sqrt(l/h)` in x and in y at its centre of mass (so the forcing does not depend
    /// on N or h). Zero disables it.
    pub noise: f64,
    /// Rigid objects the whisker may touch (kinematic: their motion is prescribed).
    pub objects: &'a [Object],
}

/// Checks that every load names an existing segment and a point on it, with a finite force.
pub fn check_loads(model: &Model, loads: &[PointLoad]) -> Result<()> {
    for (k, l) in loads.iter().enumerate() {
        if l.segment >= model.n {
            return Err(Error::invalid(
                format!("loads[{k}].segment"),
                l.segment,
                format!("a segment index from 0 to {}", model.n - 1),
            ));
        }
        let len = model.len[l.segment];
        if !(l.along.is_finite() && (0.0..=len * (1.0 + 1e-12)).contains(&l.along)) {
            return Err(Error::invalid(
                format!("loads[{k}].along"),
                l.along,
                format!("in [0, {len}] m"),
            ));
        }
        if !(l.force[0].is_finite() && l.force[1].is_finite()) {
            return Err(Error::invalid(
                format!("loads[{k}].force"),
                format!("{:?}", l.force),
                "finite components",
            ));
        }
    }
    Ok(())
}

/// One whisker's dynamic state. Cheap to clone (`clone_from` reuses the buffer); many states
/// share one [`Model`].
#[derive(Debug, PartialEq)]
pub struct State {
    /// Simulated time, s.
    pub t: f64,
    /// Base rotation at time `t`.
    pub base: BaseMotion,
    /// `[q | q̇ | q̈ | q̇_prev | q̈_contact]`, each `[N]`: joint angles (rad), rates (rad/s),
    /// accelerations (rad/s², without contact impulses), the rates one step earlier, and the part
    /// of the accelerations due to lasting contact forces.
    x: Vec<f64>,
    /// Base wrench at the previous step's intermediate time (for extrapolation to `t`).
    wrench_alpha: [f64; 3],
    /// Wrench the base applies to the whisker at time `t`, world frame: (moment N·m, fx N, fy N).
    pub base_wrench: [f64; 3],
    /// Contact during the last step, if any (the contact nearest the base).
    pub contact: Option<ContactReport>,
    /// Objects that carried contact force in the last step (bit k for object k).
    touching: u64,
    /// The state's own random stream (process noise).
    pub rng: Rng,
}

impl Clone for State {
    fn clone(&self) -> Self {
        State {
            t: self.t,
            base: self.base,
            x: self.x.clone(),
            wrench_alpha: self.wrench_alpha,
            base_wrench: self.base_wrench,
            contact: self.contact,
            touching: self.touching,
            rng: self.rng.clone(),
        }
    }

    /// Copies `source` into `self` without allocating when the segment counts agree.
    fn clone_from(&mut self, source: &Self) {
        self.t = source.t;
        self.base = source.base;
        self.x.clone_from(&source.x);
        self.wrench_alpha = source.wrench_alpha;
        self.base_wrench = source.base_wrench;
        self.contact = source.contact;
        self.touching = source.touching;
        self.rng.clone_from(&source.rng);
    }
}

impl State {
    /// The whisker at rest in its rest shape at t = 0, with a seeded random stream.
    pub fn at_rest(model: &Model, seed: u64) -> State {
        let n = model.n;
        let mut x = vec![0.0; 5 * n];
        x[..n].copy_from_slice(&model.rest);
        State {
            t: 0.0,
            base: BaseMotion::default(),
            x,
            wrench_alpha: [0.0; 3],
            base_wrench: [0.0; 3],
            contact: None,
            touching: 0,
            rng: Rng::new(seed),
        }
    }
    /// Base wrench at the last step's intermediate time `t - αf·dt` (see [`Stepper::alpha_f`]),
    /// where the method balances forces; [`State::base_wrench`] is extrapolated from it to `t`.
    pub fn base_wrench_intermediate(&self) -> [f64; 3] {
        self.wrench_alpha
    }
    /// Segment count.
    pub fn n(&self) -> usize {
        self.x.len() / 5
    }
    /// Joint angles, rad.
    pub fn q(&self) -> &[f64] {
        &self.x[..self.n()]
    }
    /// Joint angles, mutable (call [`initialize`] afterwards to make accelerations consistent).
    pub fn q_mut(&mut self) -> &mut [f64] {
        let n = self.n();
        &mut self.x[..n]
    }
    /// Joint rates, rad/s.
    pub fn v(&self) -> &[f64] {
        let n = self.n();
        &self.x[n..2 * n]
    }
    /// Joint rates, mutable.
    pub fn v_mut(&mut self) -> &mut [f64] {
        let n = self.n();
        &mut self.x[n..2 * n]
    }
    /// Joint accelerations, rad/s².
    pub fn qdd(&self) -> &[f64] {
        let n = self.n();
        &self.x[2 * n..3 * n]
    }
}

/// Per-segment scratch, kept together for locality.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Seg {
    /// Unit vector along the chord (cos φ, sin φ).
    pub(crate) dir: [f64; 2],
    /// Spatial velocity about the joint: (ω, vx, vy of the joint point).
    pub(crate) vel: [f64; 3],
    /// Velocity-product acceleration of the joint (its first component is always 0).
    pub(crate) bias: [f64; 2],
    /// First row of the spatial inertia about the joint: (J + m|c|², -m·cy, m·cx); the rest is
    /// (m, 0, m).
    pub(crate) inertia: [f64; 3],
    /// External spatial force about the joint.
    pub(crate) f_ext: [f64; 3],
    /// Articulated-body quantities: `U = IA·S`, `1/D`, `u`.
    pub(crate) u_vec: [f64; 3],
    pub(crate) inv_d: f64,
    pub(crate) u: f64,
    /// Spatial acceleration about the joint.
    pub(crate) acc: [f64; 3],
}

/// Scratch memory for stepping one state at a time; reuse it across steps and states.
///
/// Per-segment spatial quantities are expressed about the segment's proximal joint (node `i`)
/// with world-parallel axes, so every revolute joint has the motion vector `(1, 0, 0)`.
#[derive(Debug, Clone)]
pub struct Workspace {
    pub(crate) n: usize,
    /// Joint angles and rates at which kinematics was last evaluated, `[N]`.
    pub(crate) q: Vec<f64>,
    pub(crate) v: Vec<f64>,
    /// Node positions, world frame, m: `[N+1][2]`.
    pub(crate) node: Vec<[f64; 2]>,
    /// Per-segment scratch `[N]`.
    pub(crate) seg: Vec<Seg>,
    /// Joint torque and armature handed to the solver: `[N]`.
    pub(crate) tau: Vec<f64>,
    pub(crate) arm: Vec<f64>,
    /// Articulated inertia and bias force of body 0 (for the base reaction).
    pub(crate) ia0: [f64; 6],
    pub(crate) pa0: [f64; 3],
    /// Solved joint accelerations `[N]`.
    pub(crate) qdd: Vec<f64>,
    /// Intermediate angles and rates at b = 0 (the linearisation point of the springs) `[N]`.
    pub(crate) q_lin: Vec<f64>,
    pub(crate) v_lin: Vec<f64>,
    /// Process-noise forces drawn for the current step, world frame, N: `[N][2]`.
    pub(crate) noise: Vec<[f64; 2]>,
    /// Contact scratch.
    pub(crate) contacts: contact::Scratch,
    /// Geometric iterations used by the last step.
    pub iterations: usize,
    /// The state at the start of the step being taken (restored if the step fails).
    backup: Option<State>,
}

impl Workspace {
    /// Scratch for a model of `model.n` segments.
    pub fn new(model: &Model) -> Workspace {
        let n = model.n;
        Workspace {
            n,
            q: vec![0.0; n],
            v: vec![0.0; n],
            node: vec![[0.0; 2]; n + 1],
            seg: vec![Seg::default(); n],
            tau: vec![0.0; n],
            arm: vec![0.0; n],
            ia0: [0.0; 6],
            pa0: [0.0; 3],
            qdd: vec![0.0; n],
            q_lin: vec![0.0; n],
            v_lin: vec![0.0; n],
            noise: vec![[0.0; 2]; n],
            contacts: contact::Scratch::new(n),
            iterations: 0,
            backup: None,
        }
    }

    /// Node positions of the last evaluated configuration, world frame, m (`[N+1]`).
    pub fn nodes(&self) -> &[[f64; 2]] {
        &self.node
    }

    /// Unit vector along segment `seg`'s chord in the last evaluated configuration.
    pub fn direction(&self, seg: usize) -> [f64; 2] {
        self.seg[seg].dir
    }

    /// World position of the point `along` metres down segment `seg`'s chord.
    pub fn point(&self, seg: usize, along: f64) -> [f64; 2] {
        let (p, d) = (self.node[seg], self.seg[seg].dir);
        [p[0] + along * d[0], p[1] + along * d[1]]
    }

    /// World velocity of the material point of segment `seg` at world position `p`.
    pub fn point_velocity(&self, seg: usize, p: [f64; 2]) -> [f64; 2] {
        let [w, vx, vy] = self.seg[seg].vel;
        let o = self.node[seg];
        [vx - w * (p[1] - o[1]), vy + w * (p[0] - o[0])]
    }

    /// Adds a world-frame force `f` acting at world point `p` of segment `seg`.
    pub fn add_force(&mut self, seg: usize, p: [f64; 2], f: [f64; 2]) {
        let o = self.node[seg];
        let e = &mut self.seg[seg].f_ext;
        e[0] += (p[0] - o[0]) * f[1] - (p[1] - o[1]) * f[0];
        e[1] += f[0];
        e[2] += f[1];
    }

    /// Spatial inertia of segment `i` about its joint, packed (after kinematics).
    fn inertia(&self, model: &Model, i: usize) -> [f64; 6] {
        let [a, b, c] = self.seg[i].inertia;
        let m = model.mass[i];
        [a, b, c, m, 0.0, m]
    }

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

    /// Draws this step's process-noise forces (once per step, whatever the iterations).
    fn draw_noise(&mut self, model: &Model, noise: f64, rng: &mut Rng, h: f64) {
        if noise > 0.0 {
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

    /// Evaluates kinematics at a state's own configuration (for energies, momenta, sensors).
    pub fn evaluate(&mut self, model: &Model, state: &State) {
        self.q.copy_from_slice(state.q());
        self.v.copy_from_slice(state.v());
        self.kinematics(model, &state.base);
    }
}

/// Something that adds external forces once the step's kinematics is known (contact, fields).
pub trait Forcing {
    /// Adds forces for the configuration in `ws` at time `t` with [`Workspace::add_force`].
    fn apply(&mut self, t: f64, model: &Model, ws: &mut Workspace);
}

/// No extra forces.
pub struct NoForcing;

impl Forcing for NoForcing {
    fn apply(&mut self, _t: f64, _model: &Model, _ws: &mut Workspace) {}
}

/// Makes `state`'s accelerations consistent with its positions, rates and `inputs` (forward
/// dynamics with no integrator terms). Call after setting a state by hand.
pub fn initialize(
    model: &Model,
    state: &mut State,
    inputs: &Inputs,
    ws: &mut Workspace,
) -> Result<()> {
    let n = model.n;
    check_inputs(model, inputs)?;
    state.base = inputs.base;
    ws.evaluate(model, state);
    ws.draw_noise(model, inputs.noise, &mut state.rng.clone(), MAX_DT);
    ws.forces(model, inputs);
    for i in 0..n {
        ws.tau[i] = -model.stiffness[i] * (ws.q[i] - model.rest[i]) - model.damping[i] * ws.v[i];
        ws.arm[i] = 0.0;
    }
    ws.solve(model, &inputs.base);
    state.x[2 * n..3 * n].copy_from_slice(&ws.qdd);
    state.x.copy_within(n..2 * n, 3 * n);
    state.base_wrench = ws.base_wrench();
    state.wrench_alpha = state.base_wrench;
    check_state(state, model)
}

/// Advances `state` by one step with `inputs`.
pub fn step(
    model: &Model,
    st: &Stepper,
    state: &mut State,
    inputs: &Inputs,
    ws: &mut Workspace,
) -> Result<()> {
    step_with(model, st, state, inputs, ws, &mut NoForcing)
}

/// How many times a step that diverged is halved before its error is returned: a step of `dt`
/// is retried as two steps of `dt/2`, either of which may be halved again, down to `dt/16`.
pub const MAX_HALVINGS: u32 = 4;

/// Advances `state` by one step with `inputs` and extra `forcing`.
///
/// A step whose result is not finite or folds a joint past π from its rest angle is not kept:
/// the state is restored and the step taken again as two half steps (the base motion
/// interpolated to the middle), each halved again if it fails, up to [`MAX_HALVINGS`] times. Only
/// when that fails too does the step return [`Error::Diverged`], and the state is then left as
/// it was before the step.
pub fn step_with<F: Forcing + ?Sized>(
    model: &Model,
    st: &Stepper,
    state: &mut State,
    inputs: &Inputs,
    ws: &mut Workspace,
    forcing: &mut F,
) -> Result<()> {
    let mut backup = ws.backup.take().unwrap_or_else(|| state.clone());
    backup.clone_from(state);
    let result = match step_once(model, st, state, inputs, ws, forcing) {
        Err(first @ Error::Diverged { .. }) => {
            state.clone_from(&backup);
            let t_end = state.t + st.dt;
            match halves(model, st, state, inputs, ws, forcing, 1) {
                Ok(()) => {
                    state.t = t_end;
                    Ok(())
                }
                Err(_) => {
                    state.clone_from(&backup);
                    Err(first)
                }
            }
        }
        Err(e) => {
            state.clone_from(&backup);
            Err(e)
        }
        ok => ok,
    };
    ws.backup = Some(backup);
    result
}

/// Takes the step of `st` as two half steps, halving a half that diverges again while `level`
/// allows (see [`step_with`]). On error the state is wherever the failed half left it.
fn halves<F: Forcing + ?Sized>(
    model: &Model,
    st: &Stepper,
    state: &mut State,
    inputs: &Inputs,
    ws: &mut Workspace,
    forcing: &mut F,
    level: u32,
) -> Result<()> {
    let half = Integrator {
        dt: 0.5 * st.dt,
        rho_inf: st.rho_inf,
        tolerance: st.tolerance,
        max_iterations: st.max_iterations,
    }
    .check()?;
    let (b0, b1) = (state.base, inputs.base);
    let middle = BaseMotion {
        angle: 0.5 * (b0.angle + b1.angle),
        rate: 0.5 * (b0.rate + b1.rate),
        accel: 0.5 * (b0.accel + b1.accel),
    };
    for base in [middle, b1] {
        let part = Inputs { base, ..*inputs };
        let start = state.clone();
        match step_once(model, &half, state, &part, ws, forcing) {
            Ok(()) => {}
            Err(Error::Diverged { .. }) if level < MAX_HALVINGS => {
                state.clone_from(&start);
                halves(model, &half, state, &part, ws, forcing, level + 1)?;
            }
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

/// One step of `st`, without retries (see [`step_with`]).
fn step_once<F: Forcing + ?Sized>(
    model: &Model,
    st: &Stepper,
    state: &mut State,
    inputs: &Inputs,
    ws: &mut Workspace,
    forcing: &mut F,
) -> Result<()> {
    let n = model.n;
    check_inputs(model, inputs)?;
    let h = st.dt;
    let t_next = state.t + h;
    let (am, af, beta, gamma) = (st.alpha_m, st.alpha_f, st.beta, st.gamma);
    let c1 = 1.0 - af;
    let t_mid = state.t + c1 * h;
    // Base motion at the intermediate time, interpolated between the step's ends.
    let (b0, b1) = (state.base, inputs.base);
    let base = BaseMotion {
        angle: b0.angle + c1 * (b1.angle - b0.angle),
        rate: b0.rate + c1 * (b1.rate - b0.rate),
        accel: b0.accel + c1 * (b1.accel - b0.accel),
    };
    let (q, rest) = state.x.split_at_mut(n);
    let (v, rest) = rest.split_at_mut(n);
    let (a, rest) = rest.split_at_mut(n);
    let (v_prev, a_contact) = rest.split_at_mut(n);
    ws.draw_noise(model, inputs.noise, &mut state.rng, h);
    if inputs.objects.is_empty() {
        ws.contacts.clear();
    }
    let touching = state.touching;

    for attempt in 0..2 {
        // Stage: predict. The intermediate angles and rates are affine in the unknown
        // b = a_{n+1-αm}: q_f = q0 + dq·b, v_f = v0 + dv·b. The geometry is first evaluated at
        // q_n + (1-αf)·h·q̇_n and at rates extrapolated from the last two steps: both bounded for the
        // stiff modes, and second-order accurate.
        for i in 0..n {
            ws.q_lin[i] = q[i] + c1 * h * v[i] + (c1 * h * h * (0.5 - beta) - st.dq * am) * a[i];
            ws.v_lin[i] = v[i] + (c1 * h * (1.0 - gamma) - st.dv * am) * a[i];
            ws.q[i] = q[i] + c1 * h * v[i];
            ws.v[i] = v[i] + c1 * (v[i] - v_prev[i]);
        }

        // Stage: passive joint torques, implicit in the springs and dampers: with the armature
        // A = K·dq + D·dv, (M + A) b = τ enforces the spring–damper law at the intermediate time.
        for i in 0..n {
            let (k, d) = (model.stiffness[i], model.damping[i]);
            ws.arm[i] = k * st.dq + d * st.dv;
            ws.tau[i] = -k * (ws.q_lin[i] - model.rest[i]) - d * ws.v_lin[i];
        }

        // Geometric iterations: kinematics, forces and solve at the latest estimate of the
        // intermediate state, until that estimate stops moving.
        ws.iterations = 0;
        loop {
            ws.iterations += 1;
            // Stage: kinematics at the evaluation point, then external forces.
            ws.kinematics(model, &base);
            ws.forces(model, inputs);
            forcing.apply(t_mid, model, ws);
            // Stage: solve for b.
            ws.solve(model, &base);
            // Stage: contact forces that keep the whisker out of the objects at the end of the step.
            if !inputs.objects.is_empty() {
                let start = contact::StepStart { q, v, a, touching };
                contact::solve(model, st, ws, inputs, &start, state.t)?;
            }
            if ws.iterations >= st.max_iterations {
                break;
            }
            // Stage: the intermediate state this solve implies; how far the segments moved. Contact
            // impulses (`ac`) and the penetration correction (`fix`) move with their own weights,
            // everything else with the method's.
            let (mut phi, mut moved) = (0.0f64, 0.0f64);
            let contacts = ws.contacts.count > 0;
            let (q_lin, v_lin, qdd) = (&ws.q_lin[..n], &ws.v_lin[..n], &ws.qdd[..n]);
            let (acc, fixes) = (&ws.contacts.acc[..n], &ws.contacts.position_fix[..n]);
            let (qe, ve) = (&mut ws.q[..n], &mut ws.v[..n]);
            for i in 0..n {
                let (mut qf, mut vf) = (q_lin[i] + st.dq * qdd[i], v_lin[i] + st.dv * qdd[i]);
                if contacts {
                    let (ac, fix) = (acc[i], fixes[i]);
                    qf += c1 * (0.5 * h * h * ac + fix) - st.dq * ac;
                    vf += (c1 * h - st.dv) * ac;
                }
                phi += qf - qe[i];
                moved = moved.max(phi.abs()).max(h * (vf - ve[i]).abs());
                qe[i] = qf;
                ve[i] = vf;
            }
            if moved <= st.tolerance {
                break;
            }
        }

        // A lasting contact that ended: take the step again without its force in the history,
        // so the whisker is not pushed by a force that no longer acts.
        let released = touching & !ws.contacts.touching() != 0;
        if attempt == 0 && released && a_contact.iter().any(|x| *x != 0.0) {
            for (ai, ci) in a.iter_mut().zip(a_contact.iter_mut()) {
                *ai -= *ci;
                *ci = 0.0;
            }
            continue;
        }
        break;
    }

    // Stage: integrate to the end of the step. Contact impulses (`ac`) move the rates by h·ac and
    // the angles by h²/2·ac and stay out of the acceleration history; `fix` removes penetration
    // (see the contact module).
    let inv_am = 1.0 / (1.0 - am);
    let contacts = ws.contacts.count > 0;
    let (qdd, acc, fixes) = (
        &ws.qdd[..n],
        &ws.contacts.acc[..n],
        &ws.contacts.position_fix[..n],
    );
    let (q, v, a, v_prev) = (&mut q[..n], &mut v[..n], &mut a[..n], &mut v_prev[..n]);
    a_contact.copy_from_slice(&ws.contacts.acc_lasting[..n]);
    for i in 0..n {
        let a_new = (qdd[i] - am * a[i]) * inv_am;
        let mut q_new = q[i] + h * v[i] + h * h * ((0.5 - beta) * a[i] + beta * a_new);
        let mut v_new = v[i] + h * ((1.0 - gamma) * a[i] + gamma * a_new);
        let mut a_kept = a_new;
        if contacts {
            // The impulses' part of the acceleration, with its own weights and out of the history.
            let (ac, fix) = (acc[i] * inv_am, fixes[i]);
            a_kept -= ac;
            q_new += h * h * (0.5 - beta) * ac + fix;
            v_new += h * (1.0 - gamma) * ac;
        }
        v_prev[i] = v[i];
        q[i] = q_new;
        v[i] = v_new;
        a[i] = a_kept;
    }
    // Base reaction: solved at the intermediate time, extrapolated to the end of the step.
    let w = ws.base_wrench();
    let first = state.t == 0.0;
    for ((out, wk), prev) in state.base_wrench.iter_mut().zip(w).zip(state.wrench_alpha) {
        *out = if first { wk } else { wk + af * (wk - prev) };
    }
    state.wrench_alpha = w;
    state.contact = ws.contacts.report(model, inputs.objects.is_empty());
    state.touching = if inputs.objects.is_empty() {
        0
    } else {
        ws.contacts.touching()
    };
    state.t = t_next;
    state.base = inputs.base;
    check_state(state, model)
}

/// Checks a step's inputs: finite base motion and noise, loads on existing segments.
fn check_inputs(model: &Model, inputs: &Inputs) -> Result<()> {
    let b = inputs.base;
    if !(b.angle.is_finite() && b.rate.is_finite() && b.accel.is_finite()) {
        return Err(Error::invalid(
            "base motion",
            format!("{b:?}"),
            "finite angle, rate and acceleration",
        ));
    }
    if !(inputs.noise.is_finite() && inputs.noise >= 0.0) {
        return Err(Error::invalid(
            "noise",
            inputs.noise,
            "a finite intensity >= 0",
        ));
    }
    if !inputs.loads.is_empty() {
        check_loads(model, inputs.loads)?;
    }
    Ok(())
}

/// Stage boundary check: every value finite, no joint folded past π from rest.
fn check_state(state: &State, model: &Model) -> Result<()> {
    let n = model.n;
    let bad = |i: usize, what: &str, x: f64| Error::Diverged {
        t: state.t,
        detail: format!(
            "joint {i} (arc length {:.4} m) {what} = {}",
            i as f64 * model.arc,
            readable(x)
        ),
    };
    for i in 0..n {
        let (q, v, a) = (state.x[i], state.x[n + i], state.x[2 * n + i]);
        if !(q.is_finite() && v.is_finite() && a.is_finite()) {
            let (what, x) = if !q.is_finite() {
                ("angle", q)
            } else if !v.is_finite() {
                ("rate", v)
            } else {
                ("acceleration", a)
            };
            return Err(bad(i, what, x));
        }
        if (q - model.rest[i]).abs() > std::f64::consts::PI {
            return Err(bad(i, "bent beyond pi from rest: angle", q));
        }
    }
    for (k, w) in state.base_wrench.iter().enumerate() {
        check_finite(["base moment", "base fx", "base fy"][k], *w).map_err(|_| {
            Error::Diverged {
                t: state.t,
                detail: format!("base reaction is {}", readable(*w)),
            }
        })?;
    }
    Ok(())
}

/// Kinetic energy of a state, J.
pub fn kinetic_energy(model: &Model, state: &State, ws: &mut Workspace) -> f64 {
    ws.evaluate(model, state);
    (0..model.n)
        .map(|i| {
            let v = ws.seg[i].vel;
            0.5 * dot3(v, sym_mul(&ws.inertia(model, i), v))
        })
        .sum()
}

/// Elastic energy stored in the joint springs, J.
pub fn potential_energy(model: &Model, state: &State) -> f64 {
    (0..model.n)
        .map(|i| 0.5 * model.stiffness[i] * (state.q()[i] - model.rest[i]).powi(2))
        .sum()
}

/// Spatial momentum of the whole chain about the origin: (angular N·m·s, px, py N·s).
pub fn momentum(model: &Model, state: &State, ws: &mut Workspace) -> [f64; 3] {
    ws.evaluate(model, state);
    let mut h = [0.0; 3];
    for i in 0..model.n {
        // Momentum about the joint, moved to the origin.
        let o = ws.node[i];
        let m = shift_force(sym_mul(&ws.inertia(model, i), ws.seg[i].vel), -o[0], -o[1]);
        for k in 0..3 {
            h[k] += m[k];
        }
    }
    h
}
