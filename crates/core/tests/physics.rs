//! The chain against beam theory and Newton's laws.

use vibrissa_core::beam::{self, BeamProfile};
use vibrissa_core::dynamics::{
    initialize, kinetic_energy, momentum, potential_energy, step, BaseMotion, Inputs, Integrator,
    PointLoad, State, Workspace,
};
use vibrissa_core::sensors::Sensors;
use vibrissa_core::whisker::{Damping, Follicle};
use vibrissa_core::{batch, statics, validate, Discretisation, Error, Model, WhiskerParams};

fn w30() -> vibrissa_core::Whisker {
    WhiskerParams::w30().check().unwrap()
}

fn w30_undamped() -> vibrissa_core::Whisker {
    let mut p = WhiskerParams::w30();
    p.damping = Damping::None;
    p.check().unwrap()
}

fn tip_load(model: &Model, f: [f64; 2]) -> PointLoad {
    let n = model.n;
    PointLoad {
        segment: n - 1,
        along: model.len[n - 1],
        force: f,
    }
}

#[test]
fn static_tip_load_matches_the_cubic_and_the_seed_rule_does_not() {
    let w = w30();
    let (l, ei) = (w.length(), w.ei(0.0));
    let load = beam::load_for_tip_deflection(ei, l, l, 0.01 * l);
    let reference = beam::PointLoadCubic { ei, w: load, c: l }.deflection(l);
    let err = |d| {
        let m = Model::new(&w, 20, d).unwrap();
        let eq = statics::solve(&m, &[tip_load(&m, [0.0, load])]).unwrap();
        eq.nodes[20][1] / reference - 1.0
    };
    let (gregory, seed) = (err(Discretisation::Gregory), err(Discretisation::Seed));
    assert!(gregory.abs() < 5e-4, "gregory {gregory}");
    // The seed rule's half-segment of extra base compliance: (N+1)(2N+1)/(2N²) - 1 = 7.6%.
    assert!((seed - 0.0763).abs() < 0.002, "seed {seed}");
}

#[test]
fn load_at_mid_length_matches_the_cubic() {
    let w = w30();
    let (l, ei) = (w.length(), w.ei(0.0));
    let c = 0.5 * l;
    let load = beam::load_for_tip_deflection(ei, l, c, 0.01 * l);
    let cubic = beam::PointLoadCubic { ei, w: load, c };
    let m = Model::new(&w, 20, Discretisation::Gregory).unwrap();
    let (segment, along) = m.locate(c).unwrap();
    let eq = statics::solve(
        &m,
        &[PointLoad {
            segment,
            along,
            force: [0.0, load],
        }],
    )
    .unwrap();
    // Shape within 1% of the tip deflection at every node.
    for (i, p) in eq.nodes.iter().enumerate() {
        let x = i as f64 * l / 20.0;
        assert!(
            (p[1] - cubic.deflection(x)).abs() < 0.01 * cubic.deflection(l),
            "node {i}"
        );
    }
    // Base moment balances the load.
    assert!((eq.base_wrench[0] / (-load * eq.nodes[10][0]) - 1.0).abs() < 1e-12);
}

#[test]
fn large_deflection_matches_the_elastica() {
    let w = w30();
    let (l, ei) = (w.length(), w.ei(0.0));
    for alpha in [1.0, 10.0] {
        let f = [0.0, alpha * ei / (l * l)];
        let tip = beam::elastica(&w, f, l).unwrap().tip();
        let m = Model::new(&w, 20, Discretisation::Gregory).unwrap();
        let eq = statics::solve(&m, &[tip_load(&m, f)]).unwrap();
        let d = (eq.nodes[20][0] - tip[0]).hypot(eq.nodes[20][1] - tip[1]) / l;
        assert!(d < 0.005, "alpha {alpha}: {d}");
    }
}

