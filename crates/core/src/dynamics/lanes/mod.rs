//! Free steps of several states of one model at once, in lanes.
//!
//! A particle filter advances thousands of whisker states of one model with the same inputs.
//! Where no object and no point load acts (a whisker ringing after its object has gone, or
//! moved only by its base and random forces), [`step_group`] takes up to [`LANES`] states
//! together: their angles, rates and accelerations are laid out joint by joint with one value
//! per state (structure of arrays), and every stage of the step (predict, passive torques,
//! kinematics, noise forces, the articulated-body solve, integration) runs on all of them at once.
//! Each lane computes exactly the bits the single-state [`step`](super::step) computes for its
//! state: the same operations in the same order, every state drawing its process noise from its
//! own random stream. A lane whose step diverges is given back to the single-state step, which
//! halves it as usual; a group that holds a state in contact, or inputs with objects or loads, or
//! a chain fitted to the step ([`Integrator::fit_first_mode`](super::Integrator)), is stepped one
//! state at a time.

mod stages;
mod vector;

pub use vector::LANES;

use super::inputs::{check_inputs, BaseMotion, Inputs};
use super::integrator::Stepper;
use super::state::State;
use super::step::step;
use super::workspace::Workspace;
use crate::chain::Model;
use crate::error::Error;
use crate::rng::Rng;
use stages::{LaneBase, LaneScratch};
use std::borrow::BorrowMut;
use vector::Wide;

/// The dynamic state of a lane group, joint by joint (see [`State`] for what each holds).
#[derive(Debug, Clone)]
struct LaneState {
    q: Vec<Wide>,
    v: Vec<Wide>,
    a: Vec<Wide>,
    v_prev: Vec<Wide>,
    t: Wide,
    base: [BaseMotion; LANES],
    wrench_alpha: [Wide; 3],
    base_wrench: [Wide; 3],
    rng: [Rng; LANES],
}

impl LaneState {
    fn new(n: usize) -> LaneState {
        LaneState {
            q: vec![Wide::default(); n],
            v: vec![Wide::default(); n],
            a: vec![Wide::default(); n],
            v_prev: vec![Wide::default(); n],
            t: Wide::default(),
            base: [BaseMotion::default(); LANES],
            wrench_alpha: [Wide::default(); 3],
            base_wrench: [Wide::default(); 3],
            rng: std::array::from_fn(|_| Rng::new(0)),
        }
    }

    /// Lane `l` takes `s`.
    fn gather(&mut self, l: usize, s: &State) {
        let n = self.q.len();
        for i in 0..n {
            self.q[i].0[l] = s.x[i];
            self.v[i].0[l] = s.x[n + i];
            self.a[i].0[l] = s.x[2 * n + i];
            self.v_prev[i].0[l] = s.x[3 * n + i];
        }
        self.t.0[l] = s.t;
        self.base[l] = s.base;
        for k in 0..3 {
            self.wrench_alpha[k].0[l] = s.wrench_alpha[k];
            self.base_wrench[k].0[l] = s.base_wrench[k];
        }
        self.rng[l].clone_from(&s.rng);
    }

    /// Per lane, whether the state passes the single-state step's check (`single::check_state`):
    /// every value finite, no joint folded past π from rest.
    fn sound(&self, model: &Model) -> [bool; LANES] {
        let mut ok = [true; LANES];
        let pi = std::f64::consts::PI;
        for i in 0..self.q.len() {
            let (q, v, a, rest) = (self.q[i].0, self.v[i].0, self.a[i].0, model.rest[i]);
            for (l, ok) in ok.iter_mut().enumerate() {
                // Folded past π (a NaN fails the finite checks first).
                let folded = (q[l] - rest).abs() > pi;
                *ok &= q[l].is_finite() && v[l].is_finite() && a[l].is_finite() && !folded;
            }
        }
        for w in &self.base_wrench {
            for (ok, w) in ok.iter_mut().zip(w.0) {
                *ok &= w.is_finite();
            }
        }
        ok
    }

    /// `s` takes lane `l`, after a free step (no contact, no lasting contact force).
    fn scatter(&self, l: usize, s: &mut State) {
        let n = self.q.len();
        for i in 0..n {
            s.x[i] = self.q[i].0[l];
            s.x[n + i] = self.v[i].0[l];
            s.x[2 * n + i] = self.a[i].0[l];
            s.x[3 * n + i] = self.v_prev[i].0[l];
        }
        s.x[4 * n..5 * n].fill(0.0);
        s.t = self.t.0[l];
        s.base = self.base[l];
        for k in 0..3 {
            s.wrench_alpha[k] = self.wrench_alpha[k].0[l];
            s.base_wrench[k] = self.base_wrench[k].0[l];
        }
        s.contact = None;
        s.touching = 0;
        s.rng.clone_from(&self.rng[l]);
    }
}

