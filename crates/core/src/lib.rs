//! Whisker beam mechanics and a segment-chain whisker simulator.
//!
//! The modules, each depending only on those above it:
//!
//! - [`error`]: the library's error type and the checks and number formatting of its messages.
//! - [`rng`]: a small, seeded, portable random number generator.
//! - `planar`: small planar rigid-body helpers (packed spatial inertias, their products and
//!   shifts, a fast `sin_cos`) shared by the model and the step.
//! - [`beam`]: continuum Euler–Bernoulli references (small-deflection cubic, elastica,
//!   clamped–free frequencies).
//! - [`whisker`]: the whisker description and presets.
//! - [`objects`]: rigid objects the whisker can strike, and their motions.
//! - [`chain`]: the segment-chain discretisation, the immutable [`chain::Model`].
//! - [`dynamics`]: the time step, one file per stage: settings, inputs, state, scratch,
//!   kinematics, the articulated-body solve, [`contact`] and the step that runs them, and steps
//!   of many states of one model at once in lanes.
//! - [`statics`]: the chain's static equilibrium under point loads.
//! - [`sensors`]: the contract's observation channels.
//! - [`batch`]: many states stepped in parallel against one model (free ones in lanes).
//! - [`sim`]: whole runs of a scenario, sampled into the contract's time series; [`array`]: arrays
//!   of whiskers striking the same objects.
//! - `signal`: the frequency and damping ratio of a sampled oscillation.
//! - [`scenes`], [`validate`], [`inverse`]: standard scenes, the validation suite and the
//!   beam-theory inverse estimators.
#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod array;
pub mod batch;
pub mod beam;
pub mod chain;
pub mod dynamics;
pub mod error;
pub mod inverse;
pub mod objects;
mod planar;
mod quadrature;
pub mod rng;
pub mod scenes;
pub mod sensors;
mod signal;
pub mod sim;
mod sim_many;
pub mod statics;
pub mod validate;
pub mod whisker;

pub use chain::{Discretisation, Model};
pub use dynamics::contact;
pub use dynamics::{BaseMotion, Inputs, Integrator, PointLoad, State, Stepper, Workspace};
pub use error::{Error, Result};
pub use whisker::{Whisker, WhiskerParams};
