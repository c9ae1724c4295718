//! Standard contact scenes, measured against theory: the figures behind `vibrissa validate`'s
//! contact checks and the contact tests.

use crate::beam::{BeamProfile, PointLoadCubic};
use crate::chain::{Discretisation, Model};
use crate::dynamics::{
    initialize, kinetic_energy, potential_energy, step, Inputs, Integrator, PointLoad, State,
    Workspace,
};
use crate::error::Result;
use crate::objects::{Motion, Object, Shape};
use crate::sensors::Sensors;
use crate::sim::{self, penetration, BaseDrive, Scenario};
use crate::statics;
use crate::whisker::{Damping, WhiskerParams};

/// A stationary circular peg.
pub fn peg(x: f64, y: f64, radius: f64, friction: f64) -> Object {
    Object {
        shape: Shape::Circle { radius },
        position: [x, y],
        angle: 0.0,
        motion: Motion::default(),
        friction,
        vertical: None,
    }
}

/// The seed experiments' box: 10 mm square, top-left corner at (d, -1 mm) at t = 0, moving +y at
/// `v` (docs/experiments.md).
pub fn e2_box(d: f64, v: f64) -> Object {
    Object {
        shape: Shape::Box {
            width: 0.01,
            height: 0.01,
        },
        position: [d + 0.005, -0.006],
        angle: 0.0,
        motion: Motion::Constant {
            velocity: [0.0, v],
            angular_velocity: 0.0,
        },
        friction: 0.0,
        vertical: None,
    }
}

fn w30_with(damping: Damping) -> Result<crate::whisker::Whisker> {
    let mut p = WhiskerParams::w30();
    p.damping = damping;
    p.check()
}

/// Quasi-static contact measured against beam theory.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PegWhisk {
    /// Samples checked (small deflection, after the impact's ringing has died).
    pub samples: usize,
    /// Largest |m0/(|f|·s) - 1|: the base moment against the contact force times its arc length.
    pub moment_arm_error: f64,
    /// Largest |m0/(cx·fy - cy·fx) - 1|: Newton's third law at the base, in the base frame.
    pub third_law_error: f64,
    /// Largest distance of a node from the seed's cubic for the measured load, over the tip
    /// deflection.
    pub shape_error: f64,
}

/// The w30 whisker (ζ1 = 0.05, N = 20) whisked at 0.05 rad/s into a peg of radius 0.5 mm 20 mm
/// out, 0.02 mm clear of its surface. Checked once the impact's ringing has died (0.3 s, five
/// time constants) while the tip deflection is between 0.1% and 2% of L.
pub fn peg_whisk() -> Result<PegWhisk> {
    peg_whisk_at(0.020, 1e-4, 0.02)
}

/// [`peg_whisk`] with the peg at `d` (m), time step `dt` (s), and samples taken up to a tip
/// deflection of `max_tip` times L (near the base the part beyond the peg turns with the base,
/// so the tip deflection grows while the bending stays small).
pub fn peg_whisk_at(d: f64, dt: f64, max_tip: f64) -> Result<PegWhisk> {
    let w = w30_with(Damping::ModalRatio { ratio: 0.05 })?;
    let (ei, l) = (w.ei(0.0), w.length());
    let m = Model::new(&w, 20, Discretisation::Gregory)?;
    let objects = [peg(d, 0.5e-3 + 0.1e-3 + 0.02e-3, 0.5e-3, 0.0)];
    let drive = BaseDrive::Ramp {
        rate: 0.05,
        start: 0.0,
        stop: f64::INFINITY,
        smoothing: 0.02,
    };
    let st = Integrator::with_dt(dt).check()?;
    let mut s = State::at_rest(&m, 0);
    let mut ws = Workspace::new(&m);
    let mut out = PegWhisk {
        samples: 0,
        moment_arm_error: 0.0,
        third_law_error: 0.0,
        shape_error: 0.0,
    };
    let mut first = f64::INFINITY;
    for k in 1..=(1.2 / dt).round() as usize {
        let inputs = Inputs {
            base: drive.at(k as f64 * st.dt),
            objects: &objects,
            ..Default::default()
        };
        step(&m, &st, &mut s, &inputs, &mut ws)?;
        let Some(c) = s.contact else { continue };
        first = first.min(s.t);
        if s.t < first + 0.3 {
            continue;
        }
        // Tip deflection relative to the rotated base: small.
        ws.evaluate(&m, &s);
        let (sn, cs) = s.base.angle.sin_cos();
        let local = |p: [f64; 2]| [cs * p[0] + sn * p[1], -sn * p[0] + cs * p[1]];
        let tip = local(ws.nodes()[m.n])[1].abs();
        if !(1e-3 * l..=max_tip * l).contains(&tip) {
            continue;
        }
        out.samples += 1;
        let sen = Sensors::read(&s);
        let f = c.force[0].hypot(c.force[1]);
        out.moment_arm_error = out
            .moment_arm_error
            .max((sen.m0.abs() / f / c.s - 1.0).abs());
        let cp = local(c.point);
        let torque = cp[0] * sen.fy - cp[1] * sen.fx;
        out.third_law_error = out.third_law_error.max((sen.m0 / torque - 1.0).abs());
        let cubic = PointLoadCubic { ei, w: -f, c: c.s };
        for p in ws.nodes() {
            let q = local(*p);
            out.shape_error = out
                .shape_error
                .max((q[1] - cubic.deflection(q[0])).abs() / tip);
        }
    }
    Ok(out)
}

