//! The library's error type.

use std::fmt::Display;

/// Everything that can go wrong in `vibrissa-core`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// A parameter is outside its allowed range (or not finite).
    #[error("invalid {name} = {value}: allowed is {allowed}")]
    InvalidParameter {
        /// Dotted name of the parameter, e.g. `whisker.length`.
        name: String,
        /// The offending value, as written.
        value: String,
        /// Human-readable allowed range.
        allowed: String,
    },
    /// A simulation produced a non-finite or runaway value.
    #[error("simulation diverged at t = {t:.6} s: {detail}")]
    Diverged {
        /// Simulated time of the step that failed, in s.
        t: f64,
        /// Where (segment, quantity) and what was seen.
        detail: String,
    },
    /// An iterative solver did not reach its tolerance.
    #[error("{what} did not converge: {detail}")]
    NoConvergence {
        /// The solver.
        what: String,
        /// Residual, iterations, hint.
        detail: String,
    },
    /// A whisker of an array failed.
    #[error("whisker `{name}`: {detail}")]
    Whisker {
        /// The whisker's name.
        name: String,
        /// What went wrong.
        detail: String,
    },
}

impl Error {
    /// Shorthand for [`Error::InvalidParameter`].
    pub fn invalid(
        name: impl Into<String>,
        value: impl Display,
        allowed: impl Into<String>,
    ) -> Self {
        Error::InvalidParameter {
            name: name.into(),
            value: in_exponent_form_if_long(value.to_string()),
            allowed: allowed.into(),
        }
    }
}

/// A number written long in decimals (`0.000000000001`) in exponent form (`1e-12`); any other
/// text as it is.
fn in_exponent_form_if_long(text: String) -> String {
    match text.parse::<f64>() {
        Ok(x) if x != 0.0 && x.is_finite() && text.len() > 10 => format!("{x:e}"),
        _ => text,
    }
}

/// Result alias of the library.
pub type Result<T> = std::result::Result<T, Error>;

/// Checks that `value` is finite and strictly positive.
pub fn check_positive(name: &str, value: f64) -> Result<f64> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(Error::invalid(name, value, "a finite number > 0"))
    }
}

/// Checks that `value` is finite and not negative.
pub fn check_non_negative(name: &str, value: f64) -> Result<f64> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(Error::invalid(name, value, "a finite number >= 0"))
    }
}

/// Checks that `value` is finite.
pub fn check_finite(name: &str, value: f64) -> Result<f64> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(Error::invalid(name, value, "a finite number"))
    }
}

/// A number for a message: four significant digits, in scientific notation when large or small.
pub(crate) fn readable(x: f64) -> String {
    if !x.is_finite() || x == 0.0 || (1e-3..1e4).contains(&x.abs()) {
        format!("{x:.4}")
    } else {
        format!("{x:.3e}")
    }
}

#[cfg(test)]
mod value_tests {
    use super::*;

    #[test]
    fn long_numbers_are_written_in_exponent_form() {
        let e = Error::invalid("dt", 1e-12, "positive");
        assert!(e.to_string().contains("1e-12"), "{e}");
        let e = Error::invalid("whisker.length", 1e-9 * 0.1000000000000000_2, "positive");
        assert!(!e.to_string().contains("0.0000000001"), "{e}");
        assert!(Error::invalid("segments", 1, "2 to 200")
            .to_string()
            .contains("= 1"));
        assert!(Error::invalid("x", 0.023, "").to_string().contains("0.023"));
        assert!(Error::invalid("kind", "blob", "")
            .to_string()
            .contains("blob"));
    }
}