#[test]
fn damped_dynamics_settles_to_the_static_solution_with_balanced_base_reaction() {
    let w = w30();
    let m = Model::new(&w, 10, Discretisation::Gregory).unwrap();
    let f = [-1e-4, 3e-4];
    let loads = [PointLoad {
        segment: 6,
        along: 0.5 * m.len[6],
        force: f,
    }];
    let eq = statics::solve(&m, &loads).unwrap();
    let st = Integrator::with_dt(2e-4).check().unwrap();
    let mut s = State::at_rest(&m, 0);
    let mut ws = Workspace::new(&m);
    let inputs = Inputs {
        loads: &loads,
        ..Default::default()
    };
    for _ in 0..15_000 {
        step(&m, &st, &mut s, &inputs, &mut ws).unwrap();
    }
    for (a, b) in s.q().iter().zip(&eq.q) {
        assert!((a - b).abs() < 1e-9, "{a} vs {b}");
    }
    for k in 0..3 {
        let scale = eq.base_wrench[k].abs().max(1e-12);
        assert!(
            (s.base_wrench[k] - eq.base_wrench[k]).abs() < 1e-7 * scale.max(3e-4),
            "component {k}"
        );
    }
}

#[test]
fn natural_frequencies_converge_at_least_as_one_over_n_squared() {
    let w = w30_undamped();
    let r = beam::clamped_free_uniform(w.ei(0.0), w.rho_a(0.0), w.length(), 3);
    let errs = |n| {
        let f = Model::new(&w, n, Discretisation::Gregory)
            .unwrap()
            .modes()
            .unwrap()
            .frequencies;
        [f[0] / r[0] - 1.0, f[1] / r[1] - 1.0, f[2] / r[2] - 1.0]
    };
    let (e10, e20) = (errs(10), errs(20));
    for k in 0..3 {
        assert!(e20[k].abs() < 0.005, "f{} at N=20: {}", k + 1, e20[k]);
        assert!(
            e10[k].abs() / e20[k].abs() > 4.0,
            "f{}: {} -> {}",
            k + 1,
            e10[k],
            e20[k]
        );
    }
}

/// Frequency of free vibration from the state's first joint angle.
fn simulated_f1(model: &Model, dt: f64, periods: f64, f_ref: f64) -> f64 {
    let shape = &model.modes().unwrap().shapes[0];
    let scale = 1e-4 / shape[0].abs();
    let mut s = State::at_rest(model, 0);
    for (q, x) in s.q_mut().iter_mut().zip(shape) {
        *q += scale * x;
    }
    let mut ws = Workspace::new(model);
    let inputs = Inputs::default();
    initialize(model, &mut s, &inputs, &mut ws).unwrap();
    let st = Integrator::with_dt(dt).check().unwrap();
    let (mut t, mut y) = (vec![], vec![]);
    for _ in 0..(periods / f_ref / dt) as usize {
        step(model, &st, &mut s, &inputs, &mut ws).unwrap();
        t.push(s.t);
        y.push(s.q()[0] - model.rest[0]);
    }
    validate::crossing_frequency(&t, &y).unwrap()
}

#[test]
fn simulated_first_frequency_matches_the_beam() {
    let w = w30_undamped();
    let f1 = beam::clamped_free_uniform(w.ei(0.0), w.rho_a(0.0), w.length(), 1)[0];
    let m = Model::new(&w, 20, Discretisation::Gregory).unwrap();
    let f = simulated_f1(&m, 2e-5, 20.0, f1);
    assert!((f / f1 - 1.0).abs() < 0.002, "{f} vs {f1}");
    // At the large step of 0.5 ms the period error stays within 1%.
    let f = simulated_f1(&m, 5e-4, 20.0, f1);
    assert!((f / f1 - 1.0).abs() < 0.01, "{f} vs {f1}");
}