/// Ringing after the e2 box has passed, against the model's damped first frequency.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ringing {
    /// Frequency from the zero crossings of theta01 after the last contact, Hz.
    pub frequency: f64,
    /// The chain's first natural frequency times sqrt(1 - ζ1²), Hz.
    pub damped_f1: f64,
}

/// The e2 box at d = 28 mm, v = 0.6 m/s; 0.4 s sampled at 1 kHz.
pub fn ringing_after_release() -> Result<Ringing> {
    let mut sc = Scenario {
        duration: 0.4,
        ..Default::default()
    };
    sc.objects.push(e2_box(0.028, 0.6));
    let out = sim::run(&sc, &mut |_| {})?;
    let last = out.rows.iter().rposition(|r| r[6] > 0.5).unwrap_or(0);
    let (t, y): (Vec<f64>, Vec<f64>) = out.rows[last + 10..].iter().map(|r| (r[0], r[1])).unzip();
    let frequency = crate::signal::crossing_frequency(&t, &y).unwrap_or(f64::NAN);
    let model = Model::new(&sc.whisker.check()?, sc.segments, sc.discretisation)?;
    let f1 = model.modes()?.frequencies[0];
    Ok(Ringing {
        frequency,
        damped_f1: f1 * (1.0f64 - 0.05 * 0.05).sqrt(),
    })
}

/// An undamped whisker released onto a stationary frictionless peg.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounce {
    /// Steps with contact.
    pub contact_steps: usize,
    /// Largest total energy over the initial energy.
    pub max_energy_ratio: f64,
    /// Largest energy after a contact episode over the energy before it.
    pub max_episode_gain: f64,
    /// Largest penetration at the end of a step, m.
    pub max_penetration: f64,
}

/// The w30 whisker, undamped, released from the static shape under a tip load 0.3·EI/L² (tip
/// deflection 0.1 L) and swinging into a peg of radius 0.5 mm at (22, -1) mm; 0.3 s at 0.1 ms.
pub fn release_onto_peg() -> Result<Bounce> {
    let w = w30_with(Damping::None)?;
    let m = Model::new(&w, 20, Discretisation::Gregory)?;
    let l = w.length();
    let load = PointLoad {
        segment: 19,
        along: m.len[19],
        force: [0.0, 0.3 * w.ei(0.0) / (l * l)],
    };
    let eq = statics::solve(&m, &[load])?;
    let objects = [peg(0.022, -1.0e-3, 0.5e-3, 0.0)];
    let st = Integrator::with_dt(1e-4).check()?;
    let mut s = State::at_rest(&m, 0);
    s.q_mut().copy_from_slice(&eq.q);
    let mut ws = Workspace::new(&m);
    let inputs = Inputs {
        objects: &objects,
        ..Default::default()
    };
    initialize(&m, &mut s, &inputs, &mut ws)?;
    let e0 = potential_energy(&m, &s);
    let (mut last, mut before, mut was) = (e0, e0, false);
    let mut out = Bounce {
        contact_steps: 0,
        max_energy_ratio: 1.0,
        max_episode_gain: 0.0,
        max_penetration: 0.0,
    };
    for _ in 0..3_000 {
        step(&m, &st, &mut s, &inputs, &mut ws)?;
        let now = s.contact.is_some();
        out.contact_steps += now as usize;
        let e = potential_energy(&m, &s) + kinetic_energy(&m, &s, &mut ws);
        out.max_energy_ratio = out.max_energy_ratio.max(e / e0);
        if now && !was {
            before = last;
        }
        if was && !now {
            out.max_episode_gain = out.max_episode_gain.max(e / before - 1.0);
        }
        out.max_penetration = out
            .max_penetration
            .max(penetration(&m, &s, &mut ws, &objects));
        (last, was) = (e, now);
    }
    Ok(out)
}

