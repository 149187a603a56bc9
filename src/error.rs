//! The one error type of the core. Every fallible public function returns
//! [`Result<T>`]; the Python bindings map each variant to one exception class
//! (`src/python/errors.rs`) and the CLI prints it as one line.

use std::path::PathBuf;

/// Everything that can go wrong in slam2world, with the data that says what.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An array or argument has the wrong shape or length.
    #[error("{what}: expected {expected}, got {got}")]
    ShapeMismatch {
        /// Which argument.
        what: String,
        /// The shape that was expected, e.g. `(N, 3)`.
        expected: String,
        /// The shape that was given.
        got: String,
    },
    /// A NaN or infinity where a finite number is required.
    #[error("{what}: non-finite value at index {index}")]
    NonFinite {
        /// Which argument.
        what: String,
        /// Index of the first offending element (row for arrays of rows).
        index: usize,
    },
    /// Fewer items than the operation needs.
    #[error("{what}: need at least {need}, got {got}")]
    TooFew {
        /// What was counted.
        what: String,
        /// The minimum.
        need: usize,
        /// What was given.
        got: usize,
    },
    /// The input is well formed but its geometry does not determine the answer
    /// (coincident or collinear points, zero motion, …). `value` is the
    /// diagnostic that decided it (a spread, an eigen-gap, a singular value).
    #[error("degenerate input: {reason} (diagnostic {value:.3e})")]
    Degenerate {
        /// What is degenerate and why the result would be undefined.
        reason: String,
        /// The diagnostic value that was below its threshold.
        value: f64,
    },
    /// An argument value outside its domain (negative resolution, unknown method, …).
    #[error("invalid {what}: {reason}")]
    InvalidArgument {
        /// Which argument.
        what: String,
        /// Why it is invalid.
        reason: String,
    },
    /// A query outside the range the data covers (interpolation outside the
    /// trajectory, across a gap, …).
    #[error("{what}: {reason}")]
    OutOfRange {
        /// What was queried.
        what: String,
        /// Why it cannot be answered.
        reason: String,
    },
    /// A file could not be opened, read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// A text or binary file whose content is malformed.
    #[error("{}:{line}: {reason}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line number (0 when the format has no lines).
        line: usize,
        /// What was wrong.
        reason: String,
    },
    /// A result that would hold more items than a bound allows (a pruned
    /// octree leaf expanded voxel by voxel, a grid over a huge extent);
    /// refused before anything is allocated.
    #[error("{what}: {count} items exceed the limit of {limit}")]
    TooLarge {
        /// What would have been built.
        what: String,
        /// How many items it would hold.
        count: u64,
        /// The bound.
        limit: u64,
    },
    /// An MCAP log that cannot be read or decoded.
    #[error("{}: {reason}", path.display())]
    Mcap {
        /// The log file.
        path: PathBuf,
        /// Topic, channel or record the problem was found in, when known.
        reason: String,
    },
}

/// Result with the crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// Shorthand for [`Error::InvalidArgument`].
    pub fn invalid(what: impl Into<String>, reason: impl Into<String>) -> Self {
        Error::InvalidArgument {
            what: what.into(),
            reason: reason.into(),
        }
    }

    /// Shorthand for [`Error::Io`].
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }

    /// Shorthand for [`Error::Parse`].
    pub fn parse(path: impl Into<PathBuf>, line: usize, reason: impl Into<String>) -> Self {
        Error::Parse {
            path: path.into(),
            line,
            reason: reason.into(),
        }
    }
}

/// Checks that a flat slice holds rows of `cols` values and that all are finite.
/// Returns the number of rows.
pub fn check_rows(what: &str, data: &[f64], cols: usize) -> Result<usize> {
    if data.len() % cols != 0 {
        return Err(Error::ShapeMismatch {
            what: what.into(),
            expected: format!("(N, {cols})"),
            got: format!("{} values", data.len()),
        });
    }
    if let Some(i) = data.iter().position(|v| !v.is_finite()) {
        return Err(Error::NonFinite {
            what: what.into(),
            index: i / cols,
        });
    }
    Ok(data.len() / cols)
}
