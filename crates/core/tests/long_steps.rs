//! Long time steps against objects: a thin plate is not stepped through, and a step too long
//! for a run is refused with one that runs.

use vibrissa_core::dynamics::Integrator;
use vibrissa_core::objects::{Motion, Object, Shape};
use vibrissa_core::scenes::e2_box;
use vibrissa_core::sim::{self, Scenario};

/// A plate `height` thick and 10 mm wide, its top 1 mm below the w30 whisker and its near edge
/// 15 mm from the base, moving up at `speed`; 30 ms at 1 kHz with steps of `dt`.
fn plate(height: f64, speed: f64, dt: f64) -> Scenario {
    Scenario {
        duration: 0.03,
        objects: vec![Object {
            shape: Shape::Box {
                width: 0.01,
                height,
            },
            position: [0.02, -0.001 - 0.5 * height],
            angle: 0.0,
            motion: Motion::Constant {
                velocity: [0.0, speed],
                angular_velocity: 0.0,
            },
            friction: 0.0,
            vertical: None,
        }],
        integrator: Integrator::with_dt(dt),
        ..Scenario::default()
    }
}

/// Samples in contact and the largest base angle of a run.
fn contact_and_peak(out: &sim::Output) -> (usize, f64) {
    let contact = out.rows.iter().filter(|r| r[6] > 0.5).count();
    let peak = out.rows.iter().map(|r| r[1]).fold(f64::MIN, f64::max);
    (contact, peak)
}

#[test]
fn a_plate_thinner_than_a_steps_travel_is_not_stepped_through() {
    // A 20 µm plate at 1.5 m/s travels 75 times its thickness in a 1 ms step, yet the contact
    // (found at the step's evaluation point, with what the relative motion closes in the rest of
    // the step) still catches it and bends the whisker upwards, as at 10 µs.
    let fine = sim::run(&plate(2e-5, 1.5, 1e-5), &mut |_| {}).unwrap();
    let long = sim::run(&plate(2e-5, 1.5, 1e-3), &mut |_| {}).unwrap();
    let (c_fine, p_fine) = contact_and_peak(&fine);
    let (c_long, p_long) = contact_and_peak(&long);
    assert!(
        c_fine >= 10 && c_long >= 5,
        "{c_fine} and {c_long} samples in contact"
    );
    assert!(p_fine > 0.05, "{p_fine}");
    // At 1 ms the impact is coarse (the peak angle about 40% high) but on the right side.
    assert!(
        p_long > 0.8 * p_fine && p_long < 1.6 * p_fine,
        "{p_long} vs {p_fine}"
    );
    // After the plate has passed the whisker lies above it, not below (the plate's top is at
    // -1 mm + 1.5 m/s · t, the whisker's tip well above it while in contact).
    let last = long.rows.iter().rposition(|r| r[6] > 0.5).unwrap();
    let [_, _, _, _, _, _, _, _, cy, _] = long.rows[last];
    let top = -0.001 + 1.5 * long.rows[last][0];
    assert!(
        cy > top - 1e-3,
        "contact at y = {cy} below the plate's top {top}"
    );
}

#[test]
fn a_step_too_long_for_a_run_is_refused_with_one_that_runs() {
    // The e2 box at 30 m/s: a 1 ms step diverges at the impact.
    let scenario = |dt: f64| Scenario {
        duration: 0.01,
        objects: vec![e2_box(0.015, 30.0)],
        integrator: Integrator::with_dt(dt),
        ..Scenario::default()
    };
    let e = sim::run(&scenario(1e-3), &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("diverged") && e.contains("too long"), "{e}");
    // The message names the step to use, as a value that can be set.
    let key = "`--set dt=";
    let at = e
        .find(key)
        .unwrap_or_else(|| panic!("no step named in: {e}"))
        + key.len();
    let works: f64 = e[at..]
        .split('`')
        .next()
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no number after {key} in: {e}"));
    assert!((1e-3 / 64.0..1e-3).contains(&works), "{works}");
    // It runs, and twice it did not (or it is the first halving).
    sim::run(&scenario(works), &mut |_| {}).unwrap();
    if works < 0.5e-3 {
        assert!(sim::run(&scenario(2.0 * works), &mut |_| {}).is_err());
    }
}
