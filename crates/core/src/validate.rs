//! The validation suite: the segment chain measured against continuum beam theory.
//!
//! Every figure is computed here, by simulation or by the chain's own static solver, and is
//! reported beside its independent reference (the seed paper's cubic, the elastica, clamped–free
//! beam frequencies) so anyone can recompute the error. Targets are those the project holds the
//! default discretisation to at N = 20; the `seed` rule is measured for comparison only.

use crate::beam::{self, BeamProfile};
use crate::chain::{Discretisation, Model};
use crate::dynamics::{
    self, initialize, kinetic_energy, momentum, potential_energy, step, Inputs, Integrator,
    PointLoad, State, Workspace,
};
use crate::error::Result;
pub use crate::signal::{crossing_frequency, decay_ratio};
use crate::statics;
use crate::whisker::{Damping, WhiskerParams};
use nalgebra::DVector;
use serde::Serialize;

/// Options of [`run`].
#[derive(Debug, Clone, Copy, Default)]
pub struct ValidateOptions {
    /// Fewer segment counts and shorter runs (for tests); the full suite otherwise.
    pub quick: bool,
}

/// One measured quantity beside its reference.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Check {
    /// Family of checks, e.g. `static_small`, `large_deflection`, `frequency`, `stability`.
    pub group: String,
    /// What was run, e.g. `w30 gregory N=20 C=L`.
    pub label: String,
    /// The quantity, e.g. `tip deflection`.
    pub quantity: String,
    /// SI unit of `value` and `reference`.
    pub unit: String,
    /// Measured value.
    pub value: f64,
    /// Independent reference value.
    pub reference: f64,
    /// Error of `value` against `reference`, in `error_unit`.
    pub error: f64,
    /// `relative` (value/reference - 1), `fraction_of_length` ((value-reference)/L) or `absolute`.
    pub error_unit: String,
    /// Largest acceptable |error|, where a target applies.
    pub target: Option<f64>,
    /// Whether the check passes, where it has a requirement: |error| <= `target`, or the one its
    /// label states (the order of convergence).
    pub pass: Option<bool>,
}

/// The suite's result.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Report {
    /// Every check, in the order run.
    pub checks: Vec<Check>,
}

impl Report {
    /// True when no check with a target failed.
    pub fn all_pass(&self) -> bool {
        self.checks.iter().all(|c| c.pass != Some(false))
    }
}

/// How an error is expressed.
#[derive(Clone, Copy)]
enum ErrorUnit {
    Relative,
    OfLength(f64),
    Absolute,
}

struct Group<'a> {
    name: &'a str,
    out: &'a mut Vec<Check>,
}

impl Group<'_> {
    /// Records `value` against `reference`; the target (if any) bounds |error|.
    #[allow(clippy::too_many_arguments)]
    fn add(
        &mut self,
        label: &str,
        quantity: &str,
        unit: &str,
        value: f64,
        reference: f64,
        eu: ErrorUnit,
        target: Option<f64>,
    ) {
        let (error, name) = match eu {
            ErrorUnit::Relative => (value / reference - 1.0, "relative"),
            ErrorUnit::OfLength(l) => ((value - reference) / l, "fraction_of_length"),
            ErrorUnit::Absolute => (value - reference, "absolute"),
        };
        self.out.push(Check {
            group: self.name.to_string(),
            label: label.to_string(),
            quantity: quantity.to_string(),
            unit: unit.to_string(),
            value,
            reference,
            error,
            error_unit: name.to_string(),
            target,
            pass: target.map(|t| error.is_finite() && error.abs() <= t),
        });
    }
}

const DISCRETISATIONS: [Discretisation; 2] = [Discretisation::Gregory, Discretisation::Seed];

fn target_at_20(d: Discretisation, n: usize, t: f64) -> Option<f64> {
    (d == Discretisation::Gregory && n == 20).then_some(t)
}

