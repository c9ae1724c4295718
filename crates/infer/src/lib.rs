//! Estimating the distance and speed of a moving object from whisker time series.
//!
//! The seed paper's two template experiments ([`experiment`]) are restated runs of the `w30`
//! whisker struck by a moving box. [`method`] defines what an estimator is ([`Method`]) and what
//! it returns ([`Estimate`]); [`methods`] holds the estimators: the paper's template method and
//! better ones under the paper's budget (templates only) or a free budget (any simulated
//! training runs except the evaluated ones). [`evaluate()`] runs a whole experiment and scores
//! every method. [`noise`] measures each channel's sensor noise on the recordings themselves;
//! [`check`] tells whether a scenario explains a recording at its estimate; [`randomise`] draws
//! training whiskers around a scenario's. [`calibrate`] fits a whisker's material, follicle,
//! damping and sensor gains to labelled recordings, with the simulator in the loop; [`standin`]
//! makes perturbed "foreign" whiskers and their labelled recordings to check it on.
#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod batch;
pub mod calibrate;
pub mod check;
pub mod contract;
pub mod error;
pub mod evaluate;
pub mod experiment;
pub mod family;
pub mod features;
pub mod lead_in;
pub mod limits;
mod linalg;
pub mod method;
pub mod methods;
pub mod mixture;
pub mod model_error;
pub mod noise;
pub mod pf;
pub mod randomise;
pub mod recording;
mod reference;
pub mod resolution;
pub mod shapes;
pub mod signs;
pub mod standin;
pub mod trained;
pub mod units;
pub mod unknown_start;

pub use error::{Error, Result};
pub use evaluate::{calibration, evaluate, evaluate_with, training_for, Evaluation, MethodResult};
pub use experiment::{Sample, Variant, CHANNELS};
pub use family::Family;
pub use method::{Budget, Estimate, Method, Training};
pub use recording::{Reader, Recording};
pub use trained::Trained;
pub use unknown_start::{evaluate_unknown_start, StartEvaluation};
