//! Time stepping of the segment chain.
//!
//! The equations of motion in joint coordinates are
//! `M(q) q̈ + c(q, q̇) = -K (q - q_rest) - D q̇ + τ_ext`, with `K` and `D` diagonal (one spring and
//! one damper per joint). They are integrated by the Hilber–Hughes–Taylor (HHT-α) member of the
//! generalized-α family: second-order accurate, unconditionally stable for the linear
//! spring–damper part, with a little high-frequency dissipation set by `rho_inf` (1 = trapezoidal
//! rule). Forces balance at the intermediate time `t_{n+1-αf}`, `αf = (1 - ρ∞)/(1 + ρ∞)`.
//!
//! Why this member: with large rotations and large steps, members that balance forces near the
//! middle of the step (the trapezoidal rule, Chung–Hulbert's αm ≠ 0) let energy grow (×2.6 over
//! 10 s for N = 10 at dt = 1 ms after release from a tip-load shape with W = EI/L²), and
//! stronger high-frequency dissipation overshoots after a kick of the heavily damped stiff modes
//! (see [`DEFAULT_RHO_INF`]); HHT at ρ∞ = 0.99 does neither in those tests.
//!
//! The stiff, linear spring and damper forces are treated implicitly and exactly. The geometric
//! terms (the configuration-dependent mass matrix, velocity-product forces and external forces)
//! are evaluated at the intermediate time from positions and rates predicted without the
//! acceleration terms (which the stiff modes would amplify), and refined by a few fixed-point
//! iterations until the geometry stops moving. Each solve is `(M + A) b = τ` with a diagonal
//! `A`, exactly what the articulated-body algorithm solves with joint "armature", so an iteration
//! is one O(N) recursion and allocates nothing.
//!
//! Spatial vectors are planar and expressed in the world frame about the origin (the whisker
//! base): motion `(ω, vx, vy)`, force `(n, fx, fy)` with `n` the moment about the origin.
//!
//! The step is split by stage, one file each, in pipeline order:
//!
//! - `integrator`: the method's settings ([`Integrator`]) and coefficients ([`Stepper`]);
//! - `inputs`: what drives a step ([`Inputs`]: [`BaseMotion`], [`PointLoad`]s, objects, noise);
//! - `state`: a whisker's dynamic [`State`] and its [`ContactReport`](contact::ContactReport);
//! - `workspace`: the scratch memory of a step ([`Workspace`], with the contact solver's);
//! - `kinematics`: forward kinematics and external forces at the evaluation point;
//! - `articulated`: the articulated-body solve and the base reaction;
//! - [`contact`]: contact forces as constraints, solved on the articulated factorisation;
//! - `single`: one step of the method through these stages, halved where it diverges;
//! - `substeps`: a step near contact taken as substeps
//!   ([`Integrator::contact_substeps`]);
//! - `fitted`: the chain fitted to a long step ([`Integrator::fit_first_mode`]);
//! - `step`: the time step ([`step`], [`initialize`]): taken whole, as substeps, or on the
//!   fitted chain;
//! - `lanes`: steps of up to [`LANES`] states of one model at once, lane by lane the same bits
//!   as [`step`] ([`step_group`], [`step_group_each`] with each state's own objects, whose
//!   contact is solved lane by lane);
//! - `energy`: energies and momentum of a state.

mod articulated;
pub mod contact;
mod energy;
mod fitted;
mod inputs;
mod integrator;
mod kinematics;
mod lanes;
mod reach;
mod single;
mod state;
mod step;
mod substeps;
mod workspace;

pub use energy::{kinetic_energy, momentum, potential_energy};
pub use inputs::{check_loads, BaseMotion, Inputs, PointLoad};
pub use integrator::{
    equal_steps, Integrator, Stepper, DEFAULT_MAX_ITERATIONS, DEFAULT_RHO_INF, DEFAULT_TOLERANCE,
    MAX_CONTACT_SUBSTEPS, MAX_DT,
};
pub use lanes::{lanes_apply, step_group, step_group_each, LaneWorkspace, LANES};
pub use single::{Forcing, NoForcing, MAX_HALVINGS};
pub use state::State;
pub use step::{initialize, step, step_with};
pub use workspace::Workspace;
