//! Substeps near contact ([`Integrator::contact_substeps`](super::Integrator::contact_substeps)):
//! a step that starts in contact, or with an object within reach of the whisker, is taken as
//! equal substeps, so that a long step keeps the free whisker's cost while impacts, sliding and
//! release are resolved at the substep.
//!
//! Within reach means: some segment's surface is closer to an object (where the object is at
//! the start of the step) than twice the distance the two can close in one step, at the
//! object's speed (the larger of its speeds at the step's ends and its mean speed over the step,
//! plus its angular speed times its reach over the whisker) and the fastest point of the whisker
//! now. A contact can therefore begin only in a step that is already substepped, unless the
//! whisker or the object more than doubles its speed within one step.
//!
//! A substep in which some object begins or ends carrying contact force (an impact, a release)
//! is taken again as two halves, and a half in which that happens again is halved in turn, down
//! to a sixteenth of the substep ([`EVENT_DEPTH`] halvings): the event is located by bisection,
//! so that the impact's impulse and the moment of release fall within a sixteenth of the
//! substep of where they belong, at the cost of about two steps per halving. The halves that
//! hold no event are taken whole.
//!
//! With [`Integrator::fit_first_mode`](super::Integrator::fit_first_mode), the steps taken
//! whole are taken on a copy of the chain whose masses and inertias are scaled by
//! `(ω1/ω)²`, where `ω` is the frequency that the method at the step turns into the chain's
//! first natural frequency `ω1` (from the amplification matrix of the undamped oscillator): the
//! free whisker's first mode then rings at its own frequency, not 0.87% low at 1 ms (w30,
//! N = 20), and its statics are unchanged. The chain's modes are found once per chain and step
//! (a dense eigen-solve) and the copy is kept in the workspace. The higher modes, unresolved at
//! such steps, keep their errors, and inertial loads (base acceleration) are scaled too (by
//! 0.983 at 1 ms).
//!
//! The process noise's random forces are drawn once for the step and kept by all its substeps
//! and halves: the forcing is the one a step taken whole would have, and the substeps only
//! resolve the motion under it.
//!
//! The substeps interpolate the base motion between the step's ends (a cubic in the angle from
//! its values and rates, the acceleration linearly) and each is one step of the method, halved
//! where it diverges. The rates one step earlier, which predict the first geometric iterate of
//! the next step, are rescaled to the substep on the way in and back to the step on the way out.

use super::inputs::{BaseMotion, Inputs};
use super::integrator::{Integrator, Stepper};
use super::single::{step_whole, Forcing};
use super::state::State;
use super::workspace::Workspace;
use crate::chain::Model;
use crate::error::Result;
use crate::objects::{bounds, closest};

/// Halvings by which an impact or a release is located within its substep (`2^EVENT_DEPTH`
/// finer pieces at most).
pub(crate) const EVENT_DEPTH: usize = 4;

/// How many steps' worth of closing motion count as within reach.
const REACH_STEPS: f64 = 2.0;

/// Whether the step of `st` from `state` should be substepped: the state carries contact force,
/// or an object in the whisker's plane at either end of the step is within reach (see the
/// module's documentation). Evaluates the state's kinematics in `ws`.
pub(super) fn near_contact(
    model: &Model,
    st: &Stepper,
    state: &State,
    inputs: &Inputs,
    ws: &mut Workspace,
) -> bool {
    if state.touching != 0 {
        return true;
    }
    let n = model.n;
    let (h, t0) = (st.dt, state.t);
    let t1 = t0 + h;
    ws.evaluate(model, state);
    let length = model.whisker_length();
    let whisker_speed = ws.seg[..n].iter().fold(0.0f64, |m, s| {
        m.max(s.vel[1].hypot(s.vel[2]) + s.vel[0].abs() * length)
    });
    let rmax = model.radius.iter().cloned().fold(0.0, f64::max);
    let nodes = &ws.node[..=n];
    let mut wb = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for p in nodes {
        wb = [
            wb[0].min(p[0]),
            wb[1].min(p[1]),
            wb[2].max(p[0]),
            wb[3].max(p[1]),
        ];
    }
    for obj in inputs.objects {
        if !(obj.in_plane(t0) || obj.in_plane(t1)) {
            continue;
        }
        let (p0, p1) = (obj.pose(t0), obj.pose(t1));
        let moved = (p1.position[0] - p0.position[0]).hypot(p1.position[1] - p0.position[1]) / h;
        let lever = p0.position[0].hypot(p0.position[1]) + length;
        let turn = p0
            .angular_velocity
            .abs()
            .max(p1.angular_velocity.abs())
            .max(((p1.angle - p0.angle) / h).abs());
        let speed = p0.velocity[0]
            .hypot(p0.velocity[1])
            .max(p1.velocity[0].hypot(p1.velocity[1]))
            .max(moved)
            + turn * lever;
        let reach = rmax + REACH_STEPS * h * (speed + whisker_speed);
        let ob = bounds(&obj.shape, &p0);
        if ob[0] > wb[2] + reach
            || ob[2] < wb[0] - reach
            || ob[1] > wb[3] + reach
            || ob[3] < wb[1] - reach
        {
            continue;
        }
        for i in 0..n {
            let (a, b) = (nodes[i], nodes[i + 1]);
            if a[0].min(b[0]) > ob[2] + reach
                || a[0].max(b[0]) < ob[0] - reach
                || a[1].min(b[1]) > ob[3] + reach
                || a[1].max(b[1]) < ob[1] - reach
            {
                continue;
            }
            let c = closest(&obj.shape, &p0, a, b);
            let radius = model.radius[i] + c.u * (model.radius[i + 1] - model.radius[i]);
            if c.distance - radius < reach - rmax {
                return true;
            }
        }
    }
    false
}