/// Friction at a tip pressed and sheared by a plate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coulomb {
    /// The friction coefficient.
    pub mu: f64,
    /// Largest |tangential force| / normal force over the shear phase.
    pub max_ratio: f64,
    /// Steps sticking (ratio below 0.9 μ) and slipping (ratio at μ) in the shear phase.
    pub stick_steps: usize,
    /// See `stick_steps`.
    pub slip_steps: usize,
    /// First time of slip, s (infinite if none).
    pub first_slip: f64,
    /// Last time of stick before the first slip, s.
    pub last_stick: f64,
}

/// A curved whisker (w30 with rest curvature 20 /m, ζ1 = 0.7) whose tip is pressed 0.3 mm
/// end-on by a 1 mm plate across its tangent in 50 ms, then sheared 4 mm sideways in 200 ms: the
/// tip sticks while the transverse load is below μ·N, then slips at μ·N. `each` sees every step.
pub fn press_and_shear(mu: f64, mut each: impl FnMut(f64, &State)) -> Result<Coulomb> {
    let mut p = WhiskerParams::w30();
    p.rest_curvature = 20.0;
    p.damping = Damping::ModalRatio { ratio: 0.7 };
    let w = p.check()?;
    let m = Model::new(&w, 20, Discretisation::Gregory)?;
    // The tip and its tangent at rest (constant curvature).
    let (k, l) = (20.0f64, w.length());
    let theta = k * l;
    let tip = [theta.sin() / k, (1.0 - theta.cos()) / k];
    let (c, s) = (theta.cos(), theta.sin());
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
        vertical: None,
    };
    let objects = [plate];
    let st = Integrator::with_dt(1e-4).check()?;
    let mut state = State::at_rest(&m, 0);
    let mut ws = Workspace::new(&m);
    let inputs = Inputs {
        objects: &objects,
        ..Default::default()
    };
    let mut out = Coulomb {
        mu,
        max_ratio: 0.0,
        stick_steps: 0,
        slip_steps: 0,
        first_slip: f64::INFINITY,
        last_stick: 0.0,
    };
    for _ in 0..2_500 {
        step(&m, &st, &mut state, &inputs, &mut ws)?;
        each(state.t, &state);
        let Some(c) = state.contact else { continue };
        if state.t < 0.06 || mu == 0.0 {
            continue;
        }
        let ratio = c.tangential_force.abs() / c.normal_force;
        out.max_ratio = out.max_ratio.max(ratio);
        if ratio < 0.9 * mu {
            out.stick_steps += 1;
            if out.first_slip.is_infinite() {
                out.last_stick = state.t;
            }
        } else if ratio > (1.0 - 1e-9) * mu {
            out.slip_steps += 1;
            out.first_slip = out.first_slip.min(state.t);
        }
    }
    Ok(out)
}

/// Largest penetration over the e2 grid's distances at the fastest speed.
pub fn e2_penetration(v: f64) -> Result<(f64, usize)> {
    let mut worst = 0.0f64;
    let mut touched = 0;
    for k in 0..16 {
        let d = 0.015 + 0.001 * k as f64;
        let mut sc = Scenario::default();
        sc.objects.push(e2_box(d, v));
        let out = sim::run(&sc, &mut |_| {})?;
        touched += out.rows.iter().any(|r| r[6] > 0.5) as usize;
        worst = worst.max(out.max_penetration);
    }
    Ok((worst, touched))
}