#[test]
fn tapered_whisker_first_frequency_matches_the_finite_element_reference() {
    let mut p = WhiskerParams::robot();
    p.damping = Damping::None;
    let w = p.check().unwrap();
    let reference = beam::clamped_free_tapered(&w, 1).unwrap()[0];
    let m = Model::new(&w, 20, Discretisation::Gregory).unwrap();
    let f = m.modes().unwrap().frequencies[0];
    assert!((f / reference - 1.0).abs() < 0.01, "{f} vs {reference}");
}

#[test]
fn undamped_energy_is_conserved_and_damped_energy_never_rises() {
    for (damping, undamped) in [
        (Damping::None, true),
        (Damping::ModalRatio { ratio: 0.05 }, false),
    ] {
        let mut p = WhiskerParams::w30();
        p.damping = damping;
        let w = p.check().unwrap();
        let l = w.length();
        let m = Model::new(&w, 20, Discretisation::Gregory).unwrap();
        let eq = statics::solve(&m, &[tip_load(&m, [0.0, w.ei(0.0) / (l * l)])]).unwrap();
        let mut s = State::at_rest(&m, 0);
        s.q_mut().copy_from_slice(&eq.q);
        let mut ws = Workspace::new(&m);
        let inputs = Inputs::default();
        initialize(&m, &mut s, &inputs, &mut ws).unwrap();
        let st = Integrator::with_dt(1e-4).check().unwrap();
        let e0 = potential_energy(&m, &s);
        let mut last = e0;
        for _ in 0..5_000 {
            step(&m, &st, &mut s, &inputs, &mut ws).unwrap();
            let e = potential_energy(&m, &s) + kinetic_energy(&m, &s, &mut ws);
            assert!(e <= e0 * (1.0 + 1e-6), "energy rose to {}", e / e0);
            if !undamped {
                assert!(e <= last * (1.0 + 1e-9) + 1e-18, "damped energy rose");
            }
            last = e;
        }
        if undamped {
            assert!(last / e0 > 0.995, "undamped energy fell to {}", last / e0);
        } else {
            assert!(last / e0 < 1e-3, "damped energy only fell to {}", last / e0);
        }
    }
}

#[test]
fn base_reaction_is_the_rate_of_change_of_momentum() {
    // Released from a large deflection with no other force acting: the base wrench must equal
    // dP/dt (the method balances forces at t_n + (1-αf)·h; interpolate to mid-step).
    let w = w30_undamped();
    let l = w.length();
    let m = Model::new(&w, 10, Discretisation::Gregory).unwrap();
    let eq = statics::solve(&m, &[tip_load(&m, [0.0, 2.0 * w.ei(0.0) / (l * l)])]).unwrap();
    let mut s = State::at_rest(&m, 0);
    s.q_mut().copy_from_slice(&eq.q);
    let mut ws = Workspace::new(&m);
    initialize(&m, &mut s, &Inputs::default(), &mut ws).unwrap();
    let st = Integrator::with_dt(1e-6).check().unwrap();
    let af = st.alpha_f();
    let (mut p0, mut w0) = (momentum(&m, &s, &mut ws), s.base_wrench_intermediate());
    let (mut worst, mut scale) = (0.0f64, 0.0f64);
    for _ in 0..5_000 {
        step(&m, &st, &mut s, &Inputs::default(), &mut ws).unwrap();
        let (p1, w1) = (momentum(&m, &s, &mut ws), s.base_wrench_intermediate());
        for c in 1..3 {
            let wm = w0[c] + (0.5 + af) * (w1[c] - w0[c]);
            worst = worst.max(((p1[c] - p0[c]) / st.dt - wm).abs());
            scale = scale.max(wm.abs());
        }
        (p0, w0) = (p1, w1);
    }
    assert!(worst < 1e-3 * scale, "{worst} vs {scale}");
}

