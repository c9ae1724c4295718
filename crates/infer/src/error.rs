//! Errors of the inference library.

/// What can go wrong while simulating, fitting or estimating.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A simulation failed.
    #[error("simulation of d = {d} m, v = {v} m/s failed")]
    Simulation {
        /// Distance, m.
        d: f64,
        /// Speed, m/s.
        v: f64,
        /// The simulator's error.
        #[source]
        source: vibrissa_core::Error,
    },
    /// A run of a scenario family failed.
    #[error("simulation of {params} failed")]
    Run {
        /// The run's unknowns, `key = value, …`.
        params: String,
        /// The simulator's error.
        #[source]
        source: vibrissa_core::Error,
    },
    /// A scenario file or a folder of labelled recordings could not be read, or a scenario does not
    /// fit the schema.
    #[error(transparent)]
    Scenario(#[from] vibrissa_io::Error),
    /// An observation does not fit the experiment or the method.
    #[error("unusable observation: {0}")]
    Observation(String),
    /// A recording is unusable: a missing column, an irregular clock, a non-finite value (the
    /// message names the file and the row).
    #[error("{0}")]
    Recording(String),
    /// A setting of a method is out of its range.
    #[error("invalid setting: {0}")]
    Setting(String),
    /// A method was used before it was fitted, or with unusable training data.
    #[error("{method}: {detail}")]
    Fit {
        /// The method's name.
        method: String,
        /// What was wrong.
        detail: String,
    },
    /// A calibration could not be completed (no convergence, recordings that do not simulate).
    #[error("calibration: {0}")]
    Calibration(String),
    /// An unknown name (experiment, variant, method).
    #[error("unknown {what} `{name}`: choose one of {choices}")]
    Unknown {
        /// What kind of name.
        what: &'static str,
        /// The name given.
        name: String,
        /// The names allowed.
        choices: String,
    },
}

/// Result with [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