/// The base motion at the fraction `s` of a step of `h` from `b0` to `b1`: the angle a cubic
/// through both ends' angles and rates, the rate its derivative, the acceleration linear.
fn base_at(b0: BaseMotion, b1: BaseMotion, h: f64, s: f64) -> BaseMotion {
    let (s2, s3) = (s * s, s * s * s);
    let (h00, h10, h01, h11) = (
        2.0 * s3 - 3.0 * s2 + 1.0,
        s3 - 2.0 * s2 + s,
        -2.0 * s3 + 3.0 * s2,
        s3 - s2,
    );
    let (d00, d10, d01, d11) = (
        6.0 * s2 - 6.0 * s,
        3.0 * s2 - 4.0 * s + 1.0,
        -6.0 * s2 + 6.0 * s,
        3.0 * s2 - 2.0 * s,
    );
    BaseMotion {
        angle: h00 * b0.angle + h10 * h * b0.rate + h01 * b1.angle + h11 * h * b1.rate,
        rate: (d00 * b0.angle + d01 * b1.angle) / h + d10 * b0.rate + d11 * b1.rate,
        accel: b0.accel + s * (b1.accel - b0.accel),
    }
}

/// Takes the step of `st` as `st.contact_substeps` equal substeps. On error the state is left as
/// it was before the step.
pub(super) fn take<F: Forcing + ?Sized>(
    model: &Model,
    st: &Stepper,
    state: &mut State,
    inputs: &Inputs,
    ws: &mut Workspace,
    forcing: &mut F,
) -> Result<()> {
    let m = st.contact_substeps;
    let sub = Integrator {
        dt: st.dt / m as f64,
        contact_substeps: 1,
        ..st.integrator()
    }
    .check()?;
    let mut backup = ws.substep_backup.take().unwrap_or_else(|| state.clone());
    backup.clone_from(state);
    let (t0, b0, b1) = (state.t, state.base, inputs.base);
    let n = model.n;
    scale_prev(n, state, 1.0 / m as f64);
    let mut pool = std::mem::take(&mut ws.event_pool);
    if pool.len() < EVENT_DEPTH + 1 {
        pool.resize_with(EVENT_DEPTH + 1, || state.clone());
    }
    // The random forces are drawn once for the whole step and kept by every substep and half
    // (piecewise constant over the step, as in a step taken whole), so that substeps refine the
    // contact's motion under the same forcing instead of forcing it with more, larger draws.
    ws.draw_noise(model, inputs.noise, &mut state.rng, st.dt);
    ws.noise_held = true;
    let mut result = Ok(());
    for j in 1..=m {
        let (c0, c1) = (
            state.base,
            if j == m {
                b1
            } else {
                base_at(b0, b1, st.dt, j as f64 / m as f64)
            },
        );
        let t_sub = state.t;
        result = piece(model, &sub, state, c0, c1, inputs, ws, forcing, &mut pool);
        if result.is_err() {
            break;
        }
        state.t = t_sub + sub.dt;
    }
    ws.event_pool = pool;
    ws.noise_held = false;
    match result {
        Ok(()) => {
            scale_prev(n, state, m as f64);
            state.t = t0 + st.dt;
        }
        Err(_) => state.clone_from(&backup),
    }
    ws.substep_backup = Some(backup);
    result
}

/// Takes one piece of a step of `sub` from `state` (base motion `c0` now, `c1` at its end): whole,
/// and, when some object begins or ends carrying contact force in it and `pool` (one spare state
/// per halving left) allows, again as two halves, each a piece in turn. On error the state is
/// wherever the failed step left it.
#[allow(clippy::too_many_arguments)]
fn piece<F: Forcing + ?Sized>(
    model: &Model,
    sub: &Stepper,
    state: &mut State,
    c0: BaseMotion,
    c1: BaseMotion,
    inputs: &Inputs,
    ws: &mut Workspace,
    forcing: &mut F,
    pool: &mut [State],
) -> Result<()> {
    let part = Inputs {
        base: c1,
        ..*inputs
    };
    let (start, rest) = match pool.split_first_mut() {
        Some((start, rest)) if !rest.is_empty() => (start, rest),
        _ => return step_whole(model, sub, state, &part, ws, forcing),
    };
    start.clone_from(state);
    step_whole(model, sub, state, &part, ws, forcing)?;
    if state.touching == start.touching {
        return Ok(());
    }
    // An impact or a release within the piece: locate it in halves.
    state.clone_from(start);
    let half = Integrator {
        dt: 0.5 * sub.dt,
        contact_substeps: 1,
        ..sub.integrator()
    }
    .check()?;
    let t0 = state.t;
    scale_prev(model.n, state, 0.5);
    let middle = base_at(c0, c1, sub.dt, 0.5);
    piece(model, &half, state, c0, middle, inputs, ws, forcing, rest)?;
    state.t = t0 + half.dt;
    piece(model, &half, state, middle, c1, inputs, ws, forcing, rest)?;
    scale_prev(model.n, state, 2.0);
    state.t = t0 + sub.dt;
    Ok(())
}

/// Rescales the rates one step earlier in `state` (which predict the next step's first
/// geometric iterate) to a step `factor` times as long: their difference from the rates now
/// scales by `factor`.
fn scale_prev(n: usize, state: &mut State, factor: f64) {
    let (v, v_prev) = state.x[n..4 * n].split_at_mut(2 * n);
    for (p, v) in v_prev[..n].iter_mut().zip(&v[..n]) {
        *p = v - factor * (v - *p);
    }
}