#[test]
fn sensors_are_expressed_in_the_rotated_base_frame() {
    // The same load problem solved with the base turned by psi reads the same sensors.
    let w = w30();
    let m = Model::new(&w, 10, Discretisation::Gregory).unwrap();
    let st = Integrator::with_dt(2e-4).check().unwrap();
    let f_body = [-2e-5, 1e-4];
    let read = |psi: f64| {
        let (s, c) = psi.sin_cos();
        let f = [c * f_body[0] - s * f_body[1], s * f_body[0] + c * f_body[1]];
        let loads = [tip_load(&m, f)];
        let base = BaseMotion {
            angle: psi,
            rate: 0.0,
            accel: 0.0,
        };
        let inputs = Inputs {
            base,
            loads: &loads,
            ..Default::default()
        };
        let mut state = State::at_rest(&m, 0);
        state.base = base;
        let mut ws = Workspace::new(&m);
        for _ in 0..15_000 {
            step(&m, &st, &mut state, &inputs, &mut ws).unwrap();
        }
        Sensors::read(&state).to_array()
    };
    let (a, b) = (read(0.0), read(0.7));
    for k in 0..5 {
        assert!(
            (a[k] - b[k]).abs() <= 1e-7 * a[k].abs().max(1e-6),
            "channel {k}: {} vs {}",
            a[k],
            b[k]
        );
    }
    // Static balance: the base pushes back against the load.
    assert!((a[3] + f_body[0]).abs() < 1e-9 && (a[4] + f_body[1]).abs() < 1e-9);
}

#[test]
fn whisking_base_moment_is_the_inertia_times_the_acceleration() {
    // A stiffly damped whisker swung with a constant angular acceleration from rest: once the
    // start-up transient has died, m0 = I_base·ψ̈ (a straight radial whisker feels no moment
    // from the centripetal force).
    let mut p = WhiskerParams::w30();
    p.damping = Damping::ModalRatio { ratio: 0.7 };
    let w = p.check().unwrap();
    let m = Model::new(&w, 20, Discretisation::Gregory).unwrap();
    let i_base: f64 = (0..20)
        .map(|i| {
            let c = m.com[i][0] + i as f64 * m.len[i];
            m.inertia[i] + m.mass[i] * c * c
        })
        .sum();
    let accel = 20.0;
    let st = Integrator::with_dt(1e-4).check().unwrap();
    let mut s = State::at_rest(&m, 0);
    let mut ws = Workspace::new(&m);
    for _ in 0..500 {
        let t = s.t + st.dt;
        let base = BaseMotion {
            angle: 0.5 * accel * t * t,
            rate: accel * t,
            accel,
        };
        step(
            &m,
            &st,
            &mut s,
            &Inputs {
                base,
                ..Default::default()
            },
            &mut ws,
        )
        .unwrap();
    }
    let m0 = Sensors::read(&s).m0;
    assert!(
        (m0 / (i_base * accel) - 1.0).abs() < 0.01,
        "{m0} vs {}",
        i_base * accel
    );
}

#[test]
fn compliant_follicle_adds_its_series_compliance() {
    let mut p = WhiskerParams::w30();
    let (l, ei) = (p.length, 2.3562e-7);
    let kf = 50.0 * ei / l;
    p.follicle = Follicle::Spring {
        stiffness: kf,
        damping: 0.0,
    };
    let soft = Model::new(&p.check().unwrap(), 20, Discretisation::Gregory).unwrap();
    let stiff = Model::new(&w30(), 20, Discretisation::Gregory).unwrap();
    let load = 1e-3 * ei / (l * l);
    let y = |m: &Model| {
        statics::solve(m, &[tip_load(m, [0.0, load])])
            .unwrap()
            .nodes[20][1]
    };
    let extra = y(&soft) - y(&stiff);
    // Rigid rotation of the whole whisker by W·L/k_f moves the tip by W·L²/k_f.
    assert!((extra / (load * l * l / kf) - 1.0).abs() < 1e-3, "{extra}");
}