/// Runs the suite, calling `progress` with a line before each part.
pub fn run(opts: &ValidateOptions, progress: &mut dyn FnMut(&str)) -> Result<Report> {
    let mut checks = Vec::new();
    let ns: &[usize] = if opts.quick {
        &[5, 20]
    } else {
        &[5, 10, 20, 40]
    };
    progress("static small deflection vs the seed's cubic");
    static_small(ns, &mut checks)?;
    progress("large deflection vs the elastica");
    large_deflection(ns, &mut checks)?;
    progress("natural frequencies from simulated free vibration");
    frequencies(ns, &mut checks)?;
    progress("tapered whiskers' first frequency vs a converged finite-element reference");
    tapered(&mut checks)?;
    progress("base reaction vs Newton's laws");
    base_reaction(&mut checks)?;
    progress("time-step accuracy and stability");
    step_accuracy(opts.quick, &mut checks)?;
    stability(opts.quick, &mut checks)?;
    progress("contact against beam theory, Newton's laws, energy and Coulomb's law");
    contact(&mut checks)?;
    Ok(Report { checks })
}

/// The w30 whisker with its damping replaced.
fn w30_with(damping: Damping) -> Result<crate::whisker::Whisker> {
    let mut p = WhiskerParams::w30();
    p.damping = damping;
    p.check()
}

/// A point load at arc length `s` (m) with force `f`.
fn load_at(model: &Model, s: f64, f: [f64; 2]) -> Result<PointLoad> {
    let (segment, along) = model.locate(s)?;
    Ok(PointLoad {
        segment,
        along,
        force: f,
    })
}

fn static_small(ns: &[usize], out: &mut Vec<Check>) -> Result<()> {
    let w = WhiskerParams::w30().check()?;
    let (l, ei) = (w.length(), w.ei(0.0));
    let mut g = Group {
        name: "static_small",
        out,
    };
    for d in DISCRETISATIONS {
        for &n in ns {
            let model = Model::new(&w, n, d)?;
            for (cname, c) in [("L", l), ("L/2", 0.5 * l)] {
                // Load giving a continuum tip deflection of 1% of L.
                let wload = beam::load_for_tip_deflection(ei, l, c, 0.01 * l);
                let cubic = beam::PointLoadCubic { ei, w: wload, c };
                let eq = statics::solve(&model, &[load_at(&model, c, [0.0, wload])?])?;
                let label = format!("w30 {} N={n} C={cname}", d.name());
                let t = target_at_20(d, n, 0.005);
                g.add(
                    &label,
                    "tip deflection",
                    "m",
                    eq.nodes[n][1],
                    cubic.deflection(l),
                    ErrorUnit::Relative,
                    t,
                );
                g.add(
                    &label,
                    "base moment m0",
                    "N·m",
                    eq.base_wrench[0],
                    -wload * c,
                    ErrorUnit::Relative,
                    t,
                );
            }
        }
    }
    Ok(())
}

fn large_deflection(ns: &[usize], out: &mut Vec<Check>) -> Result<()> {
    let w = WhiskerParams::w30().check()?;
    let (l, ei) = (w.length(), w.ei(0.0));
    let mut g = Group {
        name: "large_deflection",
        out,
    };
    for alpha in [1.0, 3.0, 10.0] {
        let f = [0.0, alpha * ei / (l * l)];
        let reference = beam::elastica(&w, f, l)?;
        let tip = reference.tip();
        for d in DISCRETISATIONS {
            for &n in ns {
                let model = Model::new(&w, n, d)?;
                let eq = statics::solve(&model, &[load_at(&model, l, f)?])?;
                let label = format!("w30 {} N={n} alpha={alpha}", d.name());
                let t = target_at_20(d, n, 0.005);
                g.add(
                    &label,
                    "tip x",
                    "m",
                    eq.nodes[n][0],
                    tip[0],
                    ErrorUnit::OfLength(l),
                    t,
                );
                g.add(
                    &label,
                    "tip y",
                    "m",
                    eq.nodes[n][1],
                    tip[1],
                    ErrorUnit::OfLength(l),
                    t,
                );
                let dist = (eq.nodes[n][0] - tip[0]).hypot(eq.nodes[n][1] - tip[1]);
                let q = "tip distance to elastica";
                g.add(&label, q, "m", dist, 0.0, ErrorUnit::OfLength(l), t);
            }
        }
    }
    Ok(())
}