/// Scratch memory for stepping lane groups of one segment count; reuse it across calls.
#[derive(Debug, Clone)]
pub struct LaneWorkspace {
    n: usize,
    state: LaneState,
    scratch: LaneScratch,
    /// Where the geometric iterations are at: the latest estimate of the intermediate state per
    /// lane, and the solve's results kept from each lane's last iteration.
    q_lin: Vec<Wide>,
    v_lin: Vec<Wide>,
    qdd: Vec<Wide>,
    wrench: [Wide; 3],
}

impl LaneWorkspace {
    /// Scratch for lane groups of a model of `model.n` segments.
    pub fn new(model: &Model) -> LaneWorkspace {
        let n = model.n;
        LaneWorkspace {
            n,
            state: LaneState::new(n),
            scratch: LaneScratch::new(n),
            q_lin: vec![Wide::default(); n],
            v_lin: vec![Wide::default(); n],
            qdd: vec![Wide::default(); n],
            wrench: [Wide::default(); 3],
        }
    }

    /// Segment count this scratch is for.
    pub fn n(&self) -> usize {
        self.n
    }
}

/// Whether `states` can be stepped together in lanes with `inputs`: nothing but base motion and
/// process noise acts, no state is in contact, and the step is taken whole on `model` itself.
pub fn lanes_apply<S: BorrowMut<State>>(
    model: &Model,
    st: &Stepper,
    states: &[S],
    inputs: &Inputs,
) -> bool {
    inputs.objects.is_empty()
        && inputs.loads.is_empty()
        && !st.fit_first_mode
        && !states.is_empty()
        && states.len() <= LANES
        && states
            .iter()
            .all(|s| s.borrow().n() == model.n && s.borrow().touching == 0)
}

/// Advances each of `states` (one to [`LANES`] of them, of `model`; states or references to them) by `steps` steps of `st` with
/// the same `inputs`, as [`step`] does one at a time, to the same bits. Returns each state's
/// outcome: `None`, or the error of the step at which it diverged (it is then left as it was
/// before that step, as [`step`] leaves it). States that cannot be stepped in lanes (see
/// [`lanes_apply`]) are stepped one at a time with `ws`.
pub fn step_group<S: BorrowMut<State>>(
    model: &Model,
    st: &Stepper,
    states: &mut [S],
    inputs: &Inputs,
    steps: usize,
    lw: &mut LaneWorkspace,
    ws: &mut Workspace,
) -> [Option<Error>; LANES] {
    let mut out: [Option<Error>; LANES] = Default::default();
    if !lanes_apply(model, st, states, inputs) || lw.n != model.n {
        for (s, o) in states.iter_mut().zip(out.iter_mut()) {
            let s = s.borrow_mut();
            for _ in 0..steps {
                if let Err(e) = step(model, st, s, inputs, ws) {
                    *o = Some(e);
                    break;
                }
            }
        }
        return out;
    }
    if let Err(e) = check_inputs(model, inputs) {
        for o in out.iter_mut().take(states.len()) {
            *o = Some(e.clone());
        }
        return out;
    }
    // Lanes beyond the states given step a copy of the first (and are thrown away).
    let count = states.len();
    for l in 0..LANES {
        lw.state.gather(l, states[l.min(count - 1)].borrow());
    }
    let mut live: [bool; LANES] = std::array::from_fn(|l| l < count);
    for _ in 0..steps {
        if !live.iter().any(|x| *x) {
            break;
        }
        step_lanes(model, st, lw, inputs);
        let kept = lw.state.sound(model);
        for l in 0..count {
            if !live[l] || kept[l] {
                continue;
            }
            // A lane that diverged is taken again from the start by the single-state step (to
            // the same bits up to the failed step), which halves the step where it diverges. Its
            // state is still the one given: lanes are written back only at the end.
            live[l] = false;
            let s = states[l].borrow_mut();
            for _ in 0..steps {
                if let Err(e) = step(model, st, s, inputs, ws) {
                    out[l] = Some(e);
                    break;
                }
            }
        }
    }
    for l in 0..count {
        if live[l] {
            lw.state.scatter(l, states[l].borrow_mut());
        }
    }
    out
}

