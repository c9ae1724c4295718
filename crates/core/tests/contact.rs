//! Contact against beam theory, Newton's third law, energy and Coulomb's law.

use vibrissa_core::beam::{BeamProfile, PointLoadCubic};
use vibrissa_core::dynamics::{
    kinetic_energy, potential_energy, step, BaseMotion, Inputs, Integrator, State, Workspace,
};
use vibrissa_core::objects::{Motion, Object, Shape};
use vibrissa_core::sensors::Sensors;
use vibrissa_core::sim::{self, penetration, BaseDrive, Scenario};
use vibrissa_core::whisker::Damping;
use vibrissa_core::{statics, Discretisation, Model, PointLoad, WhiskerParams};

fn peg(x: f64, y: f64, radius: f64, friction: f64) -> Object {
    Object {
        shape: Shape::Circle { radius },
        position: [x, y],
        angle: 0.0,
        motion: Motion::default(),
        friction,
    }
}

/// The base turned at `rate` rad/s (smoothly started) into a stationary peg.
fn whisk_into_peg(
    damping: f64,
    friction: f64,
    rate: f64,
    steps: usize,
    mut each: impl FnMut(&Model, &State, &mut Workspace),
) {
    let mut p = WhiskerParams::w30();
    p.damping = Damping::ModalRatio { ratio: damping };
    let w = p.check().unwrap();
    let m = Model::new(&w, 20, Discretisation::Gregory).unwrap();
    let objects = [peg(0.020, 0.5e-3 + 0.1e-3 + 0.02e-3, 0.5e-3, friction)];
    let drive = BaseDrive::Ramp {
        rate,
        start: 0.0,
        stop: f64::INFINITY,
        smoothing: 0.02,
    };
    let st = Integrator::with_dt(1e-4).check().unwrap();
    let mut s = State::at_rest(&m, 0);
    let mut ws = Workspace::new(&m);
    for k in 1..=steps {
        let inputs = Inputs {
            base: drive.at(k as f64 * st.dt),
            objects: &objects,
            ..Default::default()
        };
        step(&m, &st, &mut s, &inputs, &mut ws).unwrap();
        each(&m, &s, &mut ws);
    }
}

#[test]
fn quasi_static_peg_contact_obeys_beam_theory_and_newtons_third_law() {
    // A slow whisk (0.2 rad/s) into a peg 20 mm out: while the deflection is small the base
    // moment over the contact force is the arc length to the contact, the shape is the seed's
    // cubic, and m0 = cx·fy - cy·fx.
    let ei = WhiskerParams::w30().check().unwrap().ei(0.0);
    let mut checked = 0;
    let mut first = f64::INFINITY;
    let mut worst_shape = 0.0f64;
    whisk_into_peg(0.05, 0.0, 0.05, 12_000, |m, s, ws| {
        let Some(c) = s.contact else { return };
        // Quasi-static: after the impact's ringing has died (ζ = 0.05: 0.3 s is 5 time constants;
        // the slow whisk keeps the viscous lag of the shape below 0.5 µm).
        first = first.min(s.t);
        if s.t < first + 0.3 {
            return;
        }
        let sen = Sensors::read(s);
        let f = c.force[0].hypot(c.force[1]);
        // Tip deflection relative to the rotated base, small (< 2% of L).
        ws.evaluate(m, s);
        let (sn, cs) = s.base.angle.sin_cos();
        let local = |p: [f64; 2]| [cs * p[0] + sn * p[1], -sn * p[0] + cs * p[1]];
        let tip = local(ws.nodes()[m.n]);
        if tip[1].abs() > 0.02 * 0.03 || tip[1].abs() < 1e-3 * 0.03 {
            return;
        }
        checked += 1;
        // m0/|f| = arc length to the contact.
        assert!(
            (sen.m0.abs() / f / c.s - 1.0).abs() < 0.01,
            "m0/|f| = {} vs s = {}",
            sen.m0.abs() / f,
            c.s
        );
        // Newton's third law at the base, in the base frame.
        let cp = local(c.point);
        let torque = cp[0] * sen.fy - cp[1] * sen.fx;
        assert!(
            (sen.m0 / torque - 1.0).abs() < 0.01,
            "m0 {} vs c × f {}",
            sen.m0,
            torque
        );
        // Shape: the cubic for a load |f| at the contact's arc length, within 1% of the tip's.
        let cubic = PointLoadCubic { ei, w: -f, c: c.s };
        for p in ws.nodes() {
            let l = local(*p);
            let err = (l[1] - cubic.deflection(l[0])).abs() / tip[1].abs();
            worst_shape = worst_shape.max(err);
        }
    });
    assert!(
        checked > 100,
        "only {checked} samples in small-deflection contact"
    );
    // Shape: the cubic for a load |f| at the contact's arc length, within 1% of the tip's.
    assert!(
        worst_shape < 0.01,
        "shape off by {:.3}% of the tip deflection",
        100.0 * worst_shape
    );
}

