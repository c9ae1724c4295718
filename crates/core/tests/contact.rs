//! Contact against beam theory, Newton's third law, energy and Coulomb's law (the scenes are
//! described in `vibrissa_core::scenes`).

use vibrissa_core::scenes::{self, peg};
use vibrissa_core::sim::{self, Scenario};

#[test]
fn quasi_static_peg_contact_obeys_beam_theory_and_newtons_third_law() {
    let r = scenes::peg_whisk().unwrap();
    assert!(
        r.samples > 100,
        "only {} samples in small-deflection contact",
        r.samples
    );
    assert!(
        r.moment_arm_error < 0.01,
        "m0/(|f|·s) off by {}",
        r.moment_arm_error
    );
    assert!(
        r.third_law_error < 0.01,
        "m0 vs c × f off by {}",
        r.third_law_error
    );
    assert!(
        r.shape_error < 0.01,
        "shape off by {} of the tip deflection",
        r.shape_error
    );
}

#[test]
fn ringing_after_release_is_at_the_damped_first_frequency() {
    let r = scenes::ringing_after_release().unwrap();
    assert!((r.frequency / r.damped_f1 - 1.0).abs() < 0.01, "{r:?}");
}

#[test]
fn fast_box_penetrates_less_than_a_micrometre() {
    let (worst, touched) = scenes::e2_penetration(1.5).unwrap();
    assert_eq!(touched, 16, "every distance of the grid touches");
    assert!(worst < 1e-6, "{worst}");
}

#[test]
fn energy_never_rises_against_a_stationary_frictionless_object() {
    let r = scenes::release_onto_peg().unwrap();
    assert!(r.contact_steps > 10, "the whisker never touched the peg");
    assert!(r.max_energy_ratio <= 1.0 + 1e-6, "{r:?}");
    assert!(r.max_episode_gain <= 1e-6, "{r:?}");
    assert!(r.max_penetration < 1e-6, "{r:?}");
}

#[test]
fn friction_sticks_below_and_slips_at_the_coulomb_limit() {
    let r = scenes::press_and_shear(0.3, |_, _| {}).unwrap();
    assert!(
        r.max_ratio <= r.mu * (1.0 + 1e-9),
        "friction above the Coulomb limit: {r:?}"
    );
    assert!(r.stick_steps > 50 && r.slip_steps > 50, "{r:?}");
    // Stick comes first: the transverse load grows until it reaches the limit.
    assert!(r.first_slip > 0.07 && r.last_stick > 0.06, "{r:?}");
}

#[test]
fn without_friction_the_tip_slides_freely() {
    let (mut contacts, mut max_t) = (0, 0.0f64);
    scenes::press_and_shear(0.0, |_, s| {
        if let Some(c) = s.contact {
            contacts += 1;
            max_t = max_t.max(c.tangential_force.abs());
        }
    })
    .unwrap();
    assert!(contacts > 100);
    assert_eq!(max_t, 0.0);
}

#[test]
fn objects_overlapping_the_whisker_at_the_start_are_refused() {
    let mut sc = Scenario::default();
    sc.objects.push(peg(0.01, 0.0, 0.001, 0.0));
    let e = sim::run(&sc, &mut |_| {}).unwrap_err().to_string();
    assert!(e.contains("objects[0]") && e.contains("overlapping"), "{e}");
}

#[test]
fn a_divergence_names_its_likely_cause_in_readable_numbers() {
    // A 60 mm block at 500 m/s (50 mm per step: not refused as a thin object passing within a
    // step, see `long_steps`).
    let mut sc = Scenario::default();
    let mut block = vibrissa_core::scenes::e2_box(0.02, 500.0);
    block.shape = vibrissa_core::objects::Shape::Box {
        width: 0.06,
        height: 0.06,
    };
    block.position = [0.05, -0.031];
    sc.objects.push(block);
    let e = sim::run(&sc, &mut |_| {}).unwrap_err().to_string();
    assert!(e.contains("diverged"), "{e}");
    assert!(e.contains("likely cause: objects[0] moves at 500"), "{e}");
    assert!(e.len() < 400, "an unreadable number in: {e}");
    // One at 10 km/s is refused before the run, by its field.
    let mut sc = Scenario::default();
    sc.objects.push(vibrissa_core::scenes::e2_box(0.02, 1e4));
    let e = sim::run(&sc, &mut |_| {}).unwrap_err().to_string();
    assert!(
        e.contains("objects[0].motion.velocity") && e.contains("at most 1000 m/s"),
        "{e}"
    );
    // Random forces a million times the experiments'.
    let mut sc = Scenario::default();
    sc.objects.push(vibrissa_core::scenes::e2_box(0.02, 0.6));
    sc.process_noise = 10.0;
    let e = sim::run(&sc, &mut |_| {}).unwrap_err().to_string();
    assert!(e.contains("likely cause: process_noise"), "{e}");
}

#[test]
fn a_step_that_cannot_be_taken_leaves_the_state_as_it_was() {
    use vibrissa_core::chain::{Discretisation, Model};
    use vibrissa_core::dynamics::{initialize, step, Inputs, Integrator, State, Workspace};
    use vibrissa_core::whisker::WhiskerParams;
    // The e2 box at 500 m/s: no halving of the step can follow it.
    let whisker = WhiskerParams::w30().check().unwrap();
    let model = Model::new(&whisker, 20, Discretisation::default()).unwrap();
    let stepper = Integrator::default().check().unwrap();
    let objects = [vibrissa_core::scenes::e2_box(0.02, 500.0)];
    let inputs = Inputs {
        objects: &objects,
        ..Default::default()
    };
    let mut ws = Workspace::new(&model);
    let mut state = State::at_rest(&model, 1);
    initialize(&model, &mut state, &inputs, &mut ws).unwrap();
    let mut failed = false;
    for _ in 0..200 {
        let before = state.clone();
        if let Err(e) = step(&model, &stepper, &mut state, &inputs, &mut ws) {
            assert!(e.to_string().contains("diverged"), "{e}");
            assert_eq!(state, before, "a failed step changed the state");
            failed = true;
            break;
        }
    }
    assert!(failed, "the 500 m/s box should make a step fail");
}

