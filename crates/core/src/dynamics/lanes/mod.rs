//! Steps of several states of one model at once, in lanes.
//!
//! A particle filter advances thousands of whisker states of one model, each against its own
//! object. [`step_group`] (every state with the same inputs) and [`step_group_each`] (every state
//! with its own objects) take up to [`LANES`] states together: their angles, rates and
//! accelerations are laid out joint by joint with one value per state (structure of arrays), and
//! the stages of the step that every state shares (predict, passive torques, kinematics, noise
//! forces, the articulated-body solve, integration) run on all of them at once. Contact differs
//! from state to state (its candidates, its forces), so each lane whose state has objects has its
//! contact solved on its own, by the single-state contact stage, between the solve and the
//! integration.
//!
//! Each lane computes exactly the bits the single-state [`step`](super::step) computes for its
//! state: the same operations in the same order, every state drawing its process noise from its
//! own random stream. A lasting contact that ends is taken again in lanes without its force, as
//! the single-state step does; a lane whose step diverges (which the single-state step halves) or
//! whose contact stage fails is given back to the single-state step, from the state it started
//! the call with. Point loads, substeps near contact and the chain fitted to the step are not
//! taken in lanes: such groups are stepped one state at a time.

mod stages;
mod vector;

pub use vector::LANES;

use super::contact::{self, StepStart};
use super::inputs::{check_inputs, BaseMotion, Inputs};
use super::integrator::Stepper;
use super::state::{ContactReport, State};
use super::step::step;
use super::workspace::Workspace;
use crate::chain::Model;
use crate::error::{Error, Result};
use crate::objects::Object;
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
    a_contact: Vec<Wide>,
    t: Wide,
    base: [BaseMotion; LANES],
    wrench_alpha: [Wide; 3],
    base_wrench: [Wide; 3],
    contact: [Option<ContactReport>; LANES],
    touching: [u64; LANES],
    held: [u128; LANES],
    rng: [Rng; LANES],
}

impl LaneState {
    fn new(n: usize) -> LaneState {
        LaneState {
            q: vec![Wide::default(); n],
            v: vec![Wide::default(); n],
            a: vec![Wide::default(); n],
            v_prev: vec![Wide::default(); n],
            a_contact: vec![Wide::default(); n],
            t: Wide::default(),
            base: [BaseMotion::default(); LANES],
            wrench_alpha: [Wide::default(); 3],
            base_wrench: [Wide::default(); 3],
            contact: [None; LANES],
            touching: [0; LANES],
            held: [0; LANES],
            rng: std::array::from_fn(|_| Rng::new(0)),
        }
    }

