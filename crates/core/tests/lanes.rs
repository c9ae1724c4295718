//! Lane groups step each state to the same bits as the single-state step.

use vibrissa_core::chain::Discretisation;
use vibrissa_core::dynamics::{
    initialize, step, step_group, step_group_each, BaseMotion, Inputs, Integrator, LaneWorkspace,
    State, Stepper, Workspace, LANES,
};
use vibrissa_core::scenes::e2_box;
use vibrissa_core::{Error, Model, WhiskerParams};

fn model(n: usize, curvature: f64) -> Model {
    let mut w = WhiskerParams::w30();
    w.rest_curvature = curvature;
    Model::new(&w.check().unwrap(), n, Discretisation::default()).unwrap()
}

/// `count` states of `model`, each bent its own way by a tip push and released, with its own seed.
fn states(model: &Model, count: usize) -> Vec<State> {
    let mut ws = Workspace::new(model);
    (0..count)
        .map(|k| {
            let mut s = State::at_rest(model, 11 + k as u64);
            let n = model.n;
            for (i, q) in s.q_mut().iter_mut().enumerate() {
                *q += 0.001 * (1.0 + k as f64) * (1.0 - i as f64 / n as f64);
            }
            let none = Inputs {
                base: BaseMotion::default(),
                loads: &[],
                noise: 0.0,
                objects: &[],
            };
            initialize(model, &mut s, &none, &mut ws).unwrap();
            s
        })
        .collect()
}

/// Base motion of a whisking base at time `t`.
fn whisking(t: f64) -> BaseMotion {
    let w = 2.0 * std::f64::consts::PI * 8.0;
    BaseMotion {
        angle: 0.3 * (w * t).sin(),
        rate: 0.3 * w * (w * t).cos(),
        accel: -0.3 * w * w * (w * t).sin(),
    }
}

/// Steps `states` for `rounds` rounds of `steps` steps, in one lane group and one by one, and
/// checks that both give the same states and outcomes after every round.
fn same_as_single(
    model: &Model,
    st: &Stepper,
    states: Vec<State>,
    noise: f64,
    base: fn(f64) -> BaseMotion,
    rounds: usize,
    steps: usize,
) -> usize {
    let mut single = states.clone();
    let mut grouped = states;
    let mut ws = Workspace::new(model);
    let mut lw = LaneWorkspace::new(model);
    let mut failed = 0;
    for r in 0..rounds {
        let t = (r + 1) as f64 * steps as f64 * st.dt;
        let inputs = Inputs {
            base: base(t),
            loads: &[],
            noise,
            objects: &[],
        };
        let want: Vec<Option<Error>> = single
            .iter_mut()
            .map(|s| {
                (0..steps)
                    .map(|_| step(model, st, s, &inputs, &mut ws))
                    .find_map(|r| r.err())
            })
            .collect();
        let mut refs: Vec<&mut State> = grouped.iter_mut().collect();
        let got = step_group(model, st, &mut refs, &inputs, steps, &mut lw, &mut ws);
        assert_eq!(&got[..want.len()], &want[..], "round {r}");
        assert!(got[want.len()..].iter().all(|g| g.is_none()));
        assert_eq!(grouped, single, "round {r}");
        failed += want.iter().filter(|w| w.is_some()).count();
    }
    failed
}

#[test]
fn a_ringing_group_steps_to_the_bits_of_single_steps() {
    // The filter's free-ringing setting (one geometric iteration, 1 ms) and the simulator's
    // (iterated to its tolerance, 0.1 ms), with process noise, on a straight and a curved chain.
    let fast = Integrator {
        dt: 1e-3,
        max_iterations: 1,
        ..Integrator::default()
    }
    .check()
    .unwrap();
    let fine = Integrator::default().check().unwrap();
    for (n, curvature) in [(5, 0.0), (20, 20.0)] {
        let m = model(n, curvature);
        for st in [&fast, &fine] {
            for count in 1..=LANES {
                let failed = same_as_single(
                    &m,
                    st,
                    states(&m, count),
                    2e-5,
                    |_| BaseMotion::default(),
                    20,
                    3,
                );
                assert_eq!(failed, 0);
            }
        }
    }
}

#[test]
fn a_whisking_group_without_noise_steps_to_the_bits_of_single_steps() {
    let m = model(20, 20.0);
    let st = Integrator::default().check().unwrap();
    let failed = same_as_single(&m, &st, states(&m, 3), 0.0, whisking, 30, 5);
    assert_eq!(failed, 0);
}

#[test]
fn a_lane_that_diverges_is_halved_and_reported_as_the_single_step_would() {
    // Forces strong enough to fold some whiskers at a long step: the lanes that diverge are
    // handed back to the single-state step, which halves the step and fails or not as it would
    // have alone.
    let m = model(5, 0.0);
    let st = Integrator {
        dt: 1e-3,
        max_iterations: 1,
        ..Integrator::default()
    }
    .check()
    .unwrap();
    let mut failed = 0;
    for noise in [3e-3, 1e-2, 3e-2] {
        failed += same_as_single(
            &m,
            &st,
            states(&m, 4),
            noise,
            |_| BaseMotion::default(),
            10,
            2,
        );
    }
    assert!(
        failed > 0,
        "no lane diverged: the test does not test the fallback"
    );
}