/// The follicle's damper as the joint-0 damper of the lumped chain: a spring k_f and a damper
/// c_f side by side, in series with the whisker's own base compliance 1/k0, have the complex
/// stiffness K(ω) = 1/(1/k0 + 1/(k_f + iωc_f)); its damping Im K/ω at low frequency.
fn series_damping(k0: f64, kf: f64, cf: f64, omega: f64) -> f64 {
    let d = kf * kf + omega * omega * cf * cf;
    let (a, b) = (1.0 / k0 + kf / d, omega * cf / d); // 1/K = a − ib
    b / (omega * (a * a + b * b))
}

#[test]
fn a_follicle_damper_acts_through_the_series_and_a_stiff_follicle_is_clamped() {
    let clamped = Model::new(&w30_undamped(), 20, Discretisation::Gregory).unwrap();
    let k0 = clamped.stiffness[0];
    let tau = 1e-3;
    for ratio in [0.01, 0.1, 1.0, 10.0, 100.0] {
        let kf = ratio * k0;
        let mut p = WhiskerParams::w30();
        p.damping = Damping::None;
        p.follicle = Follicle::Spring {
            stiffness: kf,
            damping: kf * tau,
        };
        let m = Model::new(&p.check().unwrap(), 20, Discretisation::Gregory).unwrap();
        let exact = series_damping(k0, kf, kf * tau, 1e-4 / tau);
        assert!(
            (m.damping[0] / exact - 1.0).abs() < 1e-6,
            "k_f = {ratio}·k0: joint-0 damper {} against {exact}",
            m.damping[0]
        );
    }

    // An e2 strike with a follicle 10⁴ times stiffer than the base joint, damped with the same
    // time constant, is the clamped strike.
    let strike = |follicle: Follicle| {
        let mut sc = vibrissa_core::sim::Scenario {
            objects: vec![vibrissa_core::scenes::e2_box(0.022, 0.9)],
            ..vibrissa_core::sim::Scenario::default()
        };
        sc.whisker.follicle = follicle;
        vibrissa_core::sim::run(&sc, &mut |_| {}).unwrap().rows
    };
    let kf = 1e4 * k0;
    let (a, b) = (
        strike(Follicle::Clamped),
        strike(Follicle::Spring {
            stiffness: kf,
            damping: kf * tau,
        }),
    );
    for k in 1..6 {
        let (lo, hi) = a
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), r| {
                (l.min(r[k]), h.max(r[k]))
            });
        let rms = (a
            .iter()
            .zip(&b)
            .map(|(x, y)| (x[k] - y[k]).powi(2))
            .sum::<f64>()
            / a.len() as f64)
            .sqrt();
        assert!(
            rms < 1e-3 * (hi - lo),
            "channel {k}: RMS {rms} of range {}",
            hi - lo
        );
    }
}

#[test]
fn seeded_noise_gives_the_same_bits_on_one_and_two_threads() {
    let w = w30();
    let m = Model::new(&w, 20, Discretisation::Gregory).unwrap();
    let st = Integrator::with_dt(1e-4).check().unwrap();
    let inputs = Inputs {
        noise: 1e-5,
        ..Default::default()
    };
    let run = |threads: usize| {
        let mut states: Vec<State> = (0..16).map(|k| State::at_rest(&m, 100 + k)).collect();
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| batch::step_all(&m, &st, &mut states, &inputs, 300))
            .unwrap();
        states
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(a, b);
    // The noise did move the whisker, and different seeds differ.
    assert!(a[0].q()[0] != m.rest[0]);
    assert_ne!(a[0].q(), a[1].q());
    // Batched stepping equals stepping one state alone.
    let mut alone = State::at_rest(&m, 100);
    let mut ws = Workspace::new(&m);
    for _ in 0..300 {
        step(&m, &st, &mut alone, &inputs, &mut ws).unwrap();
    }
    assert_eq!(alone, a[0]);
}

