//! One whisker's dynamic state ([`State`]) and the report of its contact ([`ContactReport`]).

use super::inputs::BaseMotion;
use crate::chain::Model;
use crate::rng::Rng;

/// One whisker's dynamic state. Cheap to clone (`clone_from` reuses the buffer); many states
/// share one [`Model`].
#[derive(Debug, PartialEq)]
pub struct State {
    /// Simulated time, s.
    pub t: f64,
    /// Base rotation at time `t`.
    pub base: BaseMotion,
    /// `[q | q̇ | q̈ | q̇_prev | q̈_contact]`, each `[N]`: joint angles (rad), rates (rad/s),
    /// accelerations (rad/s², without contact impulses), the rates one step earlier, and the part
    /// of the accelerations due to lasting contact forces.
    pub(super) x: Vec<f64>,
    /// Base wrench at the previous step's intermediate time (for extrapolation to `t`).
    pub(super) wrench_alpha: [f64; 3],
    /// Wrench the base applies to the whisker at time `t`, world frame: (moment N·m, fx N, fy N).
    pub base_wrench: [f64; 3],
    /// Contact during the last step, if any (the contact nearest the base).
    pub contact: Option<ContactReport>,
    /// Objects that carried contact force in the last step (bit k for object k).
    pub(super) touching: u64,
    /// Features of the whisker that carried contact force in the last step (bit 2i for a point
    /// within segment i, 2i + 1 for its far node; segments 0..63).
    pub(super) held: u128,
    /// The state's own random stream (process noise).
    pub rng: Rng,
}

impl Clone for State {
    fn clone(&self) -> Self {
        State {
            t: self.t,
            base: self.base,
            x: self.x.clone(),
            wrench_alpha: self.wrench_alpha,
            base_wrench: self.base_wrench,
            contact: self.contact,
            touching: self.touching,
            held: self.held,
            rng: self.rng.clone(),
        }
    }

    /// Copies `source` into `self` without allocating when the segment counts agree.
    fn clone_from(&mut self, source: &Self) {
        self.t = source.t;
        self.base = source.base;
        self.x.clone_from(&source.x);
        self.wrench_alpha = source.wrench_alpha;
        self.base_wrench = source.base_wrench;
        self.contact = source.contact;
        self.touching = source.touching;
        self.held = source.held;
        self.rng.clone_from(&source.rng);
    }
}

impl State {
    /// The whisker at rest in its rest shape at t = 0, with a seeded random stream.
    pub fn at_rest(model: &Model, seed: u64) -> State {
        let n = model.n;
        let mut x = vec![0.0; 5 * n];
        x[..n].copy_from_slice(&model.rest);
        State {
            t: 0.0,
            base: BaseMotion::default(),
            x,
            wrench_alpha: [0.0; 3],
            base_wrench: [0.0; 3],
            contact: None,
            touching: 0,
            held: 0,
            rng: Rng::new(seed),
        }
    }
    /// Base wrench at the last step's intermediate time `t - αf·dt` (see
    /// [`Stepper::alpha_f`](super::Stepper::alpha_f)), where the method balances forces;
    /// [`State::base_wrench`] is extrapolated from it to `t`.
    pub fn base_wrench_intermediate(&self) -> [f64; 3] {
        self.wrench_alpha
    }
    /// Segment count.
    pub fn n(&self) -> usize {
        self.x.len() / 5
    }
    /// Joint angles, rad.
    pub fn q(&self) -> &[f64] {
        &self.x[..self.n()]
    }
    /// Joint angles, mutable (call [`initialize`](super::initialize) afterwards to make
    /// accelerations consistent).
    pub fn q_mut(&mut self) -> &mut [f64] {
        let n = self.n();
        &mut self.x[..n]
    }
    /// Joint rates, rad/s.
    pub fn v(&self) -> &[f64] {
        let n = self.n();
        &self.x[n..2 * n]
    }
    /// Joint rates, mutable.
    pub fn v_mut(&mut self) -> &mut [f64] {
        let n = self.n();
        &mut self.x[n..2 * n]
    }
    /// Joint accelerations, rad/s².
    pub fn qdd(&self) -> &[f64] {
        let n = self.n();
        &self.x[2 * n..3 * n]
    }
}

/// The contact nearest the whisker's base after a step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactReport {
    /// Contact point on the whisker's axis, world frame, m.
    pub point: [f64; 2],
    /// Arc length from the base to the contact point, m.
    pub s: f64,
    /// Force the object applies to the whisker there, world frame, N.
    pub force: [f64; 2],
    /// Contact normal (from the object towards the whisker), world frame.
    pub normal: [f64; 2],
    /// Normal force, N (≥ 0).
    pub normal_force: f64,
    /// Tangential (friction) force along the normal turned +90°, N (|·| ≤ μ·normal force).
    pub tangential_force: f64,
    /// Number of contacts carrying force.
    pub count: usize,
    /// Index of the object touched.
    pub object: usize,
}