    /// Lane `l` takes `s`.
    fn gather(&mut self, l: usize, s: &State) {
        assert!(l < LANES, "lane {l} of {LANES}");
        let n = self.q.len();
        // The five parts in the order a `State` holds them.
        let parts = [
            &mut self.q,
            &mut self.v,
            &mut self.a,
            &mut self.v_prev,
            &mut self.a_contact,
        ];
        for (part, x) in parts.into_iter().zip(s.x.chunks_exact(n)) {
            let (part, x) = (&mut part[..n], &x[..n]);
            for i in 0..n {
                part[i].0[l] = x[i];
            }
        }
        self.t.0[l] = s.t;
        self.base[l] = s.base;
        for k in 0..3 {
            self.wrench_alpha[k].0[l] = s.wrench_alpha[k];
            self.base_wrench[k].0[l] = s.base_wrench[k];
        }
        self.contact[l] = s.contact;
        self.touching[l] = s.touching;
        self.held[l] = s.held;
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

    /// `s` takes lane `l`.
    fn scatter(&self, l: usize, s: &mut State) {
        assert!(l < LANES, "lane {l} of {LANES}");
        let n = self.q.len();
        let parts = [&self.q, &self.v, &self.a, &self.v_prev, &self.a_contact];
        for (part, x) in parts.into_iter().zip(s.x.chunks_exact_mut(n)) {
            let (part, x) = (&part[..n], &mut x[..n]);
            for i in 0..n {
                x[i] = part[i].0[l];
            }
        }
        s.t = self.t.0[l];
        s.base = self.base[l];
        for k in 0..3 {
            s.wrench_alpha[k] = self.wrench_alpha[k].0[l];
            s.base_wrench[k] = self.base_wrench[k].0[l];
        }
        s.contact = self.contact[l];
        s.touching = self.touching[l];
        s.held = self.held[l];
        s.rng.clone_from(&self.rng[l]);
    }
}

/// What the contact stage found for each lane in its last iteration.
#[derive(Debug, Clone)]
struct LaneContacts {
    /// Whether the lane had contact candidates (their terms then enter the update).
    any: [bool; LANES],
    /// Accelerations of impacts, of lasting contacts, and the penetration fix, per joint.
    acc: Vec<Wide>,
    lasting: Vec<Wide>,
    fix: Vec<Wide>,
    touching: [u64; LANES],
    held: [u128; LANES],
    report: [Option<ContactReport>; LANES],
}

impl LaneContacts {
    fn new(n: usize) -> LaneContacts {
        LaneContacts {
            any: [false; LANES],
            acc: vec![Wide::default(); n],
            lasting: vec![Wide::default(); n],
            fix: vec![Wide::default(); n],
            touching: [0; LANES],
            held: [0; LANES],
            report: [None; LANES],
        }
    }

    /// No contact in lane `l`.
    fn clear_lane(&mut self, l: usize) {
        self.any[l] = false;
        for x in self
            .acc
            .iter_mut()
            .chain(&mut self.lasting)
            .chain(&mut self.fix)
        {
            x.0[l] = 0.0;
        }
        self.touching[l] = 0;
        self.held[l] = 0;
        self.report[l] = None;
    }

    /// No contact in any lane.
    fn clear(&mut self) {
        self.any = [false; LANES];
        for x in self
            .acc
            .iter_mut()
            .chain(&mut self.lasting)
            .chain(&mut self.fix)
        {
            *x = Wide::default();
        }
        self.touching = [0; LANES];
        self.held = [0; LANES];
        self.report = [None; LANES];
    }
}

/// Scratch memory for stepping lane groups of one segment count; reuse it across calls.
#[derive(Debug, Clone)]
pub struct LaneWorkspace {
    n: usize,
    state: LaneState,
    scratch: LaneScratch,
    contacts: LaneContacts,
    /// Where the geometric iterations are at: the latest estimate of the intermediate state per
    /// lane, and the solve's results kept from each lane's last iteration.
    q_lin: Vec<Wide>,
    v_lin: Vec<Wide>,
    qdd: Vec<Wide>,
    wrench: [Wide; 3],
    /// One lane's start of step, for its contact stage.
    start: [Vec<f64>; 3],
}

impl LaneWorkspace {
    /// Scratch for lane groups of a model of `model.n` segments.
    pub fn new(model: &Model) -> LaneWorkspace {
        let n = model.n;
        LaneWorkspace {
            n,
            state: LaneState::new(n),
            scratch: LaneScratch::new(n),
            contacts: LaneContacts::new(n),
            q_lin: vec![Wide::default(); n],
            v_lin: vec![Wide::default(); n],
            qdd: vec![Wide::default(); n],
            wrench: [Wide::default(); 3],
            start: [vec![0.0; n], vec![0.0; n], vec![0.0; n]],
        }
    }

