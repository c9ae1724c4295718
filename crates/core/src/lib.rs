//! Whisker beam mechanics and a segment-chain whisker simulator.
#![warn(missing_docs)]

pub mod beam;
pub mod error;

pub use error::{Error, Result};
