//! A particle's object state and the transition model: the box it implies, the whisker's
//! free-ringing model once the box has gone, the mapping of model joints onto the observed chain,
//! and the one-step advance of a particle.

use super::config::Config;
use crate::error::{Error, Result};
use vibrissa_core::chain::Model;
use vibrissa_core::dynamics::{
    initialize, step, step_group, step_group_each, Inputs, Integrator, LaneWorkspace, State,
    Workspace, LANES, MAX_DT,
};
use vibrissa_core::objects::{Motion, Object, Shape};
use vibrissa_core::whisker::{Follicle, WhiskerParams};

/// The object's state of one particle: `[d, v, y0, size, mu]` with `y0` the height of the top
/// face at t = 0 (its trajectory is `y0 + v·t`).
pub(super) type ObjState = [f64; 5];

pub(super) const Y: usize = 2;

/// The particle's box.
fn object_of(o: &ObjState) -> Object {
    let [d, v, y0, size, mu] = *o;
    Object {
        shape: Shape::Box {
            width: size,
            height: size,
        },
        position: [d + 0.5 * size, y0 - 0.5 * size],
        angle: 0.0,
        motion: Motion::Constant {
            velocity: [0.0, v],
            angular_velocity: 0.0,
        },
        friction: mu,
        vertical: None,
    }
}

/// Start delay of the approach: the top face is `gap` below the whisker at `t0`.
pub(super) fn start_delay(o: &ObjState, gap: f64) -> f64 {
    -(o[Y] + gap) / o[1]
}

/// The filter's reported value of unknown `k` for a particle.
pub(super) fn param(o: &ObjState, k: usize, gap: f64) -> f64 {
    match k {
        2 => start_delay(o, gap),
        _ => o[k],
    }
}

/// The whisker's model once a particle's box has gone for good: the same chain stepped once per
/// sample period (or in equal parts of it no longer than [`MAX_DT`], for sample rates below
/// 1 kHz), its stiffness raised so that the first mode keeps its frequency at that step (the
/// implicit method's period elongation, `Ω_num = 2·atan(Ω/2)` with `Ω = ω·h`, is undone by
/// `ω_model = (2/h)·tan(ω·h/2)`). Higher modes, whose frequencies it gets wrong, are damped away
/// within a few milliseconds of the slip-off.
pub(super) struct FreeModel {
    model: Model,
    stepper: vibrissa_core::dynamics::Stepper,
    /// Steps per sample period.
    substeps: usize,
    /// Tip deflection per √energy, m/√J: √(2·C) with C the tip's compliance, L³/(3·EI_min)
    /// (the cantilever's least stiffness) plus L²/k_f for a follicle spring k_f.
    reach_per_root_energy: f64,
    /// Highest rest point of the whisker plus its thickest radius and a margin, m.
    pub(super) clearance: f64,
}

impl FreeModel {
    pub(super) fn new(
        config: &Config,
        whisker: &WhiskerParams,
        model: &Model,
        period: f64,
    ) -> Result<FreeModel> {
        let f1 = model
            .modes()
            .map_err(|e| Error::Observation(format!("filter free model: {e}")))?
            .frequencies[0];
        let substeps = vibrissa_core::dynamics::equal_steps(period, MAX_DT);
        let h = period / substeps as f64;
        let omega_h = 2.0 * std::f64::consts::PI * f1 * h;
        let warp = ((0.5 * omega_h).tan() / (0.5 * omega_h)).powi(2);
        // Every stiffness scaled by one factor scales every frequency by its square root: the
        // whisker's and the follicle's spring alike.
        let mut params = whisker.clone();
        params.youngs_modulus *= warp;
        if let Follicle::Spring { stiffness, damping } = params.follicle {
            params.follicle = Follicle::Spring {
                stiffness: stiffness * warp,
                damping,
            };
        }
        let stiffer = params
            .check()
            .map_err(|e| Error::Observation(format!("filter free model: {e}")))?;
        let free = Model::new(&stiffer, config.segments, config.model_discretisation())
            .map_err(|e| Error::Observation(format!("filter free model: {e}")))?;
        let stepper = Integrator {
            dt: h,
            max_iterations: config.max_iterations,
            ..Integrator::default()
        }
        .check()
        .map_err(|e| Error::Observation(format!("filter integrator: {e}")))?;
        let p = whisker;
        let r_min = p.base_radius.min(p.tip_radius);
        let ei_min = p.youngs_modulus * std::f64::consts::PI * r_min.powi(4) / 4.0;
        // Tip deflection per tip force: the cantilever's least stiffness, and the follicle's
        // rotation carried to the tip.
        let follicle = match p.follicle {
            Follicle::Spring { stiffness, .. } => p.length * p.length / stiffness,
            Follicle::Clamped => 0.0,
        };
        let tip_compliance = p.length.powi(3) / (3.0 * ei_min) + follicle;
        let mut y_rest = 0.0f64;
        let (mut y, mut ang) = (0.0f64, 0.0f64);
        for i in 0..model.n {
            ang += model.rest[i];
            y += model.arc * ang.sin();
            y_rest = y_rest.max(y.abs());
        }
        let rmax = model.radius.iter().cloned().fold(0.0, f64::max);
        Ok(FreeModel {
            model: free,
            stepper,
            substeps,
            reach_per_root_energy: (2.0 * tip_compliance).sqrt(),
            clearance: y_rest + rmax + 2e-4,
        })
    }