    /// Segment count this scratch is for.
    pub fn n(&self) -> usize {
        self.n
    }
}

/// Whether `states` can be stepped together in lanes by `st` (`loads`: whether point loads
/// act): no loads, whole steps on `model` itself (no substeps near contact, no fitted chain), one
/// to [`LANES`] states of `model`.
pub fn lanes_apply<S: BorrowMut<State>>(
    model: &Model,
    st: &Stepper,
    states: &[S],
    loads: bool,
) -> bool {
    !loads
        && !st.fit_first_mode
        && st.contact_substeps <= 1
        && !states.is_empty()
        && states.len() <= LANES
        && states.iter().all(|s| s.borrow().n() == model.n)
}

/// Advances each of `states` (one to [`LANES`] of them, of `model`; states or references to
/// them) by `steps` steps of `st` with the same `inputs`, as [`step`] does one at a time, to the
/// same bits. Returns each state's outcome: `None`, or the error of the step at which it
/// diverged (it is then left as it was before that step, as [`step`] leaves it). States that
/// cannot be stepped in lanes (see [`lanes_apply`]) are stepped one at a time with `ws`.
pub fn step_group<S: BorrowMut<State>>(
    model: &Model,
    st: &Stepper,
    states: &mut [S],
    inputs: &Inputs,
    steps: usize,
    lw: &mut LaneWorkspace,
    ws: &mut Workspace,
) -> [Option<Error>; LANES] {
    let plan = Plan {
        base: inputs.base,
        loads: inputs.loads,
        noise: &|_| inputs.noise,
        objects: Objects::Shared(inputs.objects),
        steps,
    };
    run(model, st, states, &plan, lw, ws)
}

/// As [`step_group`], each state against its own objects (`objects[k]` for `states[k]`), with
/// base motion `base`, no point loads, and process noise of intensity `noise(j)` on step `j` of
/// the `steps`.
#[allow(clippy::too_many_arguments)]
pub fn step_group_each<S: BorrowMut<State>>(
    model: &Model,
    st: &Stepper,
    states: &mut [S],
    objects: &[&[Object]],
    base: BaseMotion,
    noise: &(dyn Fn(usize) -> f64 + Sync),
    steps: usize,
    lw: &mut LaneWorkspace,
    ws: &mut Workspace,
) -> [Option<Error>; LANES] {
    assert_eq!(objects.len(), states.len(), "one object list per state");
    let plan = Plan {
        base,
        loads: &[],
        noise,
        objects: Objects::Each(objects),
        steps,
    };
    run(model, st, states, &plan, lw, ws)
}

/// What a call steps its states with.
struct Plan<'a> {
    base: BaseMotion,
    loads: &'a [super::PointLoad],
    noise: &'a (dyn Fn(usize) -> f64 + Sync),
    objects: Objects<'a>,
    steps: usize,
}

/// The objects of a call's states: the same for all, or each state's own.
#[derive(Clone, Copy)]
enum Objects<'a> {
    Shared(&'a [Object]),
    Each(&'a [&'a [Object]]),
}

impl Plan<'_> {
    /// The inputs of state `k`'s step `j`.
    fn inputs(&self, k: usize, j: usize) -> Inputs<'_> {
        Inputs {
            base: self.base,
            loads: self.loads,
            noise: (self.noise)(j),
            objects: self.objects_of(k),
        }
    }

    /// The objects of state `k`.
    fn objects_of(&self, k: usize) -> &[Object] {
        match self.objects {
            Objects::Shared(all) => all,
            Objects::Each(each) => each[k],
        }
    }
}

/// Steps `state` (number `k` of the call) from step `first` to the plan's end, one at a time.
fn single(
    model: &Model,
    st: &Stepper,
    state: &mut State,
    plan: &Plan,
    k: usize,
    first: usize,
    ws: &mut Workspace,
) -> Option<Error> {
    (first..plan.steps).find_map(|j| step(model, st, state, &plan.inputs(k, j), ws).err())
}

