//! Inverse estimators of the contact distance: closed forms against beam theory and the chain's
//! statics, and the simulated peg sweep.

use vibrissa_core::beam::{kaneko_omega, PointLoadCubic};
use vibrissa_core::inverse::*;
use vibrissa_core::{statics, Discretisation, Model, PointLoad, WhiskerParams};

const EI: f64 = 2.3562e-7;

fn rel(a: f64, b: f64) -> f64 {
    (a / b - 1.0).abs()
}

/// Loads and distances covering both signs and the whole whisker beyond the second chord.
fn cases() -> Vec<PointLoadCubic> {
    let mut out = Vec::new();
    for c in [0.0031, 0.005, 0.012, 0.02, 0.029] {
        for w in [2e-5, -7e-5] {
            out.push(PointLoadCubic { ei: EI, w, c });
        }
    }
    out
}

#[test]
fn inverse_moment_over_force_recovers_the_load_distance() {
    for b in cases() {
        // The base balances the load: force −W, moment −W·C.
        let m0 = -b.w * b.c;
        let c = moment_over_force(m0, 0.0, -b.w).unwrap();
        assert!(rel(c, b.c) < 1e-12, "{b:?}: {c}");
        let c = moment_over_transverse_force(m0, -b.w).unwrap();
        assert!(rel(c, b.c) < 1e-12, "{b:?}: {c}");
    }
    assert!(moment_over_force(1e-6, 0.0, 0.0).is_err());
    assert!(moment_over_force(f64::NAN, 0.0, 1.0).is_err());
}

#[test]
fn inverse_chord_angles_recover_load_and_distance() {
    let l = 0.0015;
    for b in cases() {
        // Chord slopes of the cubic itself: base to l, and l to 2l relative to the first.
        let t01 = b.deflection(l) / l;
        let t12 = (b.deflection(2.0 * l) - b.deflection(l)) / l - t01;
        let (w, c) = from_chord_angles(t01, t12, l, EI).unwrap();
        assert!(rel(c, b.c) < 1e-9 && rel(w, b.w) < 1e-9, "{b:?}: {w} {c}");
        // The closed relations themselves.
        let k = b.w / EI;
        assert!(rel(t01, k * (b.c * l / 2.0 - l * l / 6.0)) < 1e-12);
        assert!(rel(t01 + t12, k * (1.5 * b.c * l - 7.0 * l * l / 6.0)) < 1e-12);
        assert!(rel(t12, k * (b.c * l - l * l)) < 1e-12);
        // Chord angles as angles (atan) under a tiny load differ only at second order.
        let tiny = PointLoadCubic { w: b.w * 1e-4, ..b };
        let a01 = (tiny.deflection(l) / l).atan();
        let a12 = ((tiny.deflection(2.0 * l) - tiny.deflection(l)) / l).atan() - a01;
        let (_, c) = from_chord_angles(a01, a12, l, EI).unwrap();
        assert!(rel(c, b.c) < 1e-6, "{b:?}: {c}");
    }
    assert!(from_chord_angles(0.0, 0.0, 0.0015, EI).is_err());
    assert!(from_chord_angles(1e-3, 2e-3, -1.0, EI).is_err());
}

#[test]
fn inverse_moment_and_angle_recover_load_and_distance() {
    let l = 0.0015;
    for b in cases() {
        let (w, c) = from_moment_and_angle(-b.w * b.c, b.deflection(l) / l, l, EI).unwrap();
        assert!(rel(c, b.c) < 1e-9 && rel(w, b.w) < 1e-9, "{b:?}: {w} {c}");
    }
}

#[test]
fn inverse_joint_angles_recover_the_chain_statics() {
    let w = WhiskerParams::w30().check().unwrap();
    for disc in [
        Discretisation::Gregory,
        Discretisation::Trapezoid,
        Discretisation::Seed,
    ] {
        let m = Model::new(&w, 20, disc).unwrap();
        for (c, f) in [(0.0031, 1e-9), (0.0125, -3e-9), (0.029, 2e-9)] {
            let (segment, along) = m.locate(c).unwrap();
            let load = PointLoad {
                segment,
                along,
                force: [0.0, f],
            };
            let eq = statics::solve(&m, &[load]).unwrap();
            let (k0, k1) = (m.stiffness[0], m.stiffness[1]);
            let (wf, cf) = from_joint_angles(eq.q[0], eq.q[1], m.len[0], k0, k1).unwrap();
            // The statics are geometrically exact: agreement to the small-deflection order.
            assert!(
                rel(cf, c) < 1e-9 && rel(wf, f) < 1e-9,
                "{disc:?} {c}: {wf} {cf}"
            );
        }
    }
    // Synthesised from the cubic's moments with any stiffnesses.
    for b in cases() {
        let (l, k0, k1) = (0.0015, 3e-4, 1.2e-4);
        let (w, c) = from_joint_angles(b.moment(0.0) / k0, b.moment(l) / k1, l, k0, k1).unwrap();
        assert!(rel(c, b.c) < 1e-9 && rel(w, b.w) < 1e-9, "{b:?}");
    }
}