    /// Whether the box has left the whisker for good at time `t`: it moves away (upward) and its
    /// bottom is beyond anything the whisker can reach with its energy (by 10%).
    fn cleared(&self, s: &State, o: &ObjState, t: f64, ws: &mut Workspace) -> bool {
        let [_, v, y0, size, _] = *o;
        let bottom = y0 + v * t - size;
        if v <= 0.0 || bottom <= self.clearance {
            return false;
        }
        let energy = vibrissa_core::dynamics::kinetic_energy(&self.model, s, ws)
            + vibrissa_core::dynamics::potential_energy(&self.model, s);
        bottom > self.clearance + 1.1 * self.reach_per_root_energy * energy.max(0.0).sqrt()
    }
}

/// The joint angles `theta01`, `theta12` that a chain `observed` would show, from the joint angles
/// `q` of the model chain `model` (which may be cut into fewer, longer segments). A joint spring
/// holds its angle at its rest angle plus the elastic bending moment there times its compliance,
/// so the model's moments `k_i·(q_i − rest_i)` at its nodes are interpolated linearly in arc length
/// (the bending moment is linear near the base, where no load acts) to the observed chain's first
/// two joints. Identical chains map exactly. `q` needs the model's joints up to the one beyond the
/// observed chain's second joint.
pub fn map_joints(model: &Model, observed: &Model, q: &[f64]) -> [f64; 2] {
    JointMap::new(model, observed, q.len()).apply(q)
}

/// [`map_joints`] from one model chain onto one observed chain, its interpolation found once:
/// for each observed joint, the model's joint below it, the share of the way to the next, and
/// the springs and rest angles the moments are read and mapped with.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum JointMap {
    /// Identical chains: the model's first two angles.
    Same,
    /// Per observed joint: `(i, u, [k_i, rest_i, k_i+1, rest_i+1], [observed rest, observed k])`.
    Between([(usize, f64, [f64; 4], [f64; 2]); 2]),
}

impl JointMap {
    /// The map for angle vectors of `joints` values of `model`.
    pub(crate) fn new(model: &Model, observed: &Model, joints: usize) -> JointMap {
        if model.n == observed.n && model.stiffness == observed.stiffness {
            return JointMap::Same;
        }
        JointMap::Between(std::array::from_fn(|j| {
            let s = j as f64 * observed.arc / model.arc;
            let i = (s.floor() as usize).min(joints.saturating_sub(2));
            let u = s - i as f64;
            let springs = [
                model.stiffness[i],
                model.rest[i],
                model.stiffness[i + 1],
                model.rest[i + 1],
            ];
            (i, u, springs, [observed.rest[j], observed.stiffness[j]])
        }))
    }

    /// The observed chain's `theta01`, `theta12` from the model's joint angles `q`.
    pub(crate) fn apply(&self, q: &[f64]) -> [f64; 2] {
        match self {
            JointMap::Same => [q[0], q[1]],
            JointMap::Between(at) => at.map(|(i, u, [k0, r0, k1, r1], [rest, k])| {
                let m = (1.0 - u) * (k0 * (q[i] - r0)) + u * (k1 * (q[i + 1] - r1));
                rest + m / k
            }),
        }
    }
}

/// One whisker the filter entertains: its transition chain, how its joint angles map onto the
/// observed chain, its free-ringing model, and the state its particles start from (at rest).
pub(super) struct Hypothesis {
    pub(super) model: Model,
    /// The model's joint angles read as the observed chain's.
    pub(super) joints: JointMap,
    pub(super) ringing: FreeModel,
    pub(super) at_rest: State,
}

