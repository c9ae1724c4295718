//! One step of the method: predict, passive torques, then kinematics, forces, articulated solve
//! and contact iterated at the intermediate time, and integration to the end of the step, with
//! halving of steps that diverge. [`step`](super::step) decides which steps are taken whole,
//! as substeps, or on the fitted chain; each of those is one or more of these.

use super::contact;
use super::inputs::{check_inputs, BaseMotion, Inputs};
use super::integrator::{Integrator, Stepper};
use super::state::State;
use super::workspace::Workspace;
use crate::chain::Model;
use crate::error::{check_finite, readable, Error, Result};

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

/// How many times a step that diverged is halved before its error is returned: a step of `dt`
/// is retried as two steps of `dt/2`, either of which may be halved again, down to `dt/16`.
pub const MAX_HALVINGS: u32 = 4;

/// One step of `st`, halved where it diverges (see [`step_with`](super::step_with)).
pub(super) fn step_whole<F: Forcing + ?Sized>(
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
/// allows (see [`step_with`](super::step_with)). On error the state is wherever the failed half left it.
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
        ..st.integrator()
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

/// One step of `st`, without retries (see [`step_with`](super::step_with)).
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
    // A step that begins in lasting contact damps the stiff motion the contact adds
    // (`Integrator::contact_rho_inf`).
    let held;
    let st = if state.touching != 0 && st.contact_rho_inf != st.rho_inf {
        held = st.in_contact();
        &held
    } else {
        st
    };
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
    let (touching, held) = (state.touching, state.held);

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
                let start = contact::StepStart {
                    q,
                    v,
                    a,
                    touching,
                    held,
                    base_turn: b1.angle - base.angle,
                    base_rate: b1.rate,
                };
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
    (state.touching, state.held) = if inputs.objects.is_empty() {
        (0, 0)
    } else {
        (ws.contacts.touching(), ws.contacts.held())
    };
    state.t = t_next;
    state.base = inputs.base;
    check_state(state, model)
}

/// Stage boundary check: every value finite, no joint folded past π from rest.
pub(super) fn check_state(state: &State, model: &Model) -> Result<()> {
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