fn run<S: BorrowMut<State>>(
    model: &Model,
    st: &Stepper,
    states: &mut [S],
    plan: &Plan,
    lw: &mut LaneWorkspace,
    ws: &mut Workspace,
) -> [Option<Error>; LANES] {
    let mut out: [Option<Error>; LANES] = Default::default();
    let count = states.len();
    if !lanes_apply(model, st, states, !plan.loads.is_empty()) || lw.n != model.n || ws.n != model.n
    {
        for (k, (s, o)) in states.iter_mut().zip(out.iter_mut()).enumerate() {
            *o = single(model, st, s.borrow_mut(), plan, k, 0, ws);
        }
        return out;
    }
    // Lanes beyond the states given step a copy of the first (and are thrown away).
    for l in 0..LANES {
        lw.state.gather(l, states[l.min(count - 1)].borrow());
    }
    // The copies step without objects: their contact stages would be thrown away.
    let objects: [&[Object]; LANES] =
        std::array::from_fn(|l| if l < count { plan.objects_of(l) } else { &[] });
    let mut live: [bool; LANES] = std::array::from_fn(|l| l < count);
    for j in 0..plan.steps {
        if !live.iter().any(|x| *x) {
            break;
        }
        let inputs = plan.inputs(0, j);
        if let Err(e) = check_inputs(model, &inputs) {
            // As the single-state step: refused before the step, the state as it was.
            for l in 0..count {
                if live[l] {
                    lw.state.scatter(l, states[l].borrow_mut());
                    out[l] = Some(e.clone());
                }
            }
            return out;
        }
        let retake = step_lanes(model, st, lw, &inputs, &objects, ws);
        let kept = lw.state.sound(model);
        for l in 0..count {
            if !live[l] || (kept[l] && !retake[l]) {
                continue;
            }
            // The single-state step would take this step again (halved, or without a contact
            // force that ended): it steps the state from where the call found it (to the same
            // bits up to this step: lanes are written back only at the end).
            live[l] = false;
            out[l] = single(model, st, states[l].borrow_mut(), plan, l, 0, ws);
        }
    }
    for l in 0..count {
        if live[l] {
            lw.state.scatter(l, states[l].borrow_mut());
        }
    }
    out
}

/// The method's coefficients, lane by lane (a lane that begins the step in lasting contact has
/// `Integrator::contact_rho_inf`'s).
struct Coefs {
    am: Wide,
    af: Wide,
    beta: Wide,
    gamma: Wide,
    dq: Wide,
    dv: Wide,
    steppers: [Stepper; LANES],
}

impl Coefs {
    fn new(st: &Stepper, touching: &[u64; LANES]) -> Coefs {
        let held = st.in_contact();
        let steppers: [Stepper; LANES] = std::array::from_fn(|l| {
            if touching[l] != 0 && st.contact_rho_inf != st.rho_inf {
                held
            } else {
                *st
            }
        });
        let lanes = |f: fn(&Stepper) -> f64| Wide(std::array::from_fn(|l| f(&steppers[l])));
        Coefs {
            am: lanes(|s| s.alpha_m),
            af: lanes(|s| s.alpha_f),
            beta: lanes(|s| s.beta),
            gamma: lanes(|s| s.gamma),
            dq: lanes(|s| s.dq),
            dv: lanes(|s| s.dv),
            steppers,
        }
    }

    /// `f(lane's coefficients)` per lane: a derived coefficient computed as the single-state step
    /// computes it.
    fn map(&self, f: impl Fn(&Stepper) -> f64) -> Wide {
        Wide(std::array::from_fn(|l| f(&self.steppers[l])))
    }
}