#[test]
fn divergence_is_reported_with_time_and_place() {
    // A load far beyond anything a whisker survives folds the chain; the step says when and where.
    let w = w30();
    let m = Model::new(&w, 10, Discretisation::Gregory).unwrap();
    let loads = [tip_load(&m, [0.0, 1e3])];
    let st = Integrator::with_dt(1e-4).check().unwrap();
    let mut s = State::at_rest(&m, 0);
    let mut ws = Workspace::new(&m);
    let inputs = Inputs {
        loads: &loads,
        ..Default::default()
    };
    let err = (0..10_000)
        .find_map(|_| step(&m, &st, &mut s, &inputs, &mut ws).err())
        .unwrap();
    match &err {
        Error::Diverged { t, detail } => {
            assert!(*t > 0.0 && detail.contains("joint"), "{err}");
        }
        other => panic!("unexpected {other}"),
    }
}

#[test]
fn bad_parameters_name_the_field_and_range() {
    let w = w30();
    for n in [0, 1, 201] {
        let e = Model::new(&w, n, Discretisation::Gregory)
            .unwrap_err()
            .to_string();
        assert!(e.contains("segments") && e.contains("2 to 200"), "{e}");
    }
    for dt in [0.0, -1e-4, 2e-3, f64::NAN, f64::INFINITY] {
        let e = Integrator::with_dt(dt).check().unwrap_err().to_string();
        assert!(e.contains("dt") && e.contains("0.001"), "{e}");
    }
    let e = Integrator {
        rho_inf: 0.2,
        ..Default::default()
    }
    .check()
    .unwrap_err()
    .to_string();
    assert!(e.contains("rho_inf"), "{e}");
    assert!(Discretisation::from_name("fancy")
        .unwrap_err()
        .to_string()
        .contains("gregory"));
    // A load with a non-finite force or on a missing segment is refused before stepping.
    let m = Model::new(&w, 10, Discretisation::Gregory).unwrap();
    let st = Integrator::default().check().unwrap();
    let mut s = State::at_rest(&m, 0);
    let mut ws = Workspace::new(&m);
    for (load, field) in [
        (
            PointLoad {
                segment: 3,
                along: 0.0,
                force: [f64::NAN, 0.0],
            },
            "loads[0].force",
        ),
        (
            PointLoad {
                segment: 10,
                along: 0.0,
                force: [0.0, 0.0],
            },
            "loads[0].segment",
        ),
        (
            PointLoad {
                segment: 2,
                along: 1.0,
                force: [0.0, 0.0],
            },
            "loads[0].along",
        ),
    ] {
        let loads = [load];
        let inputs = Inputs {
            loads: &loads,
            ..Default::default()
        };
        let e = step(&m, &st, &mut s, &inputs, &mut ws)
            .unwrap_err()
            .to_string();
        assert!(e.contains(field), "{e}");
    }
    assert_eq!(s.t, 0.0, "a refused step must not advance the state");
}

/// The deflection at arc length `x` of a straight beam under a unit force there, square to it,
/// by Simpson's rule over 4000 intervals (independent of the library's quadrature).
fn beam_deflection_per_newton(w: &vibrissa_core::Whisker, x: f64) -> f64 {
    let m = 4000;
    let h = x / m as f64;
    let f = |s: f64| (x - s).powi(2) / w.ei(s);
    let inner: f64 = (1..m)
        .map(|k| if k % 2 == 1 { 4.0 } else { 2.0 } * f(k as f64 * h))
        .sum();
    (f(0.0) + inner + f(x)) * h / 3.0
}

/// Deflection of the chain at arc length `x` under a small force there, per newton (statics, a
/// load small enough to keep the response linear to 1e-6).
fn chain_deflection_per_newton(m: &Model, x: f64) -> f64 {
    let (segment, along) = m.locate(x).unwrap();
    let force = 1e-7;
    let eq = statics::solve(
        m,
        &[PointLoad {
            segment,
            along,
            force: [0.0, force],
        }],
    )
    .unwrap();
    // The load point on its rigid segment, between the segment's nodes.
    let u = along / m.len[segment];
    let (a, b) = (eq.nodes[segment][1], eq.nodes[segment + 1][1]);
    (a + u * (b - a)) / force
}