/// Free vibration in mode `k` (0-based) from a small modal amplitude: returns the sampled modal
/// coordinate (t, η).
fn free_vibration(
    model: &Model,
    k: usize,
    dt: f64,
    rho_inf: f64,
    duration: f64,
) -> Result<(Vec<f64>, Vec<f64>)> {
    let modes = model.modes()?;
    let shape = &modes.shapes[k];
    let m0 = model.mass_matrix(&model.rest);
    let proj = m0 * DVector::from_column_slice(shape);
    // Amplitude: the largest joint excursion 1e-4 rad (linear regime).
    let scale = 1e-4 / shape.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    let mut state = State::at_rest(model, 0);
    for (q, (r, s)) in state.q_mut().iter_mut().zip(model.rest.iter().zip(shape)) {
        *q = r + scale * s;
    }
    let mut ws = Workspace::new(model);
    let inputs = Inputs::default();
    initialize(model, &mut state, &inputs, &mut ws)?;
    let st = Integrator {
        dt,
        rho_inf,
        ..Default::default()
    }
    .check()?;
    let steps = (duration / dt).round() as usize;
    let (mut ts, mut ys) = (Vec::with_capacity(steps), Vec::with_capacity(steps));
    for _ in 0..steps {
        step(model, &st, &mut state, &inputs, &mut ws)?;
        let eta: f64 = (0..model.n)
            .map(|i| proj[i] * (state.q()[i] - model.rest[i]))
            .sum();
        ts.push(state.t);
        ys.push(eta);
    }
    Ok((ts, ys))
}

/// Slope of log|e| against log N (the order of convergence is minus this).
fn log_slope(ns: &[usize], errs: &[f64]) -> f64 {
    let xs: Vec<f64> = ns.iter().map(|&n| (n as f64).ln()).collect();
    let ys: Vec<f64> = errs.iter().map(|e| e.abs().ln()).collect();
    let m = xs.len() as f64;
    let (xb, yb) = (xs.iter().sum::<f64>() / m, ys.iter().sum::<f64>() / m);
    let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - xb) * (y - yb)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - xb).powi(2)).sum();
    sxy / sxx
}

fn frequencies(ns: &[usize], out: &mut Vec<Check>) -> Result<()> {
    let w = w30_with(Damping::None)?;
    let reference = beam::clamped_free_uniform(w.ei(0.0), w.rho_a(0.0), w.length(), 3);
    let mut g = Group {
        name: "frequency",
        out,
    };
    let mut orders = Vec::new();
    for d in DISCRETISATIONS {
        let mut errs = vec![Vec::new(); 3];
        for &n in ns {
            let model = Model::new(&w, n, d)?;
            let eig = model.modes()?.frequencies;
            for k in 0..3 {
                // Step small against the mode's period so the integrator's period error (~(ωh)²/12)
                // stays below 1e-5; 30 periods.
                let dt = (0.005 / (2.0 * std::f64::consts::PI * reference[k])).min(1e-4);
                let (t, y) = free_vibration(&model, k, dt, 1.0, 30.0 / reference[k])?;
                let f = crossing_frequency(&t, &y).unwrap_or(f64::NAN);
                let label = format!("w30 {} N={n}", d.name());
                let t20 = target_at_20(d, n, 0.005);
                g.add(
                    &label,
                    &format!("f{} simulated", k + 1),
                    "Hz",
                    f,
                    reference[k],
                    ErrorUnit::Relative,
                    t20,
                );
                g.add(
                    &label,
                    &format!("f{} eigen", k + 1),
                    "Hz",
                    eig[k],
                    reference[k],
                    ErrorUnit::Relative,
                    None,
                );
                errs[k].push(f / reference[k] - 1.0);
            }
        }
        orders.push((d, errs));
    }
    if ns.len() >= 3 {
        let mut g = Group {
            name: "convergence",
            out: g.out,
        };
        for (d, errs) in orders {
            for (k, e) in errs.iter().enumerate() {
                // Order of convergence: minus the slope of log|error| against log N. The default
                // rule must reach at least 2; the error column is the margin above 2.
                let order = -log_slope(ns, e);
                let gregory = d == Discretisation::Gregory;
                let label = if gregory {
                    format!("w30 {} N={:?}, order >= 2 required", d.name(), ns)
                } else {
                    format!("w30 {} N={:?}", d.name(), ns)
                };
                let quantity = format!("order of f{} error", k + 1);
                g.add(
                    &label,
                    &quantity,
                    "1",
                    order,
                    2.0,
                    ErrorUnit::Absolute,
                    None,
                );
                if let Some(c) = g.out.last_mut() {
                    c.pass = gregory.then_some(order >= 2.0);
                }
            }
        }
    }
    Ok(())
}

