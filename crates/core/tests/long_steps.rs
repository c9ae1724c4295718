//! Long time steps against objects: a step at which a thin plate would pass within one contact
//! step is refused with the steps that resolve it, and a step too long for a run is refused with
//! one that runs.

use vibrissa_core::dynamics::Integrator;
use vibrissa_core::objects::{Motion, Object, Shape, Vertical};
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
fn a_plate_thinner_than_a_steps_travel_is_refused_with_the_step_that_resolves_it() {
    // A 20 µm plate at 1.5 m/s travels 75 times its thickness in a 1 ms step: contact with it
    // would last less than a step. The step is refused, naming the largest that resolves it
    // (20 µm / 1.5 m/s = 13.3 µs) and the contact substeps that would do at 1 ms.
    let e = sim::run(&plate(2e-5, 1.5, 1e-3), &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("dt") && e.contains("objects[0]") && e.contains("0.020 mm"),
        "{e}"
    );
    assert!(e.contains("1.333e-5 s"), "{e}");
    assert!(e.contains("contact_substeps = 75"), "{e}");
    // Either remedy runs, and the plate is caught as at 10 µs: it bends the whisker upwards.
    let fine = sim::run(&plate(2e-5, 1.5, 1e-5), &mut |_| {}).unwrap();
    let mut sub = plate(2e-5, 1.5, 1e-3);
    sub.integrator.contact_substeps = 75;
    let sub = sim::run(&sub, &mut |_| {}).unwrap();
    let largest = sim::run(&plate(2e-5, 1.5, 1.333e-5), &mut |_| {}).unwrap();
    let (c_fine, p_fine) = contact_and_peak(&fine);
    assert!(
        c_fine >= 10 && p_fine > 0.05,
        "{c_fine} samples, peak {p_fine}"
    );
    for (name, out) in [("substeps", &sub), ("largest dt", &largest)] {
        let (c, p) = contact_and_peak(out);
        assert!(c >= 10, "{name}: {c} samples in contact");
        assert!(
            (p - p_fine).abs() < 0.1 * p_fine,
            "{name}: peak {p} vs {p_fine}"
        );
        // After the plate has passed the whisker lies above it, not below (the plate's top is
        // at -1 mm + 1.5 m/s · t).
        let last = out.rows.iter().rposition(|r| r[6] > 0.5).unwrap();
        let cy = out.rows[last][8];
        let top = -0.001 + 1.5 * out.rows[last][0];
        assert!(
            cy > top - 1e-3,
            "{name}: contact at y = {cy} below the plate's top {top}"
        );
    }
    // A thicker plate at the same speed and step is resolved and runs.
    sim::run(&plate(2e-3, 1.5, 1e-3), &mut |_| {}).unwrap();
}

#[test]
fn a_step_too_long_for_a_run_is_refused_with_one_that_runs() {
    // A 40 mm block, its near edge 15 mm from the base and its top 1 mm below the whisker, at
    // 30 m/s: 30 mm per 1 ms step, within its size, so the step is not refused for the block
    // passing unresolved; it diverges at the impact.
    let scenario = |dt: f64| Scenario {
        duration: 0.01,
        objects: vec![Object {
            shape: Shape::Box {
                width: 0.04,
                height: 0.04,
            },
            position: [0.035, -0.021],
            angle: 0.0,
            motion: Motion::Constant {
                velocity: [0.0, 30.0],
                angular_velocity: 0.0,
            },
            friction: 0.0,
            vertical: None,
        }],
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

#[test]
fn an_object_that_crosses_the_plane_within_a_step_is_refused() {
    // A plate 1 mm tall (z from -0.5 to 0.5 mm) lifting at 2 m/s crosses the whisker's plane
    // in 0.5 ms: a 1 ms step could skip it.
    let lifting = |dt: f64| {
        let mut s = plate(2e-3, 0.0, dt);
        s.objects[0].vertical = Some(Vertical {
            bottom: -5e-4,
            top: 5e-4,
            velocity: 2.0,
        });
        s
    };
    let e = sim::run(&lifting(1e-3), &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("dt") && e.contains("1.000 mm tall"), "{e}");
    assert!(e.contains("5.000e-4 s"), "{e}");
    sim::run(&lifting(5e-4), &mut |_| {}).unwrap();
}

#[test]
fn a_thin_peg_whisked_against_counts_the_sweep_of_the_whisker_s_tip() {
    // A peg 0.6 mm across at rest, 20 mm out, and the w30 whisker (30 mm) whisked at 0.5 rad and
    // 8 Hz: its tip sweeps at up to 0.5 · 2π · 8 · 0.03 = 0.754 m/s, 0.754 mm per 1 ms step.
    let whisked = |dt: f64| Scenario {
        duration: 0.05,
        objects: vec![Object {
            shape: Shape::Circle { radius: 3e-4 },
            position: [0.02, 0.004],
            angle: 0.0,
            motion: Motion::default(),
            friction: 0.0,
            vertical: None,
        }],
        base: sim::BaseDrive::Sinusoid {
            amplitude: 0.5,
            frequency: 8.0,
            phase: 0.0,
            offset: 0.0,
        },
        integrator: Integrator::with_dt(dt),
        ..Scenario::default()
    };
    let e = sim::run(&whisked(1e-3), &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("0.600 mm across") && e.contains("whisker's tip") && e.contains("0.754 m/s"),
        "{e}"
    );
    // The largest step it names: 0.6 mm at 0.754 m/s, 0.796 ms.
    assert!(e.contains("7.958e-4 s"), "{e}");
    sim::run(&whisked(7.9e-4), &mut |_| {}).unwrap();
}