#[test]
fn ringing_after_release_is_at_the_damped_first_frequency() {
    // The e2 box passes; the whisker rings freely afterwards.
    let mut sc = Scenario {
        duration: 0.4,
        ..Default::default()
    };
    sc.objects.push(Object {
        shape: Shape::Box {
            width: 0.01,
            height: 0.01,
        },
        position: [0.028, -0.006],
        angle: 0.0,
        motion: Motion::Constant {
            velocity: [0.0, 0.6],
            angular_velocity: 0.0,
        },
        friction: 0.0,
    });
    let out = sim::run(&sc, &mut |_| {}).unwrap();
    let last_contact = out.rows.iter().rposition(|r| r[6] > 0.5).unwrap();
    let (t, y): (Vec<f64>, Vec<f64>) = out.rows[last_contact + 10..]
        .iter()
        .map(|r| (r[0], r[1]))
        .unzip();
    let f = vibrissa_core::validate::crossing_frequency(&t, &y).unwrap();
    let model = Model::new(&sc.whisker.check().unwrap(), 20, Discretisation::Gregory).unwrap();
    let f1 = model.modes().unwrap().frequencies[0];
    let expected = f1 * (1.0f64 - 0.05 * 0.05).sqrt();
    assert!(
        (f / expected - 1.0).abs() < 0.01,
        "ringing at {f} Hz, damped f1 {expected} Hz"
    );
}

#[test]
fn fast_box_penetrates_less_than_a_micrometre() {
    for d in [0.015, 0.023, 0.029] {
        let mut sc = Scenario::default();
        sc.objects.push(Object {
            shape: Shape::Box {
                width: 0.01,
                height: 0.01,
            },
            position: [d + 0.005, -0.006],
            angle: 0.0,
            motion: Motion::Constant {
                velocity: [0.0, 1.5],
                angular_velocity: 0.0,
            },
            friction: 0.0,
        });
        let out = sim::run(&sc, &mut |_| {}).unwrap();
        assert!(out.rows.iter().any(|r| r[6] > 0.5), "no contact at d = {d}");
        assert!(
            out.max_penetration < 1e-6,
            "d = {d}: {}",
            out.max_penetration
        );
    }
}

#[test]
fn energy_never_rises_against_a_stationary_frictionless_object() {
    // An undamped whisker released from a deflection swings into a peg and bounces off it.
    let mut p = WhiskerParams::w30();
    p.damping = Damping::None;
    let w = p.check().unwrap();
    let m = Model::new(&w, 20, Discretisation::Gregory).unwrap();
    let l = w.length();
    let eq = statics::solve(
        &m,
        &[PointLoad {
            segment: 19,
            along: m.len[19],
            force: [0.0, 0.3 * w.ei(0.0) / (l * l)],
        }],
    )
    .unwrap();
    let objects = [peg(0.022, -1.0e-3, 0.5e-3, 0.0)];
    let st = Integrator::with_dt(1e-4).check().unwrap();
    let mut s = State::at_rest(&m, 0);
    s.q_mut().copy_from_slice(&eq.q);
    let mut ws = Workspace::new(&m);
    let inputs = Inputs {
        objects: &objects,
        ..Default::default()
    };
    vibrissa_core::dynamics::initialize(&m, &mut s, &inputs, &mut ws).unwrap();
    // The energy never exceeds its initial value, and no contact episode ends with more energy
    // than it began with (impacts are inelastic; while in contact the impulses and the
    // penetration correction may trade a little energy between steps).
    let e0 = potential_energy(&m, &s);
    let (mut last, mut before, mut was) = (e0, e0, false);
    let mut contacts = 0;
    for _ in 0..3_000 {
        step(&m, &st, &mut s, &inputs, &mut ws).unwrap();
        let now = s.contact.is_some();
        contacts += now as usize;
        let e = potential_energy(&m, &s) + kinetic_energy(&m, &s, &mut ws);
        assert!(
            e <= e0 * (1.0 + 1e-6),
            "energy rose above its initial value: {}",
            e / e0
        );
        if now && !was {
            before = last;
        }
        if was && !now {
            assert!(
                e <= before * (1.0 + 1e-6),
                "contact added energy: {} -> {e}",
                before
            );
        }
        assert!(penetration(&m, &s, &mut ws, &objects) < 1e-6);
        (last, was) = (e, now);
    }
    assert!(contacts > 10, "the whisker never touched the peg");
}

