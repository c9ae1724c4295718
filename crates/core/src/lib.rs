//! Whisker beam mechanics and a segment-chain whisker simulator.
//!
//! - [`beam`]: continuum Euler–Bernoulli references (small-deflection cubic, elastica,
//!   clamped–free frequencies).
//! - [`whisker`]: the whisker description and presets.
//! - [`chain`]: the segment-chain discretisation ([`chain::Model`]).
//! - [`dynamics`]: the time step, one file per stage: settings, inputs, state, scratch,
//!   kinematics, the articulated-body solve, [`contact`] and the step that runs them.
//! - [`sensors`]: the contract's observation channels.
//! - [`batch`]: many states stepped in parallel against one model.
#![warn(missing_docs)]

pub mod array;
pub mod batch;
pub mod beam;
pub mod chain;
pub mod dynamics;
pub mod error;
pub mod inverse;
pub mod objects;
mod planar;
pub mod rng;
pub mod scenes;
pub mod sensors;
mod signal;
pub mod sim;
pub mod statics;
pub mod validate;
pub mod whisker;

pub use chain::{Discretisation, Model};
pub use dynamics::contact;
pub use dynamics::{BaseMotion, Inputs, Integrator, PointLoad, State, Stepper, Workspace};
pub use error::{Error, Result};
pub use whisker::{Whisker, WhiskerParams};