fn tapered(out: &mut Vec<Check>) -> Result<()> {
    let mut g = Group {
        name: "tapered",
        out,
    };
    let mut rat = WhiskerParams::rat();
    rat.rest_curvature = 0.0;
    for (name, mut p) in [("robot", WhiskerParams::robot()), ("rat (straight)", rat)] {
        p.damping = Damping::None;
        let w = p.check()?;
        let reference = beam::clamped_free_tapered(&w, 1)?[0];
        for n in [10usize, 20] {
            let model = Model::new(&w, n, Discretisation::Gregory)?;
            let dt = (0.005 / (2.0 * std::f64::consts::PI * reference)).min(1e-4);
            let (t, y) = free_vibration(&model, 0, dt, 1.0, 30.0 / reference)?;
            let f = crossing_frequency(&t, &y).unwrap_or(f64::NAN);
            let target = (n == 20).then_some(0.01);
            g.add(
                &format!("{name} gregory N={n}"),
                "f1 simulated",
                "Hz",
                f,
                reference,
                ErrorUnit::Relative,
                target,
            );
        }
    }
    Ok(())
}

fn base_reaction(out: &mut Vec<Check>) -> Result<()> {
    let mut g = Group {
        name: "base_reaction",
        out,
    };
    let w = WhiskerParams::w30().check()?;
    let l = w.length();
    let model = Model::new(&w, 20, Discretisation::Gregory)?;
    // Static: a damped whisker under an oblique load at 0.7 L settles; the base reaction it
    // reports must balance the load.
    let f = [-0.3 * w.ei(0.0) / (l * l), 2.0 * w.ei(0.0) / (l * l)];
    let load = load_at(&model, 0.7 * l, f)?;
    let loads = [load];
    let inputs = Inputs {
        loads: &loads,
        ..Default::default()
    };
    let st = Integrator::default().check()?;
    let mut state = State::at_rest(&model, 0);
    let mut ws = Workspace::new(&model);
    for _ in 0..30_000 {
        step(&model, &st, &mut state, &inputs, &mut ws)?;
    }
    ws.evaluate(&model, &state);
    let p = ws.point(load.segment, load.along);
    let moment = p[0] * f[1] - p[1] * f[0];
    let label = "w30 gregory N=20, oblique load at 0.7 L, settled 3 s";
    let scale_f = f[0].hypot(f[1]);
    g.add(
        label,
        "m0 + (p × F)",
        "N·m",
        state.base_wrench[0] + moment,
        0.0,
        ErrorUnit::Absolute,
        None,
    );
    g.add(
        label,
        "|m0| vs |p × F|",
        "N·m",
        -state.base_wrench[0],
        moment,
        ErrorUnit::Relative,
        Some(1e-6),
    );
    g.add(
        label,
        "fx vs -Fx",
        "N",
        state.base_wrench[1],
        -f[0],
        ErrorUnit::OfLength(scale_f),
        Some(1e-6),
    );
    g.add(
        label,
        "fy vs -Fy",
        "N",
        state.base_wrench[2],
        -f[1],
        ErrorUnit::OfLength(scale_f),
        Some(1e-6),
    );

    // Dynamic: released from a large deflection, undamped; the base wrench must equal the rate of
    // change of the chain's momentum (no other forces act). Central differences, small step.
    let w = w30_with(Damping::None)?;
    let model = Model::new(&w, 20, Discretisation::Gregory)?;
    let eq = statics::solve(
        &model,
        &[load_at(&model, l, [0.0, 3.0 * w.ei(0.0) / (l * l)])?],
    )?;
    let mut state = State::at_rest(&model, 0);
    state.q_mut().copy_from_slice(&eq.q);
    let inputs = Inputs::default();
    initialize(&model, &mut state, &inputs, &mut ws)?;
    let st = Integrator {
        dt: 1e-6,
        rho_inf: 1.0,
        ..Default::default()
    }
    .check()?;
    let (mut worst, mut scale) = (0.0f64, 0.0f64);
    let mut prev = momentum(&model, &state, &mut ws);
    let mut w_prev = state.base_wrench_intermediate();
    let af = st.alpha_f();
    for k in 0..20_000 {
        step(&model, &st, &mut state, &inputs, &mut ws)?;
        let now = momentum(&model, &state, &mut ws);
        let w_now = state.base_wrench_intermediate();
        if k % 10 == 1 {
            // The method balances forces at t_n + (1 - αf)·h; interpolate the base wrench to the
            // middle of the step, where the momentum difference over the step is centred.
            for c in 0..3 {
                let w = w_prev[c] + (0.5 + af) * (w_now[c] - w_prev[c]);
                let rate = (now[c] - prev[c]) / st.dt;
                let s = if c == 0 { 1.0 } else { l };
                worst = worst.max(((rate - w) * s).abs());
                scale = scale.max((w * s).abs());
            }
        }
        prev = now;
        w_prev = w_now;
    }
    g.add(
        "w30 gregory N=20 undamped, released from alpha=3, 20 ms at dt=1e-6",
        "max |base wrench - dP/dt| / max |base wrench|",
        "1",
        worst / scale,
        0.0,
        ErrorUnit::Absolute,
        Some(1e-3),
    );
    Ok(())
}