#[test]
fn inverse_kaneko_torque_angle_recovers_the_distance() {
    for b in cases() {
        // Base rotation that deflects the fixed contact by the cubic's deflection there.
        let delta_psi = b.deflection(b.c) / b.c;
        let c = kaneko_torque_angle(delta_psi, -b.w * b.c, EI).unwrap();
        assert!(rel(c, b.c) < 1e-9, "{b:?}: {c}");
    }
    assert!(kaneko_torque_angle(1e-3, 0.0, EI).is_err());
}

#[test]
fn inverse_kaneko_frequency_inverts_the_formula() {
    let (m, l) = (RAYLEIGH_TIP_MASS * 1.0367e-6, 0.03);
    for c in [0.001, 0.0071, 0.015, 0.0234, 0.0299] {
        let omega = kaneko_omega(EI, m, l, c / l);
        let got = kaneko_frequency(omega, EI, m, l).unwrap();
        assert!((got - c).abs() < 1e-9 * l, "{c}: {got}");
    }
    // Below the free tip-mass frequency: 0.
    let free = kaneko_omega(EI, m, l, 0.0);
    assert_eq!(kaneko_frequency(0.5 * free, EI, m, l).unwrap(), 0.0);
    assert!(kaneko_frequency(-1.0, EI, m, l).is_err());
}

#[test]
fn inverse_pinned_frequency_brackets() {
    let w = WhiskerParams::w30().check().unwrap();
    let m = Model::new(&w, 20, Discretisation::Gregory).unwrap();
    let free = 2.0 * std::f64::consts::PI * m.modes().unwrap().frequencies[0];
    // Pinned at the base: the free whisker; pinned further out: stiffer, up to the
    // clamped–pinned beam ((3.9266/1.8751)² times the free frequency).
    assert!(rel(pinned_frequency(&m, 0.0).unwrap(), free) < 1e-9);
    let tip = pinned_frequency(&m, 0.03).unwrap();
    assert!(
        rel(tip, free * (3.926_602 / 1.875_104f64).powi(2)) < 0.01,
        "{tip} {free}"
    );
    let mut last = free;
    for s in [0.005, 0.01, 0.015, 0.02, 0.025] {
        let f = pinned_frequency(&m, s).unwrap();
        assert!(f > last, "{s}");
        last = f;
    }
}