#[test]
fn the_nodal_rule_deflects_as_the_beam_at_every_node_whatever_the_taper() {
    // The rule by its name, as scenario files give it.
    assert_eq!(
        Discretisation::from_name("nodal").unwrap(),
        Discretisation::Nodal
    );
    let mut tapered = WhiskerParams::w30();
    tapered.tip_radius = 0.5 * tapered.base_radius;
    let mut quarter = WhiskerParams::w30();
    quarter.tip_radius = 0.25 * quarter.base_radius;
    for params in [WhiskerParams::w30(), tapered, quarter] {
        let w = params.check().unwrap();
        let l = w.length();
        for n in [3, 5, 8, 16] {
            let m = Model::new(&w, n, Discretisation::Nodal).unwrap();
            assert!(m.stiffness.iter().all(|k| k.is_finite() && *k > 0.0));
            for i in 1..=n {
                let x = i as f64 * l / n as f64;
                let (chain, beam) = (
                    chain_deflection_per_newton(&m, x.min(l)),
                    beam_deflection_per_newton(&w, x),
                );
                assert!(
                    (chain / beam - 1.0).abs() < 1e-5,
                    "tip {:e} m, N = {n}, node {i}: {chain:e} vs {beam:e}",
                    params.tip_radius
                );
            }
        }
        // A uniform whisker's nodes against the closed form x³/3EI.
        if params.tip_radius == params.base_radius {
            let m = Model::new(&w, 5, Discretisation::Nodal).unwrap();
            let x = 0.6 * l;
            let cubic = x.powi(3) / (3.0 * w.ei(0.0));
            assert!((chain_deflection_per_newton(&m, x) / cubic - 1.0).abs() < 1e-5);
        }
    }
}

#[test]
fn between_nodes_a_coarse_nodal_chain_follows_a_tapered_whisker_where_hat_weights_do_not() {
    let mut p = WhiskerParams::w30();
    p.tip_radius = 0.5 * p.base_radius;
    let w = p.check().unwrap();
    let l = w.length();
    // The largest relative error of the deflection under a force anywhere along the outer two
    // thirds, at 8 segments.
    let worst = |d: Discretisation| {
        let m = Model::new(&w, 8, d).unwrap();
        (0..60)
            .map(|k| {
                let x = l * (1.0 + 2.0 * (k + 1) as f64 / 60.0) / 3.0;
                (chain_deflection_per_newton(&m, x) / beam_deflection_per_newton(&w, x) - 1.0).abs()
            })
            .fold(0.0, f64::max)
    };
    let (nodal, gregory) = (worst(Discretisation::Nodal), worst(Discretisation::Gregory));
    assert!(nodal < 0.01, "nodal {nodal}");
    assert!(gregory > 0.04, "gregory {gregory}");
}

#[test]
fn a_coarse_nodal_chain_rings_at_the_whisker_s_first_two_frequencies() {
    // Against a 100-segment chain (within 0.01% of the beam's first two modes), tapered whiskers
    // cut into 5 and 8 segments: the nodal rule within 1.5% at 5 and 0.3% at 8 (the hat weights
    // up to 9% off at 5).
    for ratio in [1.0, 0.5, 0.25] {
        let mut p = WhiskerParams::w30();
        p.tip_radius = ratio * p.base_radius;
        let w = p.check().unwrap();
        let fine = Model::new(&w, 100, Discretisation::Gregory).unwrap();
        let f = fine.modes().unwrap().frequencies;
        for n in [5, 8] {
            let m = Model::new(&w, n, Discretisation::Nodal).unwrap();
            let g = m.modes().unwrap().frequencies;
            for k in 0..2 {
                let tolerance = if n == 5 { 0.015 } else { 0.003 };
                assert!(
                    (g[k] / f[k] - 1.0).abs() < tolerance,
                    "taper {ratio}, N = {n}, mode {}: {} vs {} Hz",
                    k + 1,
                    g[k],
                    f[k]
                );
            }
        }
    }
}
