//! The one error type of the core.
//!
//! Every fallible function of the crate returns [`Result`]. Variants carry the
//! name of the offending argument and what was expected, so a binding layer can
//! turn them into precise exceptions without re-validating anything.

use thiserror::Error;

/// Errors raised by the core on invalid input. The core never panics on user data.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum Error {
    /// An array's shape or length does not match what the call needs.
    #[error("{name}: expected shape {expected}, got {got}")]
    Shape {
        /// Argument name, e.g. `"mask"`.
        name: String,
        /// The expected shape, e.g. `"(240, 320)"`.
        expected: String,
        /// The shape that was passed.
        got: String,
    },
    /// A value is outside its valid range (zero size, negative sigma, ...).
    #[error("{name}: {reason} (got {value})")]
    Value {
        /// Argument name.
        name: String,
        /// The offending value, formatted.
        value: String,
        /// What was expected.
        reason: String,
    },
    /// An array holds NaN or infinity where finite numbers are required.
    #[error("{name}: contains a non-finite value at {position}")]
    NonFinite {
        /// Argument name.
        name: String,
        /// Where the first non-finite value sits, e.g. `"[1, 3]"`.
        position: String,
    },
    /// A 4x4 matrix that should be a rigid transform is not one.
    #[error("{name}: not a rigid transform: {reason}")]
    NotRigid {
        /// Argument name, e.g. `"cam2world"`.
        name: String,
        /// Why it was rejected, with the measured error.
        reason: String,
    },
    /// A mesh id that this scene does not hold.
    #[error("unknown mesh id {id}")]
    UnknownMesh {
        /// The id that was asked for.
        id: u64,
    },
    /// A mesh that cannot be used (face index out of range, no faces, ...).
    #[error("{name}: invalid mesh: {reason}")]
    Mesh {
        /// Argument name.
        name: String,
        /// Why it was rejected.
        reason: String,
    },
}

/// The crate's result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// Builds a [`Error::Value`].
    pub fn value(name: &str, value: impl std::fmt::Display, reason: impl Into<String>) -> Self {
        Error::Value {
            name: name.to_owned(),
            value: value.to_string(),
            reason: reason.into(),
        }
    }

    /// Builds a [`Error::Shape`].
    pub fn shape(name: &str, expected: impl Into<String>, got: impl Into<String>) -> Self {
        Error::Shape {
            name: name.to_owned(),
            expected: expected.into(),
            got: got.into(),
        }
    }
}
