//! The scratch memory of a step ([`Workspace`]): per-segment quantities, the solver's vectors and
//! the contact solver's candidates ([`Scratch`]). A state's evolution lives in
//! [`State`](super::State); this is what a step computes on the way.

use super::state::State;
use crate::chain::Model;

/// Per-segment scratch, kept together for locality.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Seg {
    /// Unit vector along the chord (cos φ, sin φ).
    pub(crate) dir: [f64; 2],
    /// Spatial velocity about the joint: (ω, vx, vy of the joint point).
    pub(crate) vel: [f64; 3],
    /// Velocity-product acceleration of the joint (its first component is always 0).
    pub(crate) bias: [f64; 2],
    /// First row of the spatial inertia about the joint: (J + m|c|², -m·cy, m·cx); the rest is
    /// (m, 0, m).
    pub(crate) inertia: [f64; 3],
    /// External spatial force about the joint.
    pub(crate) f_ext: [f64; 3],
    /// Articulated-body quantities: `U = IA·S`, `1/D`, `u`.
    pub(crate) u_vec: [f64; 3],
    pub(crate) inv_d: f64,
    pub(crate) u: f64,
    /// Spatial acceleration about the joint.
    pub(crate) acc: [f64; 3],
}

/// Scratch memory for stepping one state at a time; reuse it across steps and states.
///
/// Per-segment spatial quantities are expressed about the segment's proximal joint (node `i`)
/// with world-parallel axes, so every revolute joint has the motion vector `(1, 0, 0)`.
#[derive(Debug, Clone)]
pub struct Workspace {
    pub(crate) n: usize,
    /// Joint angles and rates at which kinematics was last evaluated, `[N]`.
    pub(crate) q: Vec<f64>,
    pub(crate) v: Vec<f64>,
    /// Node positions, world frame, m: `[N+1][2]`.
    pub(crate) node: Vec<[f64; 2]>,
    /// Per-segment scratch `[N]`.
    pub(crate) seg: Vec<Seg>,
    /// Joint torque and armature handed to the solver: `[N]`.
    pub(crate) tau: Vec<f64>,
    pub(crate) arm: Vec<f64>,
    /// Articulated inertia and bias force of body 0 (for the base reaction).
    pub(crate) ia0: [f64; 6],
    pub(crate) pa0: [f64; 3],
    /// Solved joint accelerations `[N]`.
    pub(crate) qdd: Vec<f64>,
    /// Intermediate angles and rates at b = 0 (the linearisation point of the springs) `[N]`.
    pub(crate) q_lin: Vec<f64>,
    pub(crate) v_lin: Vec<f64>,
    /// Process-noise forces drawn for the current step, world frame, N: `[N][2]`.
    pub(crate) noise: Vec<[f64; 2]>,
    /// Whether [`Self::noise`] holds the forces of a step being taken in substeps, which every
    /// substep keeps instead of drawing its own.
    pub(super) noise_held: bool,
    /// Contact scratch.
    pub(crate) contacts: Scratch,
    /// Geometric iterations used by the last step.
    pub iterations: usize,
    /// The state at the start of the step being taken (restored if the step fails).
    pub(super) backup: Option<State>,
    /// The state at the start of a step taken in substeps (restored if a substep fails).
    pub(super) substep_backup: Option<State>,
    /// The states at the start of a substep and of its halves (taken again in halves at an
    /// impact or a release), one per level of the bisection.
    pub(super) event_pool: Vec<State>,
    /// The chain fitted to a step's first mode: the source chain, the step and the fitted copy.
    pub(super) fitted: Option<Box<super::fitted::Fitted>>,
}

impl Workspace {
    /// Scratch for a model of `model.n` segments.
    pub fn new(model: &Model) -> Workspace {
        let n = model.n;
        Workspace {
            n,
            q: vec![0.0; n],
            v: vec![0.0; n],
            node: vec![[0.0; 2]; n + 1],
            seg: vec![Seg::default(); n],
            tau: vec![0.0; n],
            arm: vec![0.0; n],
            ia0: [0.0; 6],
            pa0: [0.0; 3],
            qdd: vec![0.0; n],
            q_lin: vec![0.0; n],
            v_lin: vec![0.0; n],
            noise: vec![[0.0; 2]; n],
            noise_held: false,
            contacts: Scratch::new(n),
            iterations: 0,
            backup: None,
            substep_backup: None,
            event_pool: Vec::new(),
            fitted: None,
        }
    }

    /// Node positions of the last evaluated configuration, world frame, m (`[N+1]`).
    pub fn nodes(&self) -> &[[f64; 2]] {
        &self.node
    }

    /// Unit vector along segment `seg`'s chord in the last evaluated configuration.
    pub fn direction(&self, seg: usize) -> [f64; 2] {
        self.seg[seg].dir
    }

    /// World position of the point `along` metres down segment `seg`'s chord.
    pub fn point(&self, seg: usize, along: f64) -> [f64; 2] {
        let (p, d) = (self.node[seg], self.seg[seg].dir);
        [p[0] + along * d[0], p[1] + along * d[1]]
    }

    /// World velocity of the material point of segment `seg` at world position `p`.
    pub fn point_velocity(&self, seg: usize, p: [f64; 2]) -> [f64; 2] {
        let [w, vx, vy] = self.seg[seg].vel;
        let o = self.node[seg];
        [vx - w * (p[1] - o[1]), vy + w * (p[0] - o[0])]
    }

