//! Property tests of the stepper on generated whiskers: released from a static deflection with
//! nothing driving it, a whisker's state stays finite and its energy never rises.

use proptest::prelude::*;
use proptest::test_runner::RngSeed;
use vibrissa_core::beam::BeamProfile;
use vibrissa_core::dynamics::{
    initialize, kinetic_energy, potential_energy, step, Inputs, Integrator, PointLoad, State,
    Workspace,
};
use vibrissa_core::whisker::{Damping, Follicle};
use vibrissa_core::{statics, Discretisation, Model, WhiskerParams};

/// Largest rise of the energy allowed, relative to the initial energy. The stepper is not exactly
/// energy-conserving: on a coarse, stiff chain whose highest mode the time step does not resolve
/// it overshoots in the first steps (by 0.1% for 4 segments of a short tapered whisker at
/// 0.13 ms), and on large nonlinear deflections it gains a few 1e-6; an instability grows far
/// beyond 1%.
const TOLERANCE: f64 = 0.01;

/// A whisker drawn from admissible ranges.
fn whisker(
    e: f64,
    rho: f64,
    length: f64,
    tip: f64,
    follicle: Option<f64>,
    ratio: Option<f64>,
) -> WhiskerParams {
    let mut p = WhiskerParams::w30();
    p.youngs_modulus = e;
    p.density = rho;
    p.length = length;
    p.tip_radius = p.base_radius * tip;
    if let Some(k) = follicle {
        p.follicle = Follicle::Spring {
            stiffness: k,
            damping: 0.0,
        };
    }
    p.damping = match ratio {
        Some(r) => Damping::ModalRatio { ratio: r },
        None => Damping::None,
    };
    p
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, rng_seed: RngSeed::Fixed(0x5eed), ..ProptestConfig::default() })]

    #[test]
    fn released_whiskers_stay_finite_and_never_gain_energy(
        e in 0.5e9f64..8e9,
        rho in 500f64..2000.0,
        length in 0.015f64..0.06,
        tip in 0.3f64..1.0,
        follicle in prop::option::of(1e-5f64..1e-2),
        ratio in prop::option::of(0.001f64..0.3),
        segments in 4usize..30,
        rule in 0usize..3,
        dt in 1e-5f64..2e-4,
        load in 0.05f64..2.0,
    ) {
        let p = whisker(e, rho, length, tip, follicle, ratio);
        let w = p.check().expect("an admissible whisker");
        let rule = [Discretisation::Gregory, Discretisation::Trapezoid, Discretisation::Seed][rule];
        let m = Model::new(&w, segments, rule).expect("a chain");
        let l = w.length();
        // A tip load that bends the whisker by up to about its length's worth of slope.
        let f = load * w.ei(0.0) / (l * l);
        let n = m.n;
        let eq = statics::solve(
            &m,
            &[PointLoad { segment: n - 1, along: m.len[n - 1], force: [0.0, f] }],
        );
        prop_assume!(eq.is_ok());
        let eq = eq.unwrap();
        let mut s = State::at_rest(&m, 0);
        s.q_mut().copy_from_slice(&eq.q);
        let mut ws = Workspace::new(&m);
        let inputs = Inputs::default();
        initialize(&m, &mut s, &inputs, &mut ws).expect("initialised");
        let st = Integrator::with_dt(dt).check().expect("a time step");
        let e0 = potential_energy(&m, &s);
        prop_assert!(e0.is_finite() && e0 > 0.0);
        let mut last = e0;
        let steps = (0.02 / dt) as usize;
        for k in 0..steps {
            let r = step(&m, &st, &mut s, &inputs, &mut ws);
            prop_assert!(r.is_ok(), "step {k} failed: {}", r.unwrap_err());
            prop_assert!(s.q().iter().all(|x| x.is_finite()), "non-finite angles at step {k}");
            let energy = potential_energy(&m, &s) + kinetic_energy(&m, &s, &mut ws);
            prop_assert!(energy <= e0 * (1.0 + TOLERANCE), "energy rose to {} e0 at step {k}", energy / e0);
            if ratio.is_some() {
                prop_assert!(energy <= last + TOLERANCE * e0,
                    "damped energy rose at step {k}: {} -> {}", last, energy);
            }
            last = energy;
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, rng_seed: RngSeed::Fixed(0x3a1d), ..ProptestConfig::default() })]

    /// Newton's third law at the base in static equilibrium: a whisker rotated into a fixed peg
    /// and left to settle is held by the base with the force and moment that balance the peg's.
    #[test]
    fn at_rest_against_a_peg_the_base_balances_the_contact_force(
        e in 1e9f64..6e9,
        length in 0.02f64..0.05,
        tip in 0.4f64..1.0,
        follicle in prop::option::of(2e-4f64..1e-2),
        ratio in 0.1f64..0.3,
        segments in 8usize..25,
        at in 0.3f64..0.8,
        peg_radius in 2e-4f64..1e-3,
        push in 0.02f64..0.1,
    ) {
        let p = whisker(e, 1100.0, length, tip, follicle, Some(ratio));
        let w = p.check().expect("an admissible whisker");
        let m = Model::new(&w, segments, Discretisation::Gregory).expect("a chain");
        let l = w.length();
        // A peg above the whisker at arc length `at`·L, 20 µm clear of its surface; the base
        // turns up until the whisker would pass the peg's near side by `push` of its distance.
        let d = at * l;
        let clear = w.radius(d) + peg_radius + 2e-5;
        let objects = [vibrissa_core::scenes::peg(d, clear, peg_radius, 0.0)];
        let angle = (clear / d) * (1.0 + push);
        let drive = vibrissa_core::sim::BaseDrive::Ramp {
            rate: 1.0,
            start: 0.0,
            stop: angle,
            smoothing: 0.2 * angle,
        };
        let st = Integrator::with_dt(1e-4).check().expect("a time step");
        let mut s = State::at_rest(&m, 0);
        let mut ws = Workspace::new(&m);
        // Settle for ten first-mode time constants after the base stops, clamped (no follicle
        // spring) or not.
        let f1 = m.modes().expect("modes").frequencies[0];
        let settle = angle + 10.0 / (ratio * 2.0 * std::f64::consts::PI * f1);
        let steps = (settle.min(2.0) / st.dt) as usize;
        for k in 1..=steps {
            let inputs = Inputs {
                base: drive.at(k as f64 * st.dt),
                objects: &objects,
                ..Default::default()
            };
            let r = step(&m, &st, &mut s, &inputs, &mut ws);
            prop_assert!(r.is_ok(), "step {k} failed: {}", r.unwrap_err());
        }
        let c = s.contact;
        prop_assert!(c.is_some(), "no contact at rest (peg at {d} m, base at {angle} rad)");
        let c = c.unwrap();
        let f = c.force;
        let size = f[0].hypot(f[1]);
        prop_assert!(size > 0.0);
        let [m0, fx, fy] = s.base_wrench;
        // The base joint is at the origin.
        let moment = c.point[0] * f[1] - c.point[1] * f[0];
        prop_assert!((fx + f[0]).abs() <= 1e-3 * size, "fx {fx} vs contact {}", f[0]);
        prop_assert!((fy + f[1]).abs() <= 1e-3 * size, "fy {fy} vs contact {}", f[1]);
        prop_assert!((m0 + moment).abs() <= 1e-3 * size * d, "moment {m0} vs contact {moment}");
    }
}