fn step_accuracy(quick: bool, out: &mut Vec<Check>) -> Result<()> {
    let mut g = Group {
        name: "time_step",
        out,
    };
    let w = w30_with(Damping::None)?;
    let f1 = beam::clamped_free_uniform(w.ei(0.0), w.rho_a(0.0), w.length(), 1)[0];
    let model = Model::new(&w, 20, Discretisation::Gregory)?;
    let duration = if quick { 1.0 } else { 10.0 };
    for dt in [5e-4, 1e-3] {
        let (t, y) = free_vibration(&model, 0, dt, dynamics::DEFAULT_RHO_INF, duration)?;
        let f = crossing_frequency(&t, &y).unwrap_or(f64::NAN);
        let z = decay_ratio(&t, &y, f).unwrap_or(f64::NAN);
        let label = format!(
            "w30 gregory N=20 undamped, dt={dt}, rho_inf={}",
            dynamics::DEFAULT_RHO_INF
        );
        let target = (dt == 5e-4).then_some(0.01);
        g.add(
            &label,
            "f1 simulated",
            "Hz",
            f,
            f1,
            ErrorUnit::Relative,
            target,
        );
        let tz = (dt == 5e-4).then_some(0.005);
        g.add(
            &label,
            "numerical first-mode damping ratio",
            "1",
            z,
            0.0,
            ErrorUnit::Absolute,
            tz,
        );
    }
    Ok(())
}

fn stability(quick: bool, out: &mut Vec<Check>) -> Result<()> {
    let mut g = Group {
        name: "stability",
        out,
    };
    let ns: &[usize] = if quick {
        &[10, 100]
    } else {
        &[10, 20, 50, 100]
    };
    let duration = if quick { 1.0 } else { 10.0 };
    for &n in ns {
        for (dname, damping) in [
            ("undamped", Damping::None),
            ("damped", Damping::ModalRatio { ratio: 0.05 }),
        ] {
            let w = w30_with(damping)?;
            let l = w.length();
            let model = Model::new(&w, n, Discretisation::Gregory)?;
            // Released from the static shape under a tip load W = EI/L² (tip deflection ~0.3 L).
            let eq = statics::solve(&model, &[load_at(&model, l, [0.0, w.ei(0.0) / (l * l)])?])?;
            for dt in [1e-4, 5e-4, 1e-3] {
                let mut state = State::at_rest(&model, 0);
                state.q_mut().copy_from_slice(&eq.q);
                let mut ws = Workspace::new(&model);
                let inputs = Inputs::default();
                initialize(&model, &mut state, &inputs, &mut ws)?;
                let st = Integrator::with_dt(dt).check()?;
                let e0 = potential_energy(&model, &state);
                let mut emax = e0;
                let steps = (duration / dt).round() as usize;
                for k in 0..steps {
                    step(&model, &st, &mut state, &inputs, &mut ws)?;
                    if k % 10 == 0 {
                        let e = potential_energy(&model, &state)
                            + kinetic_energy(&model, &state, &mut ws);
                        emax = emax.max(e);
                    }
                }
                let e_end =
                    potential_energy(&model, &state) + kinetic_energy(&model, &state, &mut ws);
                let label = format!("w30 gregory N={n} {dname} dt={dt} {duration} s");
                // Bounded: energy never exceeds its initial value by more than 1%.
                g.add(
                    &label,
                    "max energy / initial",
                    "1",
                    emax / e0,
                    1.0,
                    ErrorUnit::Relative,
                    Some(0.01),
                );
                let target = (dname == "undamped" && dt == 1e-4).then_some(0.01);
                let quantity = "final energy / initial";
                if dname == "undamped" {
                    g.add(
                        &label,
                        quantity,
                        "1",
                        e_end / e0,
                        1.0,
                        ErrorUnit::Relative,
                        target,
                    );
                } else {
                    g.add(
                        &label,
                        quantity,
                        "1",
                        e_end / e0,
                        0.0,
                        ErrorUnit::Absolute,
                        None,
                    );
                }
            }
        }
    }
    Ok(())
}

