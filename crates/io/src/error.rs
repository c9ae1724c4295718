//! The library's error type.

use std::io;
use std::path::PathBuf;

/// Everything that can go wrong in `vibrissa-io`.
///
/// Every message names its file (or the built-in scenario) and says what is allowed, so that it
/// can be shown to a user as it is.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read, written or renamed into place.
    #[error("cannot {action} `{}`: {error}", path.display())]
    Io {
        /// What was being done (`read`, `write`, …).
        action: &'static str,
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        error: io::Error,
    },
    /// A scenario is not valid TOML, or does not fit the schema (an unknown key, a wrong type).
    /// The message is the TOML parser's: line, column, the offending text and what was expected.
    #[error("{origin}: {message}")]
    Toml {
        /// The scenario file or built-in name.
        origin: String,
        /// The parser's message.
        message: String,
    },
    /// A scenario key given where it does not apply, or missing where it is needed.
    #[error("{origin}: `{field}` {message}")]
    Field {
        /// The scenario file or built-in name.
        origin: String,
        /// Dotted name of the key, e.g. `objects[0].radius`.
        field: String,
        /// What is wrong and what is allowed.
        message: String,
    },
    /// A scenario value outside the range that `vibrissa-core` accepts.
    #[error("{origin}: {error}")]
    Invalid {
        /// The scenario file or built-in name.
        origin: String,
        /// Core's description (parameter, value, allowed range).
        error: vibrissa_core::Error,
    },
    /// An error of `vibrissa-core` that concerns no file.
    #[error(transparent)]
    Core(#[from] vibrissa_core::Error),
    /// A malformed `key=value` override.
    #[error("--set `{text}`: {message}")]
    Override {
        /// The override as given.
        text: String,
        /// What is wrong with it.
        message: String,
    },
    /// A scenario name that is neither a built-in nor an existing file.
    #[error("no scenario `{spec}`: give a built-in name ({}) or the path of a .toml file", builtins.join(", "))]
    UnknownScenario {
        /// What was asked for.
        spec: String,
        /// The built-in names.
        builtins: Vec<String>,
    },
    /// A malformed line in a data file (a time series or a trajectory), or a file that is wrong
    /// as a whole (line 0).
    #[error("{}", located(origin, *line, message))]
    Data {
        /// The file.
        origin: String,
        /// 1-based line number (0 for the file as a whole).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A folder of labelled recordings that does not fit the contract as a whole (no
    /// `truth.csv`, recordings it does not name).
    #[error("{}: {message}", path.display())]
    Labelled {
        /// The folder.
        path: PathBuf,
        /// What is wrong and what to do.
        message: String,
    },
    /// A time series lacks columns that a reader needs.
    #[error("missing column{} {}; the columns present are {}",
        if missing.len() == 1 { "" } else { "s" },
        missing.join(", "),
        if present.is_empty() { "none".to_string() } else { present.join(", ") })]
    MissingColumns {
        /// The columns asked for and not found.
        missing: Vec<String>,
        /// The columns the series has.
        present: Vec<String>,
    },
    /// A sweep's grid is malformed or would name two runs alike.
    #[error("{0}")]
    Grid(String),
    /// A time series that cannot be written as it is (ragged columns, bad names, infinities).
    #[error("invalid time series: {0}")]
    InvalidSeries(String),
    /// An output file name whose extension names no supported format.
    #[error("`{}`: unknown output format; the extension must be one of {}", path.display(), allowed.join(", "))]
    Format {
        /// The file.
        path: PathBuf,
        /// The supported extensions.
        allowed: Vec<String>,
    },
}

impl Error {
    /// The `vibrissa-core` error inside, if this is one.
    pub fn core(&self) -> Option<&vibrissa_core::Error> {
        match self {
            Error::Invalid { error, .. } | Error::Core(error) => Some(error),
            _ => None,
        }
    }

    /// Shorthand for [`Error::Io`].
    pub(crate) fn io(action: &'static str, path: impl Into<PathBuf>, error: io::Error) -> Self {
        Error::Io {
            action,
            path: path.into(),
            error,
        }
    }

    /// Shorthand for [`Error::Data`].
    pub(crate) fn data(origin: &str, line: usize, message: impl Into<String>) -> Self {
        Error::Data {
            origin: origin.to_string(),
            line,
            message: message.into(),
        }
    }
}

/// Result alias of the library.
pub type Result<T> = std::result::Result<T, Error>;

/// `origin, line N: message`, or `origin: message` for the file as a whole (line 0).
fn located(origin: &str, line: usize, message: &str) -> String {
    if line == 0 {
        format!("{origin}: {message}")
    } else {
        format!("{origin}, line {line}: {message}")
    }
}