/// A curved whisker's tip pressed end-on by a plate, which then shears sideways: the tip
/// sticks to the plate while the transverse load is below μ·N, then slips at μ·N.
fn press_and_shear(mu: f64, mut each: impl FnMut(f64, &State)) {
    let mut p = WhiskerParams::w30();
    p.rest_curvature = 20.0;
    p.damping = Damping::ModalRatio { ratio: 0.7 };
    let w = p.check().unwrap();
    let m = Model::new(&w, 20, Discretisation::Gregory).unwrap();
    // The tip and its tangent at rest (constant curvature).
    let (k, l) = (20.0f64, w.length());
    let theta = k * l;
    let tip = [theta.sin() / k, (1.0 - theta.cos()) / k];
    let (c, s) = (theta.cos(), theta.sin());
    // A 1 mm thick plate across the tangent, 0.02 mm clear of the tip's surface; pressed 0.3 mm
    // towards the base in 50 ms, then moved 4 mm sideways over 200 ms.
    let clear = 0.1e-3 + 0.5e-3 + 0.02e-3;
    let at = |along: f64, side: f64| [tip[0] + c * along - s * side, tip[1] + s * along + c * side];
    let (p0, p1, p2) = (
        at(clear, 0.0),
        at(clear - 0.32e-3, 0.0),
        at(clear - 0.32e-3, -4e-3),
    );
    let plate = Object {
        shape: Shape::Box {
            width: 1e-3,
            height: 8e-3,
        },
        position: p0,
        angle: theta,
        motion: Motion::Waypoints {
            points: vec![
                [0.0, p0[0], p0[1], theta],
                [0.05, p1[0], p1[1], theta],
                [0.25, p2[0], p2[1], theta],
            ],
        },
        friction: mu,
    };
    let objects = [plate];
    let st = Integrator::with_dt(1e-4).check().unwrap();
    let mut state = State::at_rest(&m, 0);
    let mut ws = Workspace::new(&m);
    let inputs = Inputs {
        objects: &objects,
        ..Default::default()
    };
    for _ in 0..2_500 {
        step(&m, &st, &mut state, &inputs, &mut ws).unwrap();
        each(state.t, &state);
    }
}

#[test]
fn friction_sticks_below_and_slips_at_the_coulomb_limit() {
    let mu = 0.3;
    let (mut stick, mut slip, mut worst) = (0, 0, 0.0f64);
    let mut first_slip = f64::INFINITY;
    let mut last_stick = 0.0f64;
    press_and_shear(mu, |t, s| {
        let Some(c) = s.contact else { return };
        if t < 0.06 {
            return;
        }
        let ratio = c.tangential_force.abs() / c.normal_force;
        worst = worst.max(ratio);
        if ratio < 0.9 * mu {
            stick += 1;
            last_stick = last_stick.max(t);
        } else if ratio > (1.0 - 1e-9) * mu {
            slip += 1;
            first_slip = first_slip.min(t);
        }
    });
    assert!(
        worst <= mu * (1.0 + 1e-9),
        "friction exceeded the Coulomb limit: {worst}"
    );
    assert!(
        stick > 50 && slip > 50,
        "stick {stick}, slip {slip}, largest ratio {worst}"
    );
    // Stick comes first: the transverse load grows until it reaches the limit.
    assert!(first_slip > 0.07, "slipped at once ({first_slip} s)");
}

#[test]
fn without_friction_the_tip_slides_freely() {
    let mut max_t = 0.0f64;
    let mut contacts = 0;
    press_and_shear(0.0, |t, s| {
        if let Some(c) = s.contact {
            contacts += 1;
            if t > 0.06 {
                max_t = max_t.max(c.tangential_force.abs());
            }
        }
    });
    assert!(contacts > 100);
    assert_eq!(max_t, 0.0);
}

#[test]
fn objects_overlapping_the_whisker_at_the_start_are_refused() {
    let mut sc = Scenario::default();
    sc.objects.push(peg(0.01, 0.0, 0.001, 0.0));
    let e = sim::run(&sc, &mut |_| {}).unwrap_err().to_string();
    assert!(e.contains("objects[0]") && e.contains("overlapping"), "{e}");
    let _ = BaseMotion::default();
}
