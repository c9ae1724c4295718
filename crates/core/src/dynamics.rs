//! Time stepping of the segment chain.
//!
//! The equations of motion in joint coordinates are
//! `M(q) q̈ + c(q, q̇) = -K (q - q_rest) - D q̇ + τ_ext`, with `K` and `D` diagonal (one spring and
//! one damper per joint). They are integrated by the generalized-α method in the form of Arnold
//! and Brüls for multibody systems: second-order accurate, unconditionally stable for the linear
//! spring–damper part, with high-frequency dissipation set by `rho_inf` (1 = trapezoidal rule,
//! no numerical damping; smaller values damp the chain's unresolved stiff modes while leaving the
//! low modes almost untouched).
//!
//! The stiff, linear spring and damper forces are treated implicitly and exactly. The slowly
//! varying geometric terms (the configuration-dependent mass matrix, velocity-product forces and
//! external forces) are evaluated once per step at the method's own predictor, which keeps second
//! order. The resulting linear system `(M + A) q̈ = τ` with a diagonal `A` is exactly what the
//! articulated-body algorithm solves with joint "armature", so each step is one O(N) recursion and
//! allocates nothing.
//!
//! Spatial vectors are planar and expressed in the world frame about the origin (the whisker
//! base): motion `(ω, vx, vy)`, force `(n, fx, fy)` with `n` the moment about the origin.

use crate::chain::Model;
use crate::error::{check_finite, Error, Result};
use crate::rng::Rng;

/// Largest time step accepted, s.
pub const MAX_DT: f64 = 1.0e-3;

/// Generalized-α settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Integrator {
    /// Time step, s, in (0, [`MAX_DT`]].
    pub dt: f64,
    /// Spectral radius at infinite frequency, in [0, 1]: 1 keeps every mode undamped.
    pub rho_inf: f64,
}

impl Default for Integrator {
    fn default() -> Self {
        Integrator {
            dt: 1.0e-4,
            rho_inf: DEFAULT_RHO_INF,
        }
    }
}