/// One free step of the method on every lane (see `single::step_once`, of which this is the
/// case without objects, loads or lasting contact, written over lanes).
fn step_lanes(model: &Model, st: &Stepper, lw: &mut LaneWorkspace, inputs: &Inputs) {
    let n = model.n;
    let h = st.dt;
    let (am, af, beta, gamma) = (st.alpha_m, st.alpha_f, st.beta, st.gamma);
    let c1 = 1.0 - af;
    let s = &mut lw.state;
    let ws = &mut lw.scratch;
    // Base motion at the intermediate time, per lane.
    let b1 = inputs.base;
    let mut base = LaneBase::default();
    for l in 0..LANES {
        let b0 = s.base[l];
        base.angle.0[l] = b0.angle + c1 * (b1.angle - b0.angle);
        base.rate.0[l] = b0.rate + c1 * (b1.rate - b0.rate);
        base.accel.0[l] = b0.accel + c1 * (b1.accel - b0.accel);
    }
    // Process noise, drawn lane by lane from each state's own stream in the single step's order.
    if inputs.noise > 0.0 {
        let sigma = inputs.noise * (model.arc / h).sqrt();
        for l in 0..LANES {
            let rng = &mut s.rng[l];
            for f in ws.noise.iter_mut() {
                f[0].0[l] = sigma * rng.normal();
                f[1].0[l] = sigma * rng.normal();
            }
        }
    }

    // Predict.
    let (c1h, cq_a, cv_a) = (
        c1 * h,
        c1 * h * h * (0.5 - beta) - st.dq * am,
        c1 * h * (1.0 - gamma) - st.dv * am,
    );
    let (c1h_w, cq_w, cv_w, c1_w) = (
        Wide::splat(c1h),
        Wide::splat(cq_a),
        Wide::splat(cv_a),
        Wide::splat(c1),
    );
    for i in 0..n {
        let (q, v, a, vp) = (s.q[i], s.v[i], s.a[i], s.v_prev[i]);
        lw.q_lin[i] = q + c1h_w * v + cq_w * a;
        lw.v_lin[i] = v + cv_w * a;
        ws.q[i] = q + c1h_w * v;
        ws.v[i] = v + c1_w * (v - vp);
    }
    // Passive joint torques, implicit in the springs and dampers.
    for i in 0..n {
        let (k, d) = (model.stiffness[i], model.damping[i]);
        ws.arm[i] = k * st.dq + d * st.dv;
        ws.tau[i] = Wide::splat(-k) * (lw.q_lin[i] - Wide::splat(model.rest[i]))
            - Wide::splat(d) * lw.v_lin[i];
    }

    // Geometric iterations; a lane whose estimate stops moving keeps the results of its last
    // solve while the others go on.
    let mut active = [true; LANES];
    let mut iterations = 0;
    let (dq_w, dv_w, h_w) = (Wide::splat(st.dq), Wide::splat(st.dv), Wide::splat(h));
    loop {
        iterations += 1;
        ws.kinematics(model, &base);
        if inputs.noise > 0.0 {
            ws.noise_forces(model);
        }
        ws.solve(model, &base);
        let w = ws.base_wrench();
        for i in 0..n {
            lw.qdd[i] = Wide::select(active, ws.qdd[i], lw.qdd[i]);
        }
        for (kept, w) in lw.wrench.iter_mut().zip(w) {
            *kept = Wide::select(active, w, *kept);
        }
        if iterations >= st.max_iterations {
            break;
        }
        let (mut phi, mut moved) = (Wide::splat(0.0), Wide::splat(0.0));
        for i in 0..n {
            let qf = lw.q_lin[i] + dq_w * ws.qdd[i];
            let vf = lw.v_lin[i] + dv_w * ws.qdd[i];
            phi += qf - ws.q[i];
            moved = moved.max(phi.abs()).max(h_w * (vf - ws.v[i]).abs());
            ws.q[i] = Wide::select(active, qf, ws.q[i]);
            ws.v[i] = Wide::select(active, vf, ws.v[i]);
        }
        for (l, a) in active.iter_mut().enumerate() {
            // Still moving (or NaN, as the single step's `moved <= tolerance` reads it).
            let settled = moved.0[l] <= st.tolerance;
            *a = *a && !settled;
        }
        if !active.iter().any(|a| *a) {
            break;
        }
    }

    // Integrate to the end of the step.
    let inv_am = 1.0 / (1.0 - am);
    let (am_w, inv_w) = (Wide::splat(am), Wide::splat(inv_am));
    let (hh_w, b_a, b_n) = (
        Wide::splat(h * h),
        Wide::splat(0.5 - beta),
        Wide::splat(beta),
    );
    let (g_a, g_n) = (Wide::splat(1.0 - gamma), Wide::splat(gamma));
    for i in 0..n {
        let (q, v, a) = (s.q[i], s.v[i], s.a[i]);
        let a_new = (lw.qdd[i] - am_w * a) * inv_w;
        let q_new = q + h_w * v + hh_w * (b_a * a + b_n * a_new);
        let v_new = v + h_w * (g_a * a + g_n * a_new);
        s.v_prev[i] = v;
        s.q[i] = q_new;
        s.v[i] = v_new;
        s.a[i] = a_new;
    }
    // Base reaction, extrapolated from the intermediate time to the end of the step.
    let af_w = Wide::splat(af);
    for k in 0..3 {
        let (wk, prev) = (lw.wrench[k], s.wrench_alpha[k]);
        let extrapolated = wk + af_w * (wk - prev);
        let first = std::array::from_fn(|l| s.t.0[l] == 0.0);
        s.base_wrench[k] = Wide::select(first, wk, extrapolated);
        s.wrench_alpha[k] = wk;
    }
    s.t += h_w;
    s.base = [inputs.base; LANES];
}