impl Hypothesis {
    /// The whisker `whisker` under `config`'s chains, observed every `period` seconds.
    pub(super) fn new(config: &Config, whisker: &WhiskerParams, period: f64) -> Result<Hypothesis> {
        let checked = whisker
            .check()
            .map_err(|e| Error::Observation(format!("filter whisker: {e}")))?;
        let model = Model::new(&checked, config.segments, config.model_discretisation())
            .map_err(|e| Error::Observation(format!("filter model: {e}")))?;
        let observed = Model::new(&checked, config.observed_segments, config.discretisation)
            .map_err(|e| Error::Observation(format!("observed chain: {e}")))?;
        let mut at_rest = State::at_rest(&model, config.seed);
        let mut ws = Workspace::new(&model);
        let none = Inputs {
            base: Default::default(),
            loads: &[],
            noise: 0.0,
            objects: &[],
        };
        initialize(&model, &mut at_rest, &none, &mut ws)
            .map_err(|e| Error::Observation(format!("filter initial state: {e}")))?;
        let ringing = FreeModel::new(config, whisker, &model, period)?;
        Ok(Hypothesis {
            joints: JointMap::new(&model, &observed, model.n),
            model,
            ringing,
            at_rest,
        })
    }

    /// The transition model of this whisker with `stepper`.
    pub(super) fn chain<'a>(&'a self, stepper: &'a vibrissa_core::dynamics::Stepper) -> Chain<'a> {
        Chain {
            model: &self.model,
            stepper,
            ringing: &self.ringing,
        }
    }
}

/// The filter's transition model: the chain, its stepper, and the free-ringing model.
pub(super) struct Chain<'a> {
    pub(super) model: &'a Model,
    pub(super) stepper: &'a vibrissa_core::dynamics::Stepper,
    pub(super) ringing: &'a FreeModel,
}

/// Advances one particle by `steps` steps of the contact model (or `periods` steps of the
/// free-ringing model once its box has gone for good), with process noise of intensity `noise`
/// drawn once per sample period; marks the box gone when it has left for good by time `t`.
#[allow(clippy::too_many_arguments)]
pub(super) fn advance(
    chain: &Chain,
    s: &mut State,
    o: &ObjState,
    gone: &mut bool,
    steps: usize,
    periods: usize,
    noise: f64,
    t: f64,
    ws: &mut Workspace,
) -> std::result::Result<(), ()> {
    let ringing = chain.ringing;
    if *gone {
        // Free ringing: the free model's steps of each period.
        let inputs = Inputs {
            base: Default::default(),
            loads: &[],
            noise,
            objects: &[],
        };
        for _ in 0..periods * ringing.substeps {
            step(&ringing.model, &ringing.stepper, s, &inputs, ws).map_err(|_| ())?;
        }
        return Ok(());
    }
    let object = [object_of(o)];
    // Process noise drawn once per period (on its first step, with the intensity that gives the
    // period's impulse its full variance).
    let per_period = (steps / periods.max(1)).max(1);
    let lumped = noise * (per_period as f64).sqrt();
    for j in 0..steps {
        let inputs = Inputs {
            base: Default::default(),
            loads: &[],
            noise: if j % per_period == 0 { lumped } else { 0.0 },
            objects: &object,
        };
        step(chain.model, chain.stepper, s, &inputs, ws).map_err(|_| ())?;
    }
    if s.contact.is_none() && ringing.cleared(s, o, t, ws) {
        let none = Inputs {
            base: Default::default(),
            loads: &[],
            noise: 0.0,
            objects: &[],
        };
        initialize(&ringing.model, s, &none, ws).map_err(|_| ())?;
        *gone = true;
    }
    Ok(())
}

/// Advances particles whose boxes have gone for good (up to [`LANES`] of them, of this chain)
/// together in lanes by `periods` sample periods of the free-ringing model, as [`advance`] does
/// each, to the same bits. Returns which of them could be advanced.
pub(super) fn ring_together(
    chain: &Chain,
    states: &mut [&mut State],
    periods: usize,
    noise: f64,
    lw: &mut LaneWorkspace,
    ws: &mut Workspace,
) -> [bool; LANES] {
    let ringing = chain.ringing;
    let inputs = Inputs {
        base: Default::default(),
        loads: &[],
        noise,
        objects: &[],
    };
    let steps = periods * ringing.substeps;
    let out = step_group(
        &ringing.model,
        &ringing.stepper,
        states,
        &inputs,
        steps,
        lw,
        ws,
    );
    out.map(|e| e.is_none())
}