/// Default high-frequency spectral radius (see the module docs).
pub const DEFAULT_RHO_INF: f64 = 0.9;

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
        if !(r.is_finite() && (0.0..=1.0).contains(&r)) {
            return Err(Error::invalid("rho_inf", r, "a number in [0, 1]"));
        }
        let alpha_m = (2.0 * r - 1.0) / (r + 1.0);
        let alpha_f = r / (r + 1.0);
        let gamma = 0.5 + alpha_f - alpha_m;
        let beta = 0.25 * (gamma + 0.5).powi(2);
        let ratio = (1.0 - alpha_f) / (1.0 - alpha_m);
        Ok(Stepper {
            dt: h,
            rho_inf: r,
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
    alpha_m: f64,
    alpha_f: f64,
    gamma: f64,
    beta: f64,
    /// ∂q_{n+1}/∂q̈_{n+1}, s².
    dq: f64,
    /// ∂v_{n+1}/∂q̈_{n+1}, s.
    dv: f64,
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
}

/// One whisker's dynamic state. Cheap to clone; many states share one [`Model`].
#[derive(Debug, Clone, PartialEq)]
pub struct State {
    /// Simulated time, s.
    pub t: f64,
    /// Base rotation at time `t`.
    pub base: BaseMotion,
    /// `[q | q̇ | q̈ | a]`, each `[N]`: joint angles (rad), rates, accelerations and the method's
    /// pseudo-accelerations.
    x: Vec<f64>,
    /// Wrench the base applies to the whisker at time `t`, world frame: (moment N·m, fx N, fy N).
    pub base_wrench: [f64; 3],
    /// The state's own random stream (process noise).
    pub rng: Rng,
}

impl State {
    /// The whisker at rest in its rest shape at t = 0, with a seeded random stream.
    pub fn at_rest(model: &Model, seed: u64) -> State {
        let n = model.n;
        let mut x = vec![0.0; 4 * n];
        x[..n].copy_from_slice(&model.rest);
        State {
            t: 0.0,
            base: BaseMotion::default(),
            x,
            base_wrench: [0.0; 3],
            rng: Rng::new(seed),
        }
    }
    /// Segment count.
    pub fn n(&self) -> usize {
        self.x.len() / 4
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

/// Scratch memory for stepping one state at a time; reuse it across steps and states.
///
/// Per-segment spatial quantities are expressed about the segment's proximal joint (node `i`)
/// with world-parallel axes, so every revolute joint has the motion vector `(1, 0, 0)`.
#[derive(Debug, Clone)]
pub struct Workspace {
    n: usize,
    /// Joint angles and rates at which kinematics was last evaluated, `[N]`.
    q: Vec<f64>,
    v: Vec<f64>,
    /// Node positions, world frame, m: `[N+1][2]`.
    node: Vec<[f64; 2]>,
    /// Segment unit vectors (cos φ, sin φ): `[N][2]`.
    dir: Vec<[f64; 2]>,
    /// Spatial velocity of each segment about its joint (ω, vx, vy of the joint point): `[N][3]`.
    vel: Vec<[f64; 3]>,
    /// Velocity-product (bias) acceleration of each joint: `[N][3]`.
    bias: Vec<[f64; 3]>,
    /// Spatial inertia of each segment about its joint (symmetric, packed): `[N][6]`.
    inertia: Vec<[f64; 6]>,
    /// External spatial force on each segment about its joint: `[N][3]`.
    f_ext: Vec<[f64; 3]>,
    /// Joint torque and armature handed to the solver: `[N]`.
    tau: Vec<f64>,
    arm: Vec<f64>,
    /// Articulated-body quantities: `U = IA·S` `[N][3]`, `1/D` `[N]`, `u` `[N]`.
    u_vec: Vec<[f64; 3]>,
    inv_d: Vec<f64>,
    u: Vec<f64>,
    /// Articulated inertia and bias force of body 0 (for the base reaction).
    ia0: [f64; 6],
    pa0: [f64; 3],
    /// Solved joint accelerations `[N]` and spatial accelerations `[N][3]`.
    qdd: Vec<f64>,
    acc: Vec<[f64; 3]>,
    /// Predicted pseudo-accelerations `[N]`.
    a_pred: Vec<f64>,
}

/// Packs the spatial inertia of a body with mass `m` and central inertia `j` about a reference
/// point from which its centre of mass lies at `(cx, cy)`.
#[inline]
pub(crate) fn body_inertia(m: f64, j: f64, cx: f64, cy: f64) -> [f64; 6] {
    [j + m * (cx * cx + cy * cy), -m * cy, m * cx, m, 0.0, m]
}

/// Symmetric packed 3×3 times a vector.
#[inline]
pub(crate) fn sym_mul(a: &[f64; 6], v: [f64; 3]) -> [f64; 3] {
    [
        a[0] * v[0] + a[1] * v[1] + a[2] * v[2],
        a[1] * v[0] + a[3] * v[1] + a[4] * v[2],
        a[2] * v[0] + a[4] * v[1] + a[5] * v[2],
    ]
}

/// Motion cross force: `m ×* f`.
#[inline]
fn cross_force(m: [f64; 3], f: [f64; 3]) -> [f64; 3] {
    [m[1] * f[2] - m[2] * f[1], -m[0] * f[2], m[0] * f[1]]
}

/// Taylor coefficients of sin(x)/x and cos(x) in powers of x²: (-1)^k/(2k+1)! and (-1)^k/(2k)!.
const SIN_TAYLOR: [f64; 9] = [
    1.0,
    -1.0 / 6.0,
    1.0 / 120.0,
    -1.0 / 5040.0,
    1.0 / 362_880.0,
    -1.0 / 39_916_800.0,
    1.0 / 6_227_020_800.0,
    -1.0 / 1_307_674_368_000.0,
    1.0 / 355_687_428_096_000.0,
];
const COS_TAYLOR: [f64; 10] = [
    1.0,
    -1.0 / 2.0,
    1.0 / 24.0,
    -1.0 / 720.0,
    1.0 / 40_320.0,
    -1.0 / 3_628_800.0,
    1.0 / 479_001_600.0,
    -1.0 / 87_178_291_200.0,
    1.0 / 20_922_789_888_000.0,
    -1.0 / 6_402_373_705_728_000.0,
];

/// `(sin x, cos x)`: Taylor polynomials (truncation below 1e-18) for the small joint angles of a
/// whisker, the library routine beyond 0.8 rad.
#[inline]
fn sin_cos(x: f64) -> (f64, f64) {
    if x.abs() > 0.8 {
        return x.sin_cos();
    }
    let x2 = x * x;
    let s = SIN_TAYLOR.iter().rev().fold(0.0, |acc, &k| acc * x2 + k);
    let c = COS_TAYLOR.iter().rev().fold(0.0, |acc, &k| acc * x2 + k);
    (x * s, c)
}

#[inline]
fn dot3(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Moves a packed spatial inertia's reference point by `d = (dx, dy)` (new point minus old).
#[inline]
fn shift_inertia(i: &[f64; 6], dx: f64, dy: f64) -> [f64; 6] {
    let [a, b, c, d, e, f] = *i;
    let (p, q) = (dy, -dx);
    let t1 = b + d * p + e * q;
    let t2 = c + e * p + f * q;
    let t0 = a + b * p + c * q;
    [t0 + p * t1 + q * t2, t1, t2, d, e, f]
}

/// Moves a spatial force's reference point by `d = (dx, dy)` (new point minus old).
#[inline]
fn shift_force(f: [f64; 3], dx: f64, dy: f64) -> [f64; 3] {
    [f[0] + dy * f[1] - dx * f[2], f[1], f[2]]
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
            dir: vec![[1.0, 0.0]; n],
            vel: vec![[0.0; 3]; n],
            bias: vec![[0.0; 3]; n],
            inertia: vec![[0.0; 6]; n],
            f_ext: vec![[0.0; 3]; n],
            tau: vec![0.0; n],
            arm: vec![0.0; n],
            u_vec: vec![[0.0; 3]; n],
            inv_d: vec![0.0; n],
            u: vec![0.0; n],
            ia0: [0.0; 6],
            pa0: [0.0; 3],
            qdd: vec![0.0; n],
            acc: vec![[0.0; 3]; n],
            a_pred: vec![0.0; n],
        }
    }

    /// Node positions of the last evaluated configuration, world frame, m (`[N+1]`).
    pub fn nodes(&self) -> &[[f64; 2]] {
        &self.node
    }

    /// Segment unit vectors of the last evaluated configuration (`[N]`).
    pub fn directions(&self) -> &[[f64; 2]] {
        &self.dir
    }

    /// World position of the point `along` metres down segment `seg`'s chord.
    pub fn point(&self, seg: usize, along: f64) -> [f64; 2] {
        let (p, d) = (self.node[seg], self.dir[seg]);
        [p[0] + along * d[0], p[1] + along * d[1]]
    }

    /// World velocity of the material point of segment `seg` at world position `p`.
    pub fn point_velocity(&self, seg: usize, p: [f64; 2]) -> [f64; 2] {
        let [w, vx, vy] = self.vel[seg];
        let o = self.node[seg];
        [vx - w * (p[1] - o[1]), vy + w * (p[0] - o[0])]
    }

    /// Adds a world-frame force `f` acting at world point `p` of segment `seg`.
    pub fn add_force(&mut self, seg: usize, p: [f64; 2], f: [f64; 2]) {
        let o = self.node[seg];
        let e = &mut self.f_ext[seg];
        e[0] += (p[0] - o[0]) * f[1] - (p[1] - o[1]) * f[0];
        e[1] += f[0];
        e[2] += f[1];
    }

    /// Stage: forward kinematics at joint angles `self.q`, rates `self.v`, base motion `base`.
    fn kinematics(&mut self, model: &Model, base: &BaseMotion) {
        let n = self.n;
        let (sb, cb) = base.angle.sin_cos();
        let (mut cs, mut sn) = (cb, sb);
        let mut w = base.rate;
        // Velocity of the current joint point.
        let (mut vx, mut vy) = (0.0, 0.0);
        let mut p = [0.0, 0.0];
        let (q, v, len) = (&self.q[..n], &self.v[..n], &model.len[..n]);
        let (mass, inertia, com) = (&model.mass[..n], &model.inertia[..n], &model.com[..n]);
        for i in 0..n {
            // Segment pose: the parent's direction turned by the joint angle.
            let (sq, cq) = sin_cos(q[i]);
            (cs, sn) = (cs * cq - sn * sq, sn * cq + cs * sq);
            self.dir[i] = [cs, sn];
            // Joint rate: spatial velocity about the joint and its velocity-product acceleration.
            let qd = v[i];
            w += qd;
            self.vel[i] = [w, vx, vy];
            self.bias[i] = [0.0, qd * vy, -qd * vx];
            // Spatial inertia about the joint.
            let c = com[i];
            let cx = cs * c[0] - sn * c[1];
            let cy = sn * c[0] + cs * c[1];
            self.inertia[i] = body_inertia(mass[i], inertia[i], cx, cy);
            self.f_ext[i] = [0.0; 3];
            // Next joint point and its velocity.
            let (dx, dy) = (len[i] * cs, len[i] * sn);
            vx -= w * dy;
            vy += w * dx;
            p = [p[0] + dx, p[1] + dy];
            self.node[i + 1] = p;
        }
    }

    /// World position of segment `i`'s centre of mass (after [`Self::kinematics`]).
    fn com(&self, model: &Model, i: usize) -> [f64; 2] {
        let (p, [cs, sn], c) = (self.node[i], self.dir[i], model.com[i]);
        [p[0] + cs * c[0] - sn * c[1], p[1] + sn * c[0] + cs * c[1]]
    }

    /// Stage: external forces from point loads and process noise.
    fn forces(&mut self, model: &Model, inputs: &Inputs, rng: &mut Rng, h: f64) {
        for load in inputs.loads {
            let p = self.point(load.segment, load.along);
            self.add_force(load.segment, p, load.force);
        }
        if inputs.noise > 0.0 {
            let sigma = inputs.noise * (model.arc / h).sqrt();
            for i in 0..self.n {
                let f = [sigma * rng.normal(), sigma * rng.normal()];
                let c = self.com(model, i);
                self.add_force(i, c, f);
            }
        }
    }

    /// Stage: articulated-body solve of `(M + diag(arm)) q̈ = tau - c - (external)`.
    /// Fills `qdd`, `acc` and the articulated quantities of body 0.
    fn solve(&mut self, base: &BaseMotion) {
        let n = self.n;
        // Inward pass: articulated inertias and bias forces, tip to base, each about its joint.
        let mut ia_c = [0.0f64; 6];
        let mut pa_c = [0.0f64; 3];
        for i in (0..n).rev() {
            let vel = self.vel[i];
            let ib = self.inertia[i];
            let cf = cross_force(vel, sym_mul(&ib, vel));
            let fe = self.f_ext[i];
            let mut ia = [0.0; 6];
            for k in 0..6 {
                ia[k] = ib[k] + ia_c[k];
            }
            let pa = [
                cf[0] - fe[0] + pa_c[0],
                cf[1] - fe[1] + pa_c[1],
                cf[2] - fe[2] + pa_c[2],
            ];
            // Joint motion vector (1, 0, 0): U is IA's first column, D its corner plus armature.
            let uv = [ia[0], ia[1], ia[2]];
            let inv_d = 1.0 / (ia[0] + self.arm[i]);
            let u = self.tau[i] - pa[0];
            self.u_vec[i] = uv;
            self.inv_d[i] = inv_d;
            self.u[i] = u;
            if i == 0 {
                self.ia0 = ia;
                self.pa0 = pa;
                break;
            }
            // What this subtree passes to its parent, moved to the parent's joint.
            let ia_a = [
                ia[0] - uv[0] * uv[0] * inv_d,
                ia[1] - uv[0] * uv[1] * inv_d,
                ia[2] - uv[0] * uv[2] * inv_d,
                ia[3] - uv[1] * uv[1] * inv_d,
                ia[4] - uv[1] * uv[2] * inv_d,
                ia[5] - uv[2] * uv[2] * inv_d,
            ];
            let ic = sym_mul(&ia_a, self.bias[i]);
            let k = u * inv_d;
            let pa_a = [
                pa[0] + ic[0] + uv[0] * k,
                pa[1] + ic[1] + uv[1] * k,
                pa[2] + ic[2] + uv[2] * k,
            ];
            let (a, b) = (self.node[i - 1], self.node[i]);
            let (dx, dy) = (a[0] - b[0], a[1] - b[1]);
            ia_c = shift_inertia(&ia_a, dx, dy);
            pa_c = shift_force(pa_a, dx, dy);
        }
        // Outward pass: joint and spatial accelerations, base to tip.
        let mut a = [base.accel, 0.0, 0.0];
        for i in 0..n {
            if i > 0 {
                // Move the parent's acceleration to this joint.
                let (p, o) = (self.node[i - 1], self.node[i]);
                let (dx, dy) = (o[0] - p[0], o[1] - p[1]);
                a = [a[0], a[1] - a[0] * dy, a[2] + a[0] * dx];
            }
            let c = self.bias[i];
            let ap = [a[0] + c[0], a[1] + c[1], a[2] + c[2]];
            let qdd = (self.u[i] - dot3(self.u_vec[i], ap)) * self.inv_d[i];
            a = [ap[0] + qdd, ap[1], ap[2]];
            self.qdd[i] = qdd;
            self.acc[i] = a;
        }
    }

    /// Wrench transmitted from the base to segment 0 after [`Self::solve`], about the base.
    fn base_wrench(&self) -> [f64; 3] {
        let f = sym_mul(&self.ia0, self.acc[0]);
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
    state.base = inputs.base;
    ws.evaluate(model, state);
    ws.forces(model, inputs, &mut state.rng.clone(), MAX_DT);
    for i in 0..n {
        ws.tau[i] = -model.stiffness[i] * (ws.q[i] - model.rest[i]) - model.damping[i] * ws.v[i];
        ws.arm[i] = 0.0;
    }
    ws.solve(&inputs.base);
    state.x[2 * n..3 * n].copy_from_slice(&ws.qdd);
    state.x[3 * n..4 * n].copy_from_slice(&ws.qdd);
    state.base_wrench = ws.base_wrench();
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

/// Advances `state` by one step with `inputs` and extra `forcing`.
pub fn step_with<F: Forcing + ?Sized>(
    model: &Model,
    st: &Stepper,
    state: &mut State,
    inputs: &Inputs,
    ws: &mut Workspace,
    forcing: &mut F,
) -> Result<()> {
    let n = model.n;
    let h = st.dt;
    let t_next = state.t + h;
    let (q, rest) = state.x.split_at_mut(n);
    let (v, rest) = rest.split_at_mut(n);
    let (qdd, acc) = rest.split_at_mut(n);

    // Stage: predict positions and rates with q̈_{n+1} ≈ q̈_n.
    let inv_am = 1.0 / (1.0 - st.alpha_m);
    for i in 0..n {
        let a_pred = (qdd[i] - st.alpha_m * acc[i]) * inv_am;
        ws.a_pred[i] = a_pred;
        ws.q[i] = q[i] + h * v[i] + h * h * ((0.5 - st.beta) * acc[i] + st.beta * a_pred);
        ws.v[i] = v[i] + h * ((1.0 - st.gamma) * acc[i] + st.gamma * a_pred);
    }

    // Stage: kinematics at the prediction, then external forces.
    ws.kinematics(model, &inputs.base);
    ws.forces(model, inputs, &mut state.rng, h);
    forcing.apply(t_next, model, ws);

    // Stage: passive joint torques with the implicit spring–damper correction as armature.
    for i in 0..n {
        let (k, d) = (model.stiffness[i], model.damping[i]);
        let arm = k * st.dq + d * st.dv;
        ws.arm[i] = arm;
        ws.tau[i] = -k * (ws.q[i] - model.rest[i]) - d * ws.v[i] + arm * qdd[i];
    }

    // Stage: solve for the new accelerations.
    ws.solve(&inputs.base);

    // Stage: integrate, correcting the prediction.
    let (af, am) = (st.alpha_f, st.alpha_m);
    for i in 0..n {
        let qdd_new = ws.qdd[i];
        let acc_new = ((1.0 - af) * qdd_new + af * qdd[i] - am * acc[i]) * inv_am;
        let da = acc_new - ws.a_pred[i];
        q[i] = ws.q[i] + h * h * st.beta * da;
        v[i] = ws.v[i] + h * st.gamma * da;
        qdd[i] = qdd_new;
        acc[i] = acc_new;
    }
    state.t = t_next;
    state.base = inputs.base;
    state.base_wrench = ws.base_wrench();
    check_state(state, model)
}

/// Stage boundary check: every value finite, no joint folded past π from rest.
fn check_state(state: &State, model: &Model) -> Result<()> {
    let n = model.n;
    let bad = |i: usize, what: &str, x: f64| Error::Diverged {
        t: state.t,
        detail: format!(
            "joint {i} (arc length {:.4} m) {what} = {x}",
            i as f64 * model.arc
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
                detail: format!("base reaction is {w}"),
            }
        })?;
    }
    Ok(())
}

/// Kinetic energy of a state, J.
pub fn kinetic_energy(model: &Model, state: &State, ws: &mut Workspace) -> f64 {
    ws.evaluate(model, state);
    (0..model.n)
        .map(|i| 0.5 * dot3(ws.vel[i], sym_mul(&ws.inertia[i], ws.vel[i])))
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
        let m = shift_force(sym_mul(&ws.inertia[i], ws.vel[i]), -o[0], -o[1]);
        for k in 0..3 {
            h[k] += m[k];
        }
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn taylor_sin_cos_matches_library() {
        for k in -2000..=2000 {
            let x = k as f64 * 5e-4;
            let (s, c) = sin_cos(x);
            assert!(
                (s - x.sin()).abs() < 3e-16 && (c - x.cos()).abs() < 3e-16,
                "{x}"
            );
        }
    }
}