#[test]
fn a_group_with_an_object_is_stepped_one_state_at_a_time() {
    let m = model(20, 0.0);
    let st = Integrator::default().check().unwrap();
    let objects = [e2_box(0.02, 0.8)];
    let inputs = Inputs {
        base: BaseMotion::default(),
        loads: &[],
        noise: 0.0,
        objects: &objects,
    };
    let mut single = states(&m, 2);
    let mut grouped = single.clone();
    let mut ws = Workspace::new(&m);
    let mut lw = LaneWorkspace::new(&m);
    for s in single.iter_mut() {
        for _ in 0..50 {
            step(&m, &st, s, &inputs, &mut ws).unwrap();
        }
    }
    let mut refs: Vec<&mut State> = grouped.iter_mut().collect();
    let got = step_group(&m, &st, &mut refs, &inputs, 50, &mut lw, &mut ws);
    assert!(got.iter().all(|g| g.is_none()));
    assert_eq!(grouped, single);
}

/// States of `model` at rest, each struck by its own e2 box (distance 14–29 mm, speed 0.3–1.5 m/s,
/// friction on every other), stepped in one lane group and one at a time for `duration` seconds
/// in rounds of `steps` steps with process noise `noise`: the same states and outcomes after
/// every round. Returns how many lanes were handed back to the single-state step (a lasting
/// contact that ended, or a step that diverged), summed over rounds, and how many states were
/// touching after some round.
fn strikes_same_as_single(
    model: &Model,
    st: &Stepper,
    count: usize,
    noise: f64,
    duration: f64,
    steps: usize,
) -> usize {
    let boxes: Vec<[vibrissa_core::objects::Object; 1]> = (0..count)
        .map(|k| {
            let d = 0.014 + 0.001 * k as f64;
            let v = 0.3 + 0.08 * k as f64;
            let mut b = e2_box(d, v);
            b.position[1] = -0.0055 - 0.0002 * k as f64;
            b.friction = if k % 2 == 1 { 0.3 } else { 0.0 };
            [b]
        })
        .collect();
    let objects: Vec<&[vibrissa_core::objects::Object]> = boxes.iter().map(|b| &b[..]).collect();
    let start: Vec<State> = (0..count)
        .map(|k| {
            let mut ws = Workspace::new(model);
            let mut s = State::at_rest(model, 100 + k as u64);
            let none = Inputs::default();
            initialize(model, &mut s, &none, &mut ws).unwrap();
            s
        })
        .collect();
    let mut single = start.clone();
    let mut grouped = start;
    let mut ws = Workspace::new(model);
    let mut lw = LaneWorkspace::new(model);
    let rounds = (duration / (st.dt * steps as f64)).round() as usize;
    let noise_at = |j: usize| if j % 3 == 0 { noise } else { 0.0 };
    let mut touched = 0;
    for r in 0..rounds {
        let want: Vec<Option<Error>> = single
            .iter_mut()
            .zip(&objects)
            .map(|(s, objs)| {
                (0..steps).find_map(|j| {
                    let inputs = Inputs {
                        base: BaseMotion::default(),
                        loads: &[],
                        noise: noise_at(j),
                        objects: objs,
                    };
                    step(model, st, s, &inputs, &mut ws).err()
                })
            })
            .collect();
        let got = step_group_each(
            model,
            st,
            &mut grouped,
            &objects,
            BaseMotion::default(),
            &noise_at,
            steps,
            &mut lw,
            &mut ws,
        );
        assert_eq!(&got[..count], &want[..], "round {r}");
        assert_eq!(grouped, single, "round {r}");
        touched += single.iter().filter(|s| s.contact.is_some()).count();
    }
    touched
}

#[test]
fn a_group_striking_its_own_boxes_steps_to_the_bits_of_single_steps() {
    // The filter's contact model (5 segments, 1/3 ms, one geometric iteration, process noise on
    // every third step), and the simulator's (20 segments, 0.1 ms, iterated, no noise).
    let coarse = model(5, 0.0);
    let fast = Integrator {
        dt: 1e-3 / 3.0,
        max_iterations: 1,
        ..Integrator::default()
    }
    .check()
    .unwrap();
    let touched = strikes_same_as_single(&coarse, &fast, LANES, 2e-6, 0.1, 3);
    assert!(touched > 100, "{touched}");
    let touched = strikes_same_as_single(&coarse, &fast, 5, 0.0, 0.1, 7);
    assert!(touched > 30, "{touched}");
    let fine = model(20, 20.0);
    let st = Integrator::default().check().unwrap();
    let touched = strikes_same_as_single(&fine, &st, 6, 0.0, 0.06, 10);
    assert!(touched > 30, "{touched}");
}

#[test]
fn a_group_with_held_contacts_steps_to_the_bits_of_single_steps() {
    // The simulator's chain with held contacts (`Integrator::hold_contacts`): which contact
    // features each lane holds travels with its state.
    let fine = model(20, 20.0);
    let st = Integrator {
        hold_contacts: true,
        ..Integrator::default()
    }
    .check()
    .unwrap();
    let touched = strikes_same_as_single(&fine, &st, 6, 0.0, 0.06, 10);
    assert!(touched > 30, "{touched}");
    let coarse = model(5, 0.0);
    let fast = Integrator {
        dt: 1e-3 / 3.0,
        max_iterations: 1,
        hold_contacts: true,
        ..Integrator::default()
    }
    .check()
    .unwrap();
    let touched = strikes_same_as_single(&coarse, &fast, LANES, 2e-6, 0.1, 3);
    assert!(touched > 100, "{touched}");
}
