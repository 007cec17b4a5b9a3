//! The one error type of `upm-core`.
//!
//! Every fallible public function returns [`Result`]. The Python binding maps each variant to a
//! subclass of `upm.UpmError`, so messages are written for the person who passed the value: they
//! name the parameter, the allowed range and what was received.

/// Errors raised by `upm-core`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// A parameter is outside its allowed range, non-finite, or inconsistent with another one.
    #[error("{name} {message}")]
    Parameter {
        /// The parameter's name as the user spells it (`z`, `part_velocity`, `n2`, ...).
        name: String,
        /// What is allowed and what was received.
        message: String,
    },
    /// Array lengths or shapes that do not fit together.
    #[error("{0}")]
    Shape(String),
    /// An iterative method did not reach its tolerance.
    #[error("{0}")]
    Convergence(String),
}

/// `Result` with [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// A [`Error::Parameter`] for `name`.
    pub fn parameter(name: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Parameter {
            name: name.into(),
            message: message.into(),
        }
    }

    /// The same error with `context` (e.g. the batch index) appended to its message.
    #[must_use]
    pub fn with_context(self, context: &str) -> Self {
        match self {
            Error::Parameter { name, message } => Error::Parameter {
                name,
                message: format!("{message} ({context})"),
            },
            Error::Shape(m) => Error::Shape(format!("{m} ({context})")),
            Error::Convergence(m) => Error::Convergence(format!("{m} ({context})")),
        }
    }
}

/// `Ok(x)` if `x` is finite, else a [`Error::Parameter`] naming `name`.
pub fn finite(name: &str, x: f64) -> Result<f64> {
    if x.is_finite() {
        Ok(x)
    } else {
        Err(Error::parameter(name, format!("must be finite; got {x}")))
    }
}

/// `Ok(x)` if `x` is finite and strictly positive.
pub fn positive(name: &str, x: f64) -> Result<f64> {
    if x.is_finite() && x > 0.0 {
        Ok(x)
    } else {
        Err(Error::parameter(
            name,
            format!("must be finite and > 0; got {x}"),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_the_parameter_and_value() {
        let e = positive("period", -1.0).unwrap_err();
        assert_eq!(e.to_string(), "period must be finite and > 0; got -1");
        let e = finite("b", f64::NAN)
            .unwrap_err()
            .with_context("at index 3");
        assert_eq!(e.to_string(), "b must be finite; got NaN (at index 3)");
    }
}
