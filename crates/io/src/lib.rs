//! Scenario files and time-series formats for vibrissa.
//!
//! - [`scenario`]: TOML scenario files (and the built-in experiments `e1`, `e2`) read into a
//!   checked [`vibrissa_core::sim::Scenario`], with `key=value` overrides.
//! - [`series`]: time series in the contract's CSV, and as NumPy NPY/NPZ files, with their
//!   metadata in a JSON sidecar file.
//! - [`labelled`]: folders of labelled recordings (`truth.csv` and the recordings it names).
//!
//! Every file is written through a temporary file renamed into place, so a failed write never
//! leaves a partial file. Errors are [`Error`], whose messages name the file, the line or key,
//! and what is allowed.
#![warn(missing_docs)]
#![forbid(unsafe_code)]

mod atomic;
pub mod error;
pub mod labelled;
pub mod scenario;
pub mod series;
pub mod sweep;

pub use error::{Error, Result};
pub use scenario::{load, load_str};
pub use series::Series;
