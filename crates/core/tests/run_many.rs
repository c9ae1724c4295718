//! Runs stepped together in lanes (`sim::run_together`, and `sim::run_many` on all cores) give each run's output alone (`sim::run`),
//! bit for bit, and its error when it fails.

use vibrissa_core::objects::Vertical;
use vibrissa_core::scenes::e2_box;
use vibrissa_core::sim::{self, BaseDrive, Scenario, SensorNoise, SensorResponse};
use vibrissa_core::Integrator;

/// The `e2` box run at (d, v), seeded by `seed`.
fn e2(d: f64, v: f64, seed: u64) -> Scenario {
    Scenario {
        objects: vec![e2_box(d, v)],
        seed,
        ..Scenario::default()
    }
}

/// The same as `e2`, with random forces and sensor noise (each run its own sensor gains).
fn noisy(d: f64, v: f64, seed: u64) -> Scenario {
    let mut s = e2(d, v, seed);
    s.process_noise = 2e-5;
    s.sensor_noise = SensorNoise {
        theta01: 1e-3,
        theta12: 2e-3,
        m0: 1e-7,
        fx: 1e-5,
        fy: 1e-5,
    };
    let mut r = SensorResponse::default();
    r.theta12.gain = 1.0 + 0.01 * seed as f64;
    s.sensor_response = r;
    s
}

/// Asserts that every run of `scenarios` comes out of `run_many` as out of `run`.
fn same_as_alone(scenarios: &[Scenario]) {
    let many = sim::run_many(scenarios);
    let together = sim::run_together(scenarios);
    assert_eq!(many.len(), scenarios.len());
    assert_eq!(together.len(), scenarios.len());
    for (k, (s, got)) in scenarios
        .iter()
        .zip(together)
        .chain(scenarios.iter().zip(many))
        .enumerate()
    {
        let alone = sim::run(s, &mut |_| {});
        match (alone, got) {
            (Ok(a), Ok(b)) => {
                assert_eq!(a.steps, b.steps, "run {k}: steps");
                assert_eq!(a.dt.to_bits(), b.dt.to_bits(), "run {k}: dt");
                assert_eq!(
                    a.max_penetration.to_bits(),
                    b.max_penetration.to_bits(),
                    "run {k}: penetration"
                );
                assert_eq!(a.rows.len(), b.rows.len(), "run {k}: rows");
                for (i, (ra, rb)) in a.rows.iter().zip(&b.rows).enumerate() {
                    for c in 0..10 {
                        // NaN (no contact point) compares by its bits too.
                        assert_eq!(ra[c].to_bits(), rb[c].to_bits(), "run {k} row {i} col {c}");
                    }
                }
            }
            (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string(), "run {k}"),
            (a, b) => panic!("run {k}: alone {:?}, together {:?}", a.is_ok(), b.is_ok()),
        }
    }
}

#[test]
fn clean_and_noisy_box_runs_are_those_run_alone() {
    let mut runs = Vec::new();
    for (k, d) in [0.016, 0.02, 0.024, 0.028, 0.0295].iter().enumerate() {
        for (j, v) in [0.3, 0.9, 1.5].iter().enumerate() {
            let seed = (3 * k + j) as u64;
            runs.push(e2(*d, *v, seed));
            runs.push(noisy(*d, *v, seed));
        }
    }
    same_as_alone(&runs);
}

#[test]
fn whisked_lifted_and_mixed_runs_are_those_run_alone() {
    let whisk = BaseDrive::Sinusoid {
        amplitude: 0.3,
        frequency: 8.0,
        phase: 0.0,
        offset: 0.0,
    };
    let mut runs = Vec::new();
    for k in 0..6 {
        let mut s = noisy(0.018 + 0.002 * k as f64, 0.6, k);
        s.base = whisk.clone();
        s.duration = 0.1;
        runs.push(s);
    }
    // A box lifted out of the plane in contact (plucking), and one lowered into it once past.
    for (k, (bottom, top, velocity)) in [(-0.005, 0.01, 0.8), (0.015, 0.03, -0.5)]
        .into_iter()
        .enumerate()
    {
        let mut s = e2(0.02, 0.9, 10 + k as u64);
        s.objects[0].vertical = Some(Vertical {
            bottom,
            top,
            velocity,
        });
        runs.push(s);
    }
    // Another whisker, and contact substeps (which lanes do not take): run alone, in order.
    let mut other = e2(0.022, 0.9, 20);
    other.whisker.youngs_modulus *= 1.2;
    runs.insert(3, other);
    let mut sub = e2(0.022, 0.9, 21);
    sub.integrator = Integrator {
        dt: 1e-3,
        contact_substeps: 10,
        ..Integrator::default()
    };
    runs.insert(1, sub);
    same_as_alone(&runs);
}

#[test]
fn failed_runs_fail_as_they_do_alone() {
    let mut runs: Vec<Scenario> = (0..5).map(|k| e2(0.02, 0.5, k)).collect();
    // A box that starts on the whisker, one lowered into the plane onto it mid-run, and one far
    // too fast for the step.
    runs[1].objects[0] = vibrissa_core::scenes::peg(0.01, 0.0, 0.002, 0.0);
    runs[2].objects[0].vertical = Some(Vertical {
        bottom: 0.005,
        top: 0.02,
        velocity: -0.5,
    });
    runs[3].objects[0] = e2_box(0.015, 40.0);
    runs[3].integrator.dt = 1e-3;
    same_as_alone(&runs);
    // Not even a run: a negative duration.
    runs[4].duration = -1.0;
    same_as_alone(&runs);
}