/// Advances particles whose boxes have not gone for good (up to [`LANES`] of them, of this
/// chain, `objs[k]` the object state of `states[k]`) together in lanes by `steps` steps of the
/// contact model, as [`advance`] does each, to the same bits. Returns, for each, `None` if it
/// could not be advanced, else whether its box has left for good by time `t` (its state then
/// rings on the free model).
#[allow(clippy::too_many_arguments)]
pub(super) fn advance_together(
    chain: &Chain,
    states: &mut [&mut State],
    objs: &[ObjState],
    steps: usize,
    periods: usize,
    noise: f64,
    t: f64,
    lw: &mut LaneWorkspace,
    ws: &mut Workspace,
) -> [Option<bool>; LANES] {
    let boxes: Vec<[Object; 1]> = objs.iter().map(|o| [object_of(o)]).collect();
    let objects: Vec<&[Object]> = boxes.iter().map(|b| &b[..]).collect();
    // Process noise drawn once per period, as `advance` draws it.
    let per_period = (steps / periods.max(1)).max(1);
    let lumped = noise * (per_period as f64).sqrt();
    let noise_at = move |j: usize| if j % per_period == 0 { lumped } else { 0.0 };
    let out = step_group_each(
        chain.model,
        chain.stepper,
        states,
        &objects,
        Default::default(),
        &noise_at,
        steps,
        lw,
        ws,
    );
    let ringing = chain.ringing;
    let none = Inputs {
        base: Default::default(),
        loads: &[],
        noise: 0.0,
        objects: &[],
    };
    std::array::from_fn(|k| {
        if k >= states.len() || out[k].is_some() {
            return None;
        }
        let s = &mut *states[k];
        if s.contact.is_none() && ringing.cleared(s, &objs[k], t, ws) {
            initialize(&ringing.model, s, &none, ws).ok()?;
            return Some(true);
        }
        Some(false)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use vibrissa_core::chain::Discretisation;

    #[test]
    fn joint_angles_map_exactly_under_a_linear_bending_moment() {
        // A straight and a curved whisker (whose joints rest at non-zero angles).
        let mut curved = WhiskerParams::w30();
        curved.rest_curvature = 20.0;
        for params in [WhiskerParams::w30(), curved] {
            let w = params.check().unwrap();
            let fine = Model::new(&w, 20, Discretisation::default()).unwrap();
            // A tip load: the bending moment falls linearly to zero at the tip, and every joint
            // of a chain in equilibrium holds its rest angle plus the moment at its node over its
            // stiffness.
            let moment = |s: f64| 3e-6 * (0.03 - s) + 1e-7;
            let angle = |m: &Model, i: usize| m.rest[i] + moment(i as f64 * m.arc) / m.stiffness[i];
            for n in [3, 5, 8, 20, 40] {
                let coarse = Model::new(&w, n, Discretisation::default()).unwrap();
                let q: Vec<f64> = (0..n).map(|i| angle(&coarse, i)).collect();
                let mapped = map_joints(&coarse, &fine, &q);
                for (j, m) in mapped.iter().enumerate() {
                    let want = angle(&fine, j);
                    assert!(
                        (m - want).abs() < 1e-12 * want.abs().max(1e-3),
                        "N = {n}, joint {j}: {m} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_free_model_keeps_the_first_mode_in_a_compliant_follicle() {
        let mut config = Config::e2([1.0; 5], 1, 1);
        config.whisker.follicle = Follicle::Spring {
            stiffness: 1.4e-4,
            damping: 4.5e-8,
        };
        let w = config.whisker.check().unwrap();
        let model = Model::new(&w, 8, Discretisation::default()).unwrap();
        config.segments = 8;
        let f1 = model.modes().unwrap().frequencies[0];
        // 1 kHz, 10 kHz, and 500 Hz and 300 Hz, whose periods are longer than a step may be.
        for (period, substeps) in [(1e-3, 1), (1e-4, 1), (2e-3, 2), (1.0 / 300.0, 4)] {
            let free = FreeModel::new(&config, &config.whisker, &model, period).unwrap();
            assert_eq!(free.substeps, substeps, "period {period}");
            let h = free.stepper.dt;
            assert!((h * substeps as f64 - period).abs() < 1e-15 && h <= MAX_DT);
            let raised = free.model.modes().unwrap().frequencies[0];
            // The implicit step h elongates the raised mode's period back to the true one.
            let omega_h = 2.0 * std::f64::consts::PI * raised * h;
            let numerical = 2.0 * (0.5 * omega_h).atan() / (2.0 * std::f64::consts::PI * h);
            assert!(
                (numerical / f1 - 1.0).abs() < 1e-9,
                "{numerical} Hz vs {f1} Hz"
            );
        }
    }
}