/// The three quasi-static peg checks: moment arm, Newton's third law at the base, shape.
fn peg_checks(g: &mut Group, label: &str, r: &crate::scenes::PegWhisk) {
    let checks = [
        ("max |m0/(|f|·s) - 1|", r.moment_arm_error),
        ("max |m0/(cx·fy - cy·fx) - 1|", r.third_law_error),
        ("max shape error / tip deflection", r.shape_error),
    ];
    for (quantity, value) in checks {
        g.add(
            label,
            quantity,
            "1",
            value,
            0.0,
            ErrorUnit::Absolute,
            Some(0.01),
        );
    }
}

fn contact(out: &mut Vec<Check>) -> Result<()> {
    let mut g = Group {
        name: "contact",
        out,
    };
    // Quasi-static whisk into a peg (see scenes::peg_whisk).
    let r = crate::scenes::peg_whisk()?;
    let label = format!(
        "w30 N=20 whisked at 0.05 rad/s into a peg at 20 mm ({} samples)",
        r.samples
    );
    peg_checks(&mut g, &label, &r);
    // Nearer the base (read up to a 5% tip deflection: the part beyond the peg turns with the
    // base).
    for d in [0.005, 0.010] {
        let r = crate::scenes::peg_whisk_at(d, 1e-4, 0.05)?;
        let label = format!(
            "same with the peg at {} mm ({} samples)",
            d * 1e3,
            r.samples
        );
        peg_checks(&mut g, &label, &r);
    }
    // Ringing after release.
    let r = crate::scenes::ringing_after_release()?;
    let label = "e2 box d=28 mm v=0.6 m/s, theta01 after the last contact";
    g.add(
        label,
        "ringing frequency",
        "Hz",
        r.frequency,
        r.damped_f1,
        ErrorUnit::Relative,
        Some(0.01),
    );
    // Penetration of the fastest box over the e2 distances.
    let (pen, touched) = crate::scenes::e2_penetration(1.5)?;
    let label = format!("e2 box v=1.5 m/s, d=15..30 mm ({touched} of 16 touch)");
    g.add(
        &label,
        "max penetration",
        "m",
        pen,
        0.0,
        ErrorUnit::Absolute,
        Some(1e-6),
    );
    // Energy against a stationary frictionless peg.
    let r = crate::scenes::release_onto_peg()?;
    let label = format!(
        "w30 undamped released onto a peg ({} contact steps)",
        r.contact_steps
    );
    let rise = (r.max_energy_ratio - 1.0).max(0.0);
    g.add(
        &label,
        "energy rise above initial / initial",
        "1",
        rise,
        0.0,
        ErrorUnit::Absolute,
        Some(1e-6),
    );
    let gain = r.max_episode_gain.max(0.0);
    g.add(
        &label,
        "energy gained over a contact episode / before",
        "1",
        gain,
        0.0,
        ErrorUnit::Absolute,
        Some(1e-6),
    );
    g.add(
        &label,
        "max penetration",
        "m",
        r.max_penetration,
        0.0,
        ErrorUnit::Absolute,
        Some(1e-6),
    );
    // Coulomb friction: stick, then slip at the limit.
    let r = crate::scenes::press_and_shear(0.3, |_, _| {})?;
    let label = format!(
        "tip pressed and sheared, mu=0.3 (stick {} steps to {:.3} s, then slip {} steps from {:.3} s)",
        r.stick_steps, r.last_stick, r.slip_steps, r.first_slip
    );
    g.add(
        &label,
        "max |ft|/fn",
        "1",
        r.max_ratio,
        r.mu,
        ErrorUnit::Relative,
        Some(1e-6),
    );
    Ok(())
}