#[test]
fn sample_rates_above_a_megahertz_are_refused() {
    let mut sc = Scenario {
        sample_rate: 1.1e6,
        ..Scenario::default()
    };
    let e = sim::run(&sc, &mut |_| {}).unwrap_err().to_string();
    assert!(
        e.contains("sample_rate") && e.contains("at most 1e6 Hz"),
        "{e}"
    );
    sc.sample_rate = 1e6;
    sc.duration = 1e-3;
    assert!(sim::run(&sc, &mut |_| {}).is_ok());
}

#[test]
fn an_observed_run_shows_every_sample_and_gives_the_same_output() {
    let mut sc = Scenario {
        duration: 0.05,
        ..Scenario::default()
    };
    sc.objects.push(vibrissa_core::scenes::e2_box(0.02, 0.6));
    sc.process_noise = 2e-5;
    let plain = sim::run(&sc, &mut |_| {}).unwrap();
    let mut shapes: Vec<(usize, f64, Vec<[f64; 2]>)> = Vec::new();
    let observed = sim::run_observed(
        &sc,
        &mut |_| {},
        Some(&mut |s: sim::Snapshot<'_>| shapes.push((s.k, s.t, s.nodes.to_vec()))),
    )
    .unwrap();
    // The same bits (NaN where nothing is touched, so compared as bits).
    let bits =
        |o: &sim::Output| -> Vec<u64> { o.rows.iter().flatten().map(|x| x.to_bits()).collect() };
    assert_eq!(bits(&plain), bits(&observed));
    assert_eq!(
        (plain.steps, plain.dt, plain.max_penetration),
        (observed.steps, observed.dt, observed.max_penetration)
    );
    assert_eq!(shapes.len(), plain.rows.len());
    let length = sc.whisker.length;
    for (k, (index, t, nodes)) in shapes.iter().enumerate() {
        assert_eq!((*index, *t), (k, plain.rows[k][0]));
        assert_eq!(nodes.len(), plain.segments + 1);
        // The base stays at the origin; the chain keeps its length.
        assert!(nodes[0][0].abs() < 1e-12 && nodes[0][1].abs() < 1e-12);
        let chain: f64 = nodes
            .windows(2)
            .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
            .sum();
        assert!(
            (chain - length).abs() < 1e-3 * length,
            "{chain} vs {length}"
        );
    }
    // At rest the tip lies on +x; in contact the box has pushed it up.
    let tip = |k: usize| shapes[k].2[plain.segments];
    assert!(tip(0)[1].abs() < 1e-4 * length && tip(0)[0] > 0.9 * length);
    let touching = plain.rows.iter().position(|r| r[6] > 0.5).expect("contact");
    let later = (touching + 5).min(shapes.len() - 1);
    assert!(tip(later)[1] > 1e-3 * length, "{:?}", tip(later));
}

/// A triangle whose edge meets a straight whisker's tip end-on, square to its axis, while moving
/// across it (the whisker turned −30°, the triangle's edge at 60°): the chain cannot shorten, so
/// the tip must yield sideways. The run completes at the 0.1 ms step, and its contact and base
/// angles follow a run at a 50 times finer step within 1.5% of their range.
#[test]
fn an_edge_meeting_the_tip_end_on_pushes_it_aside() {
    use vibrissa_core::array::{self, Mount};
    use vibrissa_core::objects::{Motion, Object, Shape};
    let side = 0.011_800_861;
    let r = side / 3f64.sqrt();
    let triangle = Object {
        shape: Shape::Polygon {
            vertices: vec![[0.0, r], [-side / 2.0, -r / 2.0], [side / 2.0, -r / 2.0]],
        },
        position: [0.030_567_065, -0.032],
        angle: 0.000_552_63,
        motion: Motion::Constant {
            velocity: [0.0, 1.079_097],
            angular_velocity: 0.0,
        },
        friction: 0.0,
        vertical: None,
    };
    let mount = Mount {
        name: "c1".into(),
        position: [-6.698_73e-4, -2.5e-3],
        angle: -30f64.to_radians(),
        whisker: None,
        base: None,
        sensors: None,
    };
    let run = |dt: f64| {
        let sc = Scenario {
            objects: vec![triangle.clone()],
            duration: 0.05,
            integrator: vibrissa_core::dynamics::Integrator::with_dt(dt),
            ..Scenario::default()
        };
        array::run(&sc, std::slice::from_ref(&mount))
            .unwrap()
            .remove(0)
    };
    let (coarse, fine) = (run(1e-4), run(2e-6));
    // Columns: t, theta01, theta12, m0, fx, fy, contact, ...
    let touched = coarse.rows.iter().filter(|r| r[6] > 0.5).count();
    assert!(touched > 10, "the edge pushes the tip for {touched} ms");
    for c in [1, 2, 3] {
        let range = fine
            .rows
            .iter()
            .map(|r| r[c])
            .fold(f64::NEG_INFINITY, f64::max)
            - fine.rows.iter().map(|r| r[c]).fold(f64::INFINITY, f64::min);
        let rms = (coarse
            .rows
            .iter()
            .zip(&fine.rows)
            .map(|(a, b)| (a[c] - b[c]).powi(2))
            .sum::<f64>()
            / coarse.rows.len() as f64)
            .sqrt();
        assert!(rms < 0.015 * range, "column {c}: {rms} of {range}");
    }
}
