//! Shape recognition: which object, of several classes, struck the whiskers, and its pose.
//!
//! A [`ShapeFamily`] is one scenario family per object class (each with its own pose unknowns:
//! position, rotation, size, speed), all struck past the same array of whiskers. The built-in
//! `e3` ([`e3`]) is four classes — a wall's edge, a box, a circular peg, a triangle — moving past
//! a fan of five whiskers, read with one, three or five of them. An estimator answers a posterior
//! over the classes and, for the most probable class, its pose with intervals
//! ([`ShapeEstimate`]); several whiskers are read jointly, as one recording.

mod bank;
mod batch;
mod between;
pub mod e3;
mod estimator;
mod evaluate;
mod family;
mod filter;
mod forced;
mod method;
mod mix;
mod off_nominal;
mod online;
mod refine;
mod separation;
mod series_noise;

pub use bank::{CleanRuns, ShapeBank, BANK_PER_CLASS};
pub use batch::{check_recordings, estimate_batch, Batch, BatchOptions, DEFAULT_TRAINING};
pub use estimator::{ShapeEstimate, ShapeKrr};
pub use evaluate::{
    evaluate_shapes, evaluated_draws, ClassPose, PoseScore, ReliabilityBin, RunResult,
    ShapeEvaluation, ShapeSettings, SubsetResult, Trace,
};
pub use family::{Class, ShapeFamily, ShapeSample, SHAPE_BUILTINS};
pub use filter::{ShapePf, SHAPE_PF_PARTICLES, SHAPE_PF_TRAINING};
pub use forced::whitened;
pub use method::{
    check_shape_method, fit_shape_method, has_filter, needs_clean_runs, ShapeMethod,
    DEFAULT_SHAPE_METHODS, FILTER_METHODS, SHAPE_METHODS,
};
pub use mix::ShapeMix;
pub use online::{Online, ShapeEsn};
pub use separation::{
    forced_log_likelihood, nearest_from, normal_tail, search_every_class, separations, Separation,
};
