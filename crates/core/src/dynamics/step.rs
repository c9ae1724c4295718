//! The time step: predict, passive torques, then kinematics, forces, articulated solve and
//! contact iterated at the intermediate time, and integration to the end of the step, with
//! halving of steps that diverge.

use super::fitted::Fitted;
use super::inputs::{check_inputs, Inputs};
use super::integrator::{Stepper, MAX_DT};
use super::single::{check_state, step_whole, Forcing, NoForcing};
use super::state::State;
use super::substeps;
use super::workspace::Workspace;
use crate::chain::Model;
use crate::error::Result;
use crate::objects::bounds;

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
///
/// A whisker exactly at rest (every rate and acceleration zero, every joint at its rest angle,
/// no base reaction), with a still base, no loads, no process noise and every object beyond
/// contact reach of every segment over the step, stays exactly where it is: the step only
/// advances the clock. The full step would compute the same state (zero torques and forces give
/// zero accelerations), so the result does not depend on this shortcut; it spares the steps
/// before an object arrives.
pub fn step(
    model: &Model,
    st: &Stepper,
    state: &mut State,
    inputs: &Inputs,
    ws: &mut Workspace,
) -> Result<()> {
    if stays_at_rest(model, st, state, inputs, ws) {
        state.t += st.dt;
        state.base = inputs.base;
        state.contact = None;
        ws.contacts.clear();
        return Ok(());
    }
    step_with(model, st, state, inputs, ws, &mut NoForcing)
}

/// Whether a step of `st` from `state` leaves it unchanged (see [`step`]).
fn stays_at_rest(
    model: &Model,
    st: &Stepper,
    state: &State,
    inputs: &Inputs,
    ws: &mut Workspace,
) -> bool {
    let n = model.n;
    let still_base =
        inputs.base == state.base && inputs.base.rate == 0.0 && inputs.base.accel == 0.0;
    if !still_base
        || st.fit_first_mode
        || inputs.noise != 0.0
        || !inputs.loads.is_empty()
        || state.touching != 0
        || state.base_wrench != [0.0; 3]
        || state.wrench_alpha != [0.0; 3]
        || state.x[n..].iter().any(|x| *x != 0.0)
        || state.x[..n].iter().zip(&model.rest).any(|(q, r)| q != r)
    {
        return false;
    }
    if inputs.objects.is_empty() {
        return true;
    }
    // Every segment's bounding box at rest, and every object's at both ends of the step, apart
    // by more than the contact search's reach.
    ws.evaluate(model, state);
    let rmax = model.radius.iter().cloned().fold(0.0, f64::max);
    let t_end = state.t + st.dt;
    let nodes = &ws.node[..=n];
    inputs.objects.iter().all(|obj| {
        [state.t, t_end].iter().all(|&t| {
            let pose = obj.pose(t);
            let speed = pose.velocity[0].hypot(pose.velocity[1])
                + pose.angular_velocity.abs() * model.whisker_length();
            let reach = 2.0 * (rmax + 2.0 * st.dt * speed) + 1e-6;
            let ob = bounds(&obj.shape, &pose);
            nodes.windows(2).all(|s| {
                let (a, b) = (s[0], s[1]);
                a[0].min(b[0]) > ob[2] + reach
                    || a[0].max(b[0]) < ob[0] - reach
                    || a[1].min(b[1]) > ob[3] + reach
                    || a[1].max(b[1]) < ob[1] - reach
            })
        })
    })
}

/// Advances `state` by one step with `inputs` and extra `forcing`.
///
/// A step whose result is not finite or folds a joint past π from its rest angle is not kept:
/// the state is restored and the step taken again as two half steps (the base motion
/// interpolated to the middle), each halved again if it fails, up to [`MAX_HALVINGS`](super::MAX_HALVINGS) times. Only
/// when that fails too does the step return [`Error::Diverged`](crate::error::Error::Diverged), and the state is then left as
/// it was before the step.
///
/// With [`Integrator::contact_substeps`](super::Integrator::contact_substeps) above 1, a step near contact (see the `substeps`
/// module) is taken as that many equal substeps, each one step as above.
pub fn step_with<F: Forcing + ?Sized>(
    model: &Model,
    st: &Stepper,
    state: &mut State,
    inputs: &Inputs,
    ws: &mut Workspace,
    forcing: &mut F,
) -> Result<()> {
    if st.contact_substeps > 1
        && !inputs.objects.is_empty()
        && substeps::near_contact(model, st, state, inputs, ws)
    {
        return substeps::take(model, st, state, inputs, ws, forcing);
    }
    if st.fit_first_mode {
        return fitted_step(model, st, state, inputs, ws, forcing);
    }
    step_whole(model, st, state, inputs, ws, forcing)
}

/// A whole step of `st` on the chain fitted to it ([`Integrator::fit_first_mode`]), or on
/// `model` itself where no fit exists.
fn fitted_step<F: Forcing + ?Sized>(
    model: &Model,
    st: &Stepper,
    state: &mut State,
    inputs: &Inputs,
    ws: &mut Workspace,
    forcing: &mut F,
) -> Result<()> {
    let fitted = match ws.fitted.take() {
        Some(f) if f.fits(model, st) => f,
        _ => Box::new(Fitted::new(model, st)),
    };
    let result = step_whole(fitted.model(), st, state, inputs, ws, forcing);
    ws.fitted = Some(fitted);
    result
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chain::Discretisation;
    use crate::dynamics::{BaseMotion, Integrator};
    use crate::objects::Object;
    use crate::scenes::e2_box;
    use crate::whisker::WhiskerParams;

    /// What a step leaves: the state vector, the base wrench, the contact force and the time.
    type After = (Vec<f64>, [f64; 3], Option<[f64; 2]>, f64);

    /// The e2 box at d = 20 mm, 0.8 m/s, starting 11 mm from the w30 whisker, stepped by
    /// `advance` at the default step for 150 ms: every state after every step.
    fn run(
        advance: fn(&Model, &Stepper, &mut State, &Inputs, &mut Workspace) -> Result<()>,
    ) -> Vec<After> {
        let whisker = WhiskerParams::w30().check().unwrap();
        let model = Model::new(&whisker, 20, Discretisation::default()).unwrap();
        let st = Integrator::default().check().unwrap();
        let objects = [Object {
            position: [0.025, -0.016],
            ..e2_box(0.02, 0.8)
        }];
        let inputs = Inputs {
            base: BaseMotion::default(),
            loads: &[],
            noise: 0.0,
            objects: &objects,
        };
        let mut state = State::at_rest(&model, 1);
        let mut ws = Workspace::new(&model);
        initialize(&model, &mut state, &inputs, &mut ws).unwrap();
        (0..(0.15 / st.dt) as usize)
            .map(|_| {
                advance(&model, &st, &mut state, &inputs, &mut ws).unwrap();
                (
                    state.x.clone(),
                    state.base_wrench,
                    state.contact.map(|c| c.force),
                    state.t,
                )
            })
            .collect()
    }

    #[test]
    fn steps_at_rest_before_the_object_arrives_change_nothing_but_the_clock() {
        let full = run(|m, st, s, i, ws| step_with(m, st, s, i, ws, &mut NoForcing));
        let short = run(step);
        // The whisker rests for a while, is struck, and rings: all of it the same to the bit.
        let resting = full
            .iter()
            .take_while(|s| s.2.is_none() && s.1 == [0.0; 3])
            .count();
        assert!(resting > 100 && resting < full.len() - 100, "{resting}");
        assert!(full.iter().any(|s| s.2.is_some()));
        assert_eq!(full, short);
    }
}