    /// Adds a world-frame force `f` acting at world point `p` of segment `seg`.
    pub fn add_force(&mut self, seg: usize, p: [f64; 2], f: [f64; 2]) {
        let o = self.node[seg];
        let e = &mut self.seg[seg].f_ext;
        e[0] += (p[0] - o[0]) * f[1] - (p[1] - o[1]) * f[0];
        e[1] += f[0];
        e[2] += f[1];
    }

    /// Spatial inertia of segment `i` about its joint, packed (after kinematics).
    pub(super) fn inertia(&self, model: &Model, i: usize) -> [f64; 6] {
        let [a, b, c] = self.seg[i].inertia;
        let m = model.mass[i];
        [a, b, c, m, 0.0, m]
    }
}

/// Largest number of simultaneous contact candidates handled in one step.
pub const MAX_CONTACTS: usize = 24;

/// One contact candidate.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Candidate {
    /// Segment and whisker point (world).
    pub(super) seg: usize,
    pub(super) point: [f64; 2],
    /// Whether the point is the segment's far node (not a point within the segment).
    pub(super) node: bool,
    /// Arc length of the point.
    pub(super) s: f64,
    /// Gap at the evaluation point, m.
    pub(super) gap: f64,
    /// Normal (object → whisker) and tangent.
    pub(super) n: [f64; 2],
    pub(super) t: [f64; 2],
    /// Constant parts of the end-of-step gap (m) and tangential slip velocity (m/s).
    pub(super) c_n: f64,
    pub(super) c_t: f64,
    /// Friction coefficient and object index.
    pub(super) mu: f64,
    pub(super) object: usize,
    /// Normal relative velocity of whisker and object at the end of the step (b = 0), m/s.
    pub(super) c_v: f64,
    /// End-of-step gap predicted without contact force, m, and whether it calls for contact.
    pub(super) g_pred: f64,
    pub(super) active: bool,
    /// A new contact (the object carried no force in the previous step): an impulse.
    pub(super) impact: bool,
    /// Forces.
    pub(super) lambda_n: f64,
    pub(super) lambda_t: f64,
}

/// Preallocated contact scratch, part of a [`Workspace`].
#[derive(Debug, Clone)]
pub struct Scratch {
    pub(crate) count: usize,
    pub(super) cand: [Candidate; MAX_CONTACTS],
    /// Generalised forces of unit normal and tangential forces: `[2·MAX_CONTACTS][N]`.
    pub(super) jac: Vec<f64>,
    /// `(M + A)⁻¹` applied to them: `[2·MAX_CONTACTS][N]`.
    pub(super) resp: Vec<f64>,
    /// Delassus matrix `[2·MAX_CONTACTS]²` (rows/columns: n0, t0, n1, t1, …).
    pub(super) w: Vec<f64>,
    /// Scratch for one application of `(M + A)⁻¹`: `u` per joint.
    pub(super) u: Vec<f64>,
    /// Change of the articulated bias force at the base per row of `resp`: `[2·MAX_CONTACTS]`.
    pub(super) base_resp: Vec<[f64; 3]>,
    /// End-of-step angles and rates at b = 0 (`q_end = q0 + cq·b`, `v_end = v0 + cv·b`).
    pub(super) q0: Vec<f64>,
    pub(super) v0: Vec<f64>,
    /// Joint accelerations caused by the last solve's impacts `[N]` (integrated as impulses), and
    /// by its lasting contacts (integrated like other forces; kept to drop them at release).
    pub(crate) acc: Vec<f64>,
    pub(crate) acc_lasting: Vec<f64>,
    /// Correction of the end-of-step angles that removes any remaining penetration `[N]`.
    pub(crate) position_fix: Vec<f64>,
    /// Whether `acc`, `acc_lasting` or `position_fix` has been added to since it was last zeroed.
    pub(super) forced: bool,
    /// Dense scratch of the pivoting solve, `[MAX_CONTACTS][MAX_CONTACTS + 1]` (only the part in
    /// use is written), and of post-stabilisation's compliance matrix, `[MAX_CONTACTS]²`.
    pub(super) dense: Vec<f64>,
    pub(super) stat: Vec<f64>,
}

impl Scratch {
    /// Scratch for an `n`-segment model.
    pub fn new(n: usize) -> Scratch {
        Scratch {
            count: 0,
            cand: [Candidate::default(); MAX_CONTACTS],
            jac: vec![0.0; 2 * MAX_CONTACTS * n],
            resp: vec![0.0; 2 * MAX_CONTACTS * n],
            w: vec![0.0; 4 * MAX_CONTACTS * MAX_CONTACTS],
            u: vec![0.0; n],
            base_resp: vec![[0.0; 3]; 2 * MAX_CONTACTS],
            q0: vec![0.0; n],
            v0: vec![0.0; n],
            acc: vec![0.0; n],
            acc_lasting: vec![0.0; n],
            position_fix: vec![0.0; n],
            forced: false,
            dense: vec![0.0; MAX_CONTACTS * (MAX_CONTACTS + 1)],
            stat: vec![0.0; MAX_CONTACTS * MAX_CONTACTS],
        }
    }
}