/// One step of the method on every lane (see `single::step_once`, of which this is the case
/// without point loads, written over lanes), lane `l` against `objects[l]`. Returns the lanes
/// that the single-state step would take again (a lasting contact that ended, or a contact stage
/// that failed).
fn step_lanes(
    model: &Model,
    st: &Stepper,
    lw: &mut LaneWorkspace,
    inputs: &Inputs,
    objects: &[&[Object]; LANES],
    ws1: &mut Workspace,
) -> [bool; LANES] {
    let n = model.n;
    let h = st.dt;
    let mut retake = [false; LANES];
    let co = Coefs::new(st, &lw.state.touching);
    let c1 = co.map(|s| 1.0 - s.alpha_f);
    let s = &mut lw.state;
    let ws = &mut lw.scratch;
    let cs = &mut lw.contacts;
    // Base motion at the intermediate time, per lane.
    let b1 = inputs.base;
    let mut base = LaneBase::default();
    for l in 0..LANES {
        let (b0, c1) = (s.base[l], c1.0[l]);
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
    let with_objects: [bool; LANES] = std::array::from_fn(|l| !objects[l].is_empty());
    cs.clear();

    let c1h = co.map(|s| (1.0 - s.alpha_f) * h);
    let cq_a = co.map(|s| (1.0 - s.alpha_f) * h * h * (0.5 - s.beta) - s.dq * s.alpha_m);
    let cv_a = co.map(|s| (1.0 - s.alpha_f) * h * (1.0 - s.gamma) - s.dv * s.alpha_m);
    let h_w = Wide::splat(h);
    let fix_c = co.map(|s| (1.0 - s.alpha_f) * h - s.dv);
    let half_hh = Wide::splat(0.5 * h * h);
    // The lanes this attempt computes: all of them first, then those whose lasting contact ended
    // (taken again without its force in the history, as the single-state step does).
    let mut taking = [true; LANES];
    for attempt in 0..2 {
        // Predict.
        for i in 0..n {
            let (q, v, a, vp) = (s.q[i], s.v[i], s.a[i], s.v_prev[i]);
            lw.q_lin[i] = q + c1h * v + cq_a * a;
            lw.v_lin[i] = v + cv_a * a;
            ws.q[i] = q + c1h * v;
            ws.v[i] = v + c1 * (v - vp);
        }
        // Passive joint torques, implicit in the springs and dampers.
        for i in 0..n {
            let (k, d) = (model.stiffness[i], model.damping[i]);
            ws.arm[i] = Wide::splat(k) * co.dq + Wide::splat(d) * co.dv;
            ws.tau[i] = Wide::splat(-k) * (lw.q_lin[i] - Wide::splat(model.rest[i]))
                - Wide::splat(d) * lw.v_lin[i];
        }

        // Geometric iterations; a lane whose estimate stops moving keeps the results of its
        // last solve while the others go on.
        let mut active = taking;
        let mut iterations = 0;
        loop {
            iterations += 1;
            ws.kinematics(model, &base);
            if inputs.noise > 0.0 {
                ws.noise_forces(model);
            }
            ws.solve(model, &base);
            // The broad phase's whisker terms, every lane at once: the bounding box of the
            // nodes and the fastest point's speed, as `reach` computes them for one state.
            let mut wb = [
                Wide::splat(f64::INFINITY),
                Wide::splat(f64::INFINITY),
                Wide::splat(f64::NEG_INFINITY),
                Wide::splat(f64::NEG_INFINITY),
            ];
            for p in &ws.node[..=n] {
                wb = [
                    wb[0].min(p[0]),
                    wb[1].min(p[1]),
                    wb[2].max(p[0]),
                    wb[3].max(p[1]),
                ];
            }
            let length = Wide::splat(model.whisker_length());
            let mut wmax = Wide::splat(0.0);
            for sg in &ws.seg[..n] {
                let v = &sg.vel;
                wmax = wmax.max((v[1] * v[1] + v[2] * v[2]).sqrt() + v[0].abs() * length);
            }
            // Contact, lane by lane, on the single-state stage.
            for l in 0..LANES {
                if !(active[l] && with_objects[l]) || retake[l] {
                    continue;
                }
                let stl = &co.steppers[l];
                // No object in reach: the contact stage would find no candidate.
                let lane_wb = [wb[0].0[l], wb[1].0[l], wb[2].0[l], wb[3].0[l]];
                let (t0, h) = (s.t.0[l], stl.dt);
                if super::reach::none_in_reach(model, objects[l], t0, h, lane_wb, wmax.0[l]) {
                    cs.clear_lane(l);
                    continue;
                }
                let lane_inputs = Inputs {
                    objects: objects[l],
                    ..*inputs
                };
                let base_turn = b1.angle - base.angle.0[l];
                let parts = (&*s, &mut *ws, &mut *cs, &mut lw.start);
                if lane_contact(model, stl, parts, l, &lane_inputs, base_turn, ws1).is_err() {
                    retake[l] = true;
                }
            }
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
                let mut qf = lw.q_lin[i] + co.dq * ws.qdd[i];
                let mut vf = lw.v_lin[i] + co.dv * ws.qdd[i];
                if cs.any.iter().any(|x| *x) {
                    let (ac, fix) = (cs.acc[i], cs.fix[i]);
                    let qc = qf + (c1 * (half_hh * ac + fix) - co.dq * ac);
                    let vc = vf + fix_c * ac;
                    qf = Wide::select(cs.any, qc, qf);
                    vf = Wide::select(cs.any, vc, vf);
                }
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
        if attempt == 1 {
            break;
        }
        // A lasting contact that ended: the step is taken again without its force in the
        // history, so the whisker is not pushed by a force that no longer acts.
        taking = std::array::from_fn(|l| {
            let released = s.touching[l] & !cs.touching[l] != 0;
            !retake[l] && released && s.a_contact.iter().any(|x| x.0[l] != 0.0)
        });
        if !taking.iter().any(|x| *x) {
            break;
        }
        for i in 0..n {
            let (a, ac) = (s.a[i], s.a_contact[i]);
            s.a[i] = Wide::select(taking, a - ac, a);
            s.a_contact[i] = Wide::select(taking, Wide::default(), ac);
        }
    }

    // Integrate to the end of the step.
    let inv_am = co.map(|s| 1.0 / (1.0 - s.alpha_m));
    let hh_w = Wide::splat(h * h);
    let b_a = co.map(|s| 0.5 - s.beta);
    let g_a = co.map(|s| 1.0 - s.gamma);
    let imp_q = co.map(|s| h * h * (0.5 - s.beta));
    let imp_v = co.map(|s| h * (1.0 - s.gamma));
    let any_contact = cs.any.iter().any(|x| *x);
    for i in 0..n {
        let (q, v, a) = (s.q[i], s.v[i], s.a[i]);
        let a_new = (lw.qdd[i] - co.am * a) * inv_am;
        let mut q_new = q + h_w * v + hh_w * (b_a * a + co.beta * a_new);
        let mut v_new = v + h_w * (g_a * a + co.gamma * a_new);
        let mut a_kept = a_new;
        if any_contact {
            let (ac, fix) = (cs.acc[i] * inv_am, cs.fix[i]);
            a_kept = Wide::select(cs.any, a_kept - ac, a_kept);
            q_new = Wide::select(cs.any, q_new + (imp_q * ac + fix), q_new);
            v_new = Wide::select(cs.any, v_new + imp_v * ac, v_new);
        }
        s.v_prev[i] = v;
        s.q[i] = q_new;
        s.v[i] = v_new;
        s.a[i] = a_kept;
        s.a_contact[i] = cs.lasting[i];
    }
    // Base reaction, extrapolated from the intermediate time to the end of the step.
    for k in 0..3 {
        let (wk, prev) = (lw.wrench[k], s.wrench_alpha[k]);
        let extrapolated = wk + co.af * (wk - prev);
        let first = std::array::from_fn(|l| s.t.0[l] == 0.0);
        s.base_wrench[k] = Wide::select(first, wk, extrapolated);
        s.wrench_alpha[k] = wk;
    }
    s.contact = cs.report;
    s.touching = cs.touching;
    s.held = cs.held;
    s.t += h_w;
    s.base = [inputs.base; LANES];
    retake
}

/// Lane `l`'s contact stage: its kinematics and solve copied into the single-state workspace
/// `ws`, the single-state contact stage run there (with the lane's own stepper `st`, which
/// differs in lasting contact), and its results copied back into the lane.
#[allow(clippy::needless_range_loop)] // one index over several layouts
fn lane_contact(
    model: &Model,
    st: &Stepper,
    (state, sc, cs, start): (
        &LaneState,
        &mut LaneScratch,
        &mut LaneContacts,
        &mut [Vec<f64>; 3],
    ),
    l: usize,
    inputs: &Inputs,
    base_turn: f64,
    ws: &mut Workspace,
) -> Result<()> {
    let n = model.n;
    // One check of the lane, and slices of one length, so that the copies index without checks.
    assert!(l < LANES, "lane {l} of {LANES}");
    for (to, from) in ws.node[..=n].iter_mut().zip(&sc.node[..=n]) {
        *to = [from[0].0[l], from[1].0[l]];
    }
    // Each value is read from its lane in place (mapping a `[Wide; 3]` by value would copy all
    // of its lanes first).
    for (to, from) in ws.seg[..n].iter_mut().zip(&sc.seg[..n]) {
        to.vel = std::array::from_fn(|k| from.vel[k].0[l]);
        to.u_vec = std::array::from_fn(|k| from.u_vec[k].0[l]);
        to.inv_d = from.inv_d.0[l];
    }
    let [q0, v0, a0] = start;
    let (q0, v0, a0) = (&mut q0[..n], &mut v0[..n], &mut a0[..n]);
    let (qdd, q) = (&mut ws.qdd[..n], &mut ws.q[..n]);
    let (sc_qdd, sc_q) = (&sc.qdd[..n], &sc.q[..n]);
    let (sq, sv, sa) = (&state.q[..n], &state.v[..n], &state.a[..n]);
    for i in 0..n {
        qdd[i] = sc_qdd[i].0[l];
        q[i] = sc_q[i].0[l];
        q0[i] = sq[i].0[l];
        v0[i] = sv[i].0[l];
        a0[i] = sa[i].0[l];
    }
    ws.seg[0].acc = std::array::from_fn(|k| sc.seg[0].acc[k].0[l]);
    ws.pa0 = std::array::from_fn(|k| sc.pa0[k].0[l]);
    let from = StepStart {
        q: &start[0],
        v: &start[1],
        a: &start[2],
        touching: state.touching[l],
        held: state.held[l],
        base_turn,
        base_rate: inputs.base.rate,
    };
    contact::solve(model, st, ws, inputs, &from, state.t.0[l])?;
    let (qdd, acc, lasting, fix) = (
        &mut sc.qdd[..n],
        &mut cs.acc[..n],
        &mut cs.lasting[..n],
        &mut cs.fix[..n],
    );
    let c = &ws.contacts;
    let (ws_qdd, ws_acc, ws_lasting, ws_fix) = (
        &ws.qdd[..n],
        &c.acc[..n],
        &c.acc_lasting[..n],
        &c.position_fix[..n],
    );
    for i in 0..n {
        qdd[i].0[l] = ws_qdd[i];
        acc[i].0[l] = ws_acc[i];
        lasting[i].0[l] = ws_lasting[i];
        fix[i].0[l] = ws_fix[i];
    }
    for k in 0..3 {
        sc.pa0[k].0[l] = ws.pa0[k];
        sc.seg[0].acc[k].0[l] = ws.seg[0].acc[k];
    }
    cs.any[l] = ws.contacts.count > 0;
    cs.touching[l] = ws.contacts.touching();
    cs.held[l] = ws.contacts.held();
    cs.report[l] = ws.contacts.report(model, false);
    Ok(())
}
