//! Objects that move across the whisker's plane: an object that lifts away during contact
//! releases the whisker at once (the seed paper's plucking), which then rings at the clamped
//! whisker's first natural frequency with its modal damping.

use vibrissa_core::objects::Vertical;
use vibrissa_core::scenes;
use vibrissa_core::sim::{self, Scenario, COLUMNS};

/// Column index by name.
fn col(name: &str) -> usize {
    COLUMNS.iter().position(|c| *c == name).unwrap()
}

/// The e2 box at d = 20 mm, v = 0.6 m/s (contact from 2 ms to about 51 ms), sampled at 5 kHz;
/// with `lift`, the box rises out of the plane at 0.1 m/s so that it leaves it at 35 ms.
fn strike(lift: bool) -> sim::Output {
    let mut b = scenes::e2_box(0.02, 0.6);
    if lift {
        b.vertical = Some(Vertical {
            bottom: -0.0035,
            top: 0.01,
            velocity: 0.1,
        });
    }
    let sc = Scenario {
        objects: vec![b],
        duration: 0.15,
        sample_rate: 5000.0,
        ..Scenario::default()
    };
    sim::run(&sc, &mut |_| {}).unwrap()
}

#[test]
fn a_box_lifted_away_releases_the_whisker_which_rings_at_its_first_mode() {
    let (held, plucked) = (strike(false), strike(true));
    let t = |r: &[f64; 10]| r[0];
    let contact = |r: &[f64; 10]| r[col("contact")] == 1.0;
    // Identical until the box leaves the plane.
    let lift = 0.035;
    for (a, b) in held.rows.iter().zip(&plucked.rows) {
        if t(a) < lift - 1e-9 {
            let same = a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
            assert!(same, "t = {}: {a:?} against {b:?}", t(a));
        }
    }
    // In contact just before, free from the first sample after it, for good.
    let before = plucked.rows.iter().rfind(|r| t(r) < lift).unwrap();
    assert!(contact(before), "no contact at t = {}", t(before));
    assert!(plucked
        .rows
        .iter()
        .filter(|r| t(r) > lift + 1e-9)
        .all(|r| !contact(r)));
    // The held box keeps the whisker longer.
    assert!(held.rows.iter().any(|r| t(r) > lift + 0.005 && contact(r)));

    // Free ringing of the base angle after the release: its frequency from the rising zero
    // crossings, its damping from successive peaks, against the clamped–free first mode of the
    // w30 whisker (51.341 Hz) at its damping ratio 0.05.
    let th: Vec<(f64, f64)> = plucked
        .rows
        .iter()
        .filter(|r| t(r) > 0.045)
        .map(|r| (t(r), r[col("theta01")]))
        .collect();
    let rising: Vec<f64> = th
        .windows(2)
        .filter(|w| w[0].1 < 0.0 && w[1].1 >= 0.0)
        .map(|w| w[0].0 - w[0].1 * (w[1].0 - w[0].0) / (w[1].1 - w[0].1))
        .collect();
    assert!(rising.len() >= 4, "{rising:?}");
    let f = (rising.len() - 1) as f64 / (rising[rising.len() - 1] - rising[0]);
    let zeta: f64 = 0.05;
    let damped = 51.341 * (1.0 - zeta * zeta).sqrt();
    assert!(
        (f / damped - 1.0).abs() < 0.01,
        "ringing at {f} Hz, not {damped}"
    );
    let peaks: Vec<f64> = th
        .windows(3)
        .filter(|w| w[1].1 > w[0].1 && w[1].1 >= w[2].1 && w[1].1 > 0.0)
        .map(|w| w[1].1)
        .collect();
    let decrement = (peaks[1] / peaks[peaks.len() - 1]).ln() / (peaks.len() - 2) as f64;
    let expected = 2.0 * std::f64::consts::PI * zeta / (1.0 - zeta * zeta).sqrt();
    assert!(
        (decrement / expected - 1.0).abs() < 0.03,
        "logarithmic decrement {decrement}, not {expected}"
    );
}

#[test]
fn an_object_that_never_cuts_the_plane_is_never_touched() {
    let mut b = scenes::e2_box(0.02, 0.6);
    b.vertical = Some(Vertical {
        bottom: 0.001,
        top: 0.01,
        velocity: 0.0,
    });
    let sc = Scenario {
        objects: vec![b],
        ..Scenario::default()
    };
    let out = sim::run(&sc, &mut |_| {}).unwrap();
    assert!(out.rows.iter().all(|r| r[col("contact")] == 0.0));
    assert!(out.rows.iter().all(|r| r[col("theta01")] == 0.0));
}

#[test]
fn an_object_entering_the_plane_on_the_whisker_is_refused_and_bad_extents_are_named() {
    // A box over the whisker's middle, descending into the plane at 20 ms.
    let mut b = scenes::peg(0.015, 0.0, 0.002, 0.0);
    b.vertical = Some(Vertical {
        bottom: 0.002,
        top: 0.01,
        velocity: -0.1,
    });
    let sc = Scenario {
        objects: vec![b.clone()],
        ..Scenario::default()
    };
    let e = sim::run(&sc, &mut |_| {}).unwrap_err().to_string();
    assert!(
        e.contains("objects[0].vertical") && e.contains("entering the whisker's plane"),
        "{e}"
    );
    for (v, field) in [
        (
            Vertical {
                bottom: 0.01,
                top: 0.0,
                velocity: 0.0,
            },
            "vertical.top",
        ),
        (
            Vertical {
                bottom: f64::NAN,
                top: 0.0,
                velocity: 0.0,
            },
            "vertical.bottom",
        ),
        (
            Vertical {
                bottom: 0.0,
                top: 0.01,
                velocity: 5e3,
            },
            "vertical.velocity",
        ),
    ] {
        b.vertical = Some(v);
        let sc = Scenario {
            objects: vec![b.clone()],
            ..Scenario::default()
        };
        let e = sim::run(&sc, &mut |_| {}).unwrap_err().to_string();
        assert!(e.contains(field), "{e}");
    }
}