#[test]
fn inverse_peg_sweep_small_deflection_and_growth() {
    let sweep = PegSweep {
        levels: vec![0.005, 0.20],
        ..Default::default()
    };
    let rows = evaluate_peg_sweep(&sweep).unwrap();
    let pick = |e: Estimator, level: f64| -> Vec<InverseResult> {
        rows.iter()
            .filter(|r| r.estimator == e && r.level == level)
            .copied()
            .collect()
    };
    for r in rows.iter().filter(|r| r.level == 0.005) {
        eprintln!(
            "{:16} d {:4.1} mm tip {:.4} L err {:+.5}",
            r.estimator.name(),
            r.d * 1e3,
            r.tip_deflection,
            r.relative_error
        );
    }
    let small = pick(Estimator::MomentOverForce, 0.005);
    let large = pick(Estimator::MomentOverForce, 0.20);
    assert_eq!(small.len(), 13);
    assert_eq!(large.len(), 13);
    for r in &small {
        assert!(r.relative_error.abs() < 0.02, "{r:?}");
    }
    // The joint-angle pair on every peg.
    for r in pick(Estimator::JointAngles, 0.005) {
        assert!(r.relative_error.abs() < 0.02, "{r:?}");
    }
    // Errors grow with deflection: per peg for M/F, and in the worst case for both M/F forms.
    for (a, b) in small.iter().zip(&large) {
        assert_eq!(a.d, b.d);
        assert!(
            b.relative_error.abs() > a.relative_error.abs(),
            "{a:?} {b:?}"
        );
    }
    let worst = worst_over_distances(&rows);
    let get = |e: Estimator, l: f64| worst.iter().find(|w| w.0 == e && w.1 == l).unwrap().2;
    for e in [
        Estimator::MomentOverForce,
        Estimator::MomentOverTransverseForce,
    ] {
        assert!(get(e, 0.20) > 5.0 * get(e, 0.005), "{e:?}");
    }
    // The continuum chord formulas do not describe the chain's joint angles.
    assert!(get(Estimator::ChordAngles, 0.005) > 0.5);
    // Birdwell's rates and the frequency method with the beam's own mass hold within 2 %; the
    // frequency method only before the propped beam's frequency peak (10 of the 13 pegs).
    for r in pick(Estimator::BirdwellRates, 0.005) {
        assert!(r.relative_error.abs() < 0.02, "{r:?}");
    }
    let beam: Vec<_> = pick(Estimator::KanekoFrequencyBeam, 0.0);
    assert_eq!(beam.len(), 10);
    for r in &beam {
        assert!(r.relative_error.abs() < 0.02, "{r:?}");
    }
    assert!(get(Estimator::KanekoFrequency, 0.0) > 0.1);
}

/// The propped beam's frequency equation against the classical roots: the cantilever
/// (βL = 1.8751) with the prop at the base, the clamped–pinned beam (βL = 3.9266) with it at the
/// tip; a prop at half the length gives βL = π exactly (the outer half then vibrates as a
/// pinned–free span whose root the clamped–pinned half shares).
#[test]
fn inverse_propped_beam_frequencies() {
    let (rho_a, l) = (3.4558e-5, 0.03);
    let unit = (EI / rho_a).sqrt() / (l * l);
    let bl = |c: f64| (pinned_beam_omega(EI, rho_a, l, c).unwrap() / unit).sqrt();
    assert!((bl(0.0) - 1.875_104).abs() < 1e-5, "{}", bl(0.0));
    assert!((bl(l) - 3.926_602).abs() < 1e-5, "{}", bl(l));
    assert!(
        (bl(0.5 * l) - std::f64::consts::PI).abs() < 1e-6,
        "{}",
        bl(0.5 * l)
    );
    // The first frequency peaks at about 0.78 L and falls again beyond.
    let peak = pinned_beam_peak(EI, rho_a, l).unwrap();
    assert!((0.7..0.85).contains(&peak), "{peak}");
    assert!(bl(peak * l) > bl(0.7 * l) && bl(peak * l) > bl(0.9 * l));
    // Inversion on the rising branch returns the prop.
    for c in [0.004, 0.011, 0.02] {
        let om = pinned_beam_omega(EI, rho_a, l, c).unwrap();
        let back = kaneko_frequency_beam(om, EI, rho_a, l).unwrap();
        assert!((back - c).abs() < 1e-9, "{c} -> {back}");
    }
    assert!(pinned_beam_omega(EI, rho_a, l, 0.031).is_err());
}

#[test]
fn inverse_birdwell_rates_is_the_rate_form_of_the_cubic() {
    // Base turning at ψ̇ against a point at C: M = 3 EI ψ / C, so Ṁ = 3 EI ψ̇ / C.
    for c in [0.005, 0.02] {
        let psi_rate = 0.05;
        let m0_rate = -3.0 * EI * psi_rate / c;
        assert!(rel(birdwell_rates(psi_rate, m0_rate, EI).unwrap(), c) < 1e-12);
    }
    assert!(birdwell_rates(0.0, 1.0, EI).is_err());
    assert!(birdwell_rates(0.05, f64::NAN, EI).is_err());
}

/// The joint-angle pair within 2 % on every peg at small deflection: the simulated contact keeps
/// the joint angles in static balance with the base moment.
#[test]
fn inverse_joint_angles_on_every_peg() {
    let sweep = PegSweep {
        levels: vec![0.005],
        ..Default::default()
    };
    for r in evaluate_peg_sweep(&sweep).unwrap() {
        if r.estimator == Estimator::JointAngles {
            assert!(r.relative_error.abs() < 0.02, "{r:?}");
        }
    }
}
