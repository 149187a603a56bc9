//! The one error type of the core. Every fallible public function returns
//! [`Result<T>`]; the Python bindings map each variant to one exception class
//! (`src/python/errors.rs`) and the CLI prints it as one line.

use std::path::PathBuf;

mod bag;
mod log;
mod wire;

pub use bag::{BagError, ContainerError};
pub use log::LogError;
pub use wire::WireError;

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
    /// A yaw-only fit (`4dof`, `scale+4dof`) of an estimate whose z axis is
    /// visibly not along gravity: the full-rotation Sim(3) fit of the same
    /// pairs tilts the estimate's z axis by `angle_deg` from the reference
    /// vertical, more than `threshold_deg`.
    #[error(
        "the estimate's gravity is tilted: the Sim(3) fit turns its z axis {angle_deg:.3} deg \
         from the reference vertical, above the {threshold_deg} deg a {dof} fit allows \
         (it assumes both frames have z along gravity); use dof=\"sim3\""
    )]
    GravityTilted {
        /// The degrees of freedom that were asked for (`"4dof"`, `"scale+4dof"`).
        dof: String,
        /// Angle between the estimate's z axis, mapped by the Sim(3) fit, and the reference z axis, degrees.
        angle_deg: f64,
        /// The largest angle accepted, degrees.
        threshold_deg: f64,
    },
    /// The reference positions of the fitted pairs stay within their noise
    /// of each other: there is no motion to fit a transform to
    /// (`align::checks`).
    #[error(
        "the reference does not move: its positions spread {spread_m:.6} m (rms about their \
         centroid, {n} pairs), at most {threshold} times its noise of {noise_m:.6} m \
         ({noise_source}); a transform fitted to it would fit the noise"
    )]
    StaticReference {
        /// rms distance of the reference positions to their centroid, metres.
        spread_m: f64,
        /// The reference noise (3-D rms), metres.
        noise_m: f64,
        /// Where the noise came from (stated, or estimated how).
        noise_source: String,
        /// The smallest spread-over-noise ratio accepted.
        threshold: f64,
        /// Pairs looked at.
        n: usize,
    },
    /// The fit explains almost none of the reference's spread: its rmse is
    /// close to the rms spread of the reference about its centroid
    /// (`align::checks`).
    #[error(
        "the fit explains almost none of the reference's motion: rmse {rmse_m:.6} m is \
         {ratio:.3} of the reference's rms spread of {spread_m:.6} m about its centroid \
         (refused from {threshold}); the two trajectories are not one motion in two frames \
         (mixed frames such as ECEF beside ENU, another reference, wrong time pairs, or a \
         dof that cannot map one frame onto the other)"
    )]
    UnexplainedSpread {
        /// Fit residual rms, metres.
        rmse_m: f64,
        /// rms distance of the reference positions to their centroid, metres.
        spread_m: f64,
        /// `rmse_m / spread_m`.
        ratio: f64,
        /// The ratio from which a fit is refused.
        threshold: f64,
    },
    /// A fit that estimates the scale left it at 1 (within `threshold`)
    /// while the residual is far above the noise: nothing was fitted
    /// (`align::checks`).
    #[error(
        "nothing was fitted: the scale stayed at {scale} ({scale_change:.3e} from 1, below \
         {threshold:e}) while the fit rmse of {rmse_m:.6} m is far above the reference noise \
         of {noise_m:.6} m ({noise_source}); the estimate came back as it went in"
    )]
    NothingFitted {
        /// The fitted scale.
        scale: f64,
        /// `|scale − 1|`.
        scale_change: f64,
        /// The smallest change of the scale from 1 accepted.
        threshold: f64,
        /// Fit residual rms, metres.
        rmse_m: f64,
        /// The reference noise (3-D rms), metres.
        noise_m: f64,
        /// Where the noise came from.
        noise_source: String,
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
    /// Too few SLAM stamps matched a reference pose by time. The spans and the
    /// likely cause (a unit mix-up, a constant offset) say why.
    #[error(
        "{matched} SLAM stamps match a reference pose within max_diff {max_diff} s (offset {offset} s), \
         need {need}: SLAM {slam_span}, reference {reference_span}; {cause}"
    )]
    Unmatched {
        /// Pairs found.
        matched: usize,
        /// Pairs needed.
        need: usize,
        /// First and last SLAM stamp, as text.
        slam_span: String,
        /// First and last reference stamp, as text.
        reference_span: String,
        /// The matching window, seconds.
        max_diff: f64,
        /// Seconds added to the SLAM stamps.
        offset: f64,
        /// The likely cause.
        cause: String,
    },
    /// A message of a log that does not decode: the file, the topic, the
    /// message's index on its topic and log time, and what was wrong where.
    #[error("{}: topic {topic}: message {index} (log time {log_time} ns): {source}", path.display())]
    Decode {
        /// The log file.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// Index of the message among the messages of its topic.
        index: usize,
        /// Its log time, nanoseconds.
        log_time: u64,
        /// What was wrong, with the byte offset in the message.
        #[source]
        source: WireError,
    },
    /// A binary file (COLMAP `.bin`, NumPy `.npy`) whose bytes at `offset` do
    /// not hold what the format requires there: a record cut short, a count
    /// larger than the bytes left, an unknown enumeration value.
    #[error("{}: byte {offset}: {what}: expected {expected}, found {found}", path.display())]
    BinaryFormat {
        /// The file.
        path: PathBuf,
        /// Byte offset from the start of the file where the bad field starts.
        offset: u64,
        /// Which field (e.g. `image 3 num_points2D`).
        what: String,
        /// What the format allows there.
        expected: String,
        /// What the file holds.
        found: String,
    },
    /// A reconstruction folder (COLMAP model, DROID-SLAM arrays) whose files do
    /// not make one consistent model: files missing, two flavours side by side,
    /// arrays whose lengths disagree, records that refer to missing records.
    #[error("{}: {reason}", path.display())]
    Reconstruction {
        /// The folder, or the file the inconsistency was found in.
        path: PathBuf,
        /// What is missing or inconsistent, with the ids and counts involved.
        reason: String,
    },
    /// A GNSS fix or geodetic position with a field outside its domain (NaN
    /// latitude, latitude beyond ±90°, non-finite or decreasing time, a
    /// covariance that is not one).
    #[error("{what} {index}: {field} = {value}, expected {expected}")]
    InvalidFix {
        /// What holds the value (`fix`, `origin`, `position`).
        what: String,
        /// Index of the fix or position (0 for a single value).
        index: usize,
        /// The field (`time`, `latitude`, `longitude`, `altitude`, `covariance`).
        field: String,
        /// The value found.
        value: f64,
        /// What was expected.
        expected: String,
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
    /// A ROS 1 bag, a rosbag2 folder or a rosbag2 `.db3` file that cannot be read.
    #[error("{}{}: {reason}", path.display(), bag::at_offset(*offset))]
    Bag {
        /// The bag file (or the rosbag2 folder, or the file of the folder at fault).
        path: PathBuf,
        /// Byte offset in `path` of the record at fault, when the format has offsets.
        offset: Option<u64>,
        /// What was expected and what was found.
        reason: BagError,
    },
    /// A log whose topics cannot give what was asked (any container): a
    /// named topic that is missing, of a type slam2world does not decode or
    /// cannot read in that role, samples that make no trajectory.
    #[error("{}: {reason}", path.display())]
    Log {
        /// The log file (or rosbag2 folder).
        path: PathBuf,
        /// The topic, its type and what was expected (boxed: it is the
        /// largest reason, and every `Result` carries the error's size).
        reason: Box<LogError>,
    },
    /// A path that is no log slam2world reads (see `io::container::detect`).
    #[error("{}: {reason}", path.display())]
    Container {
        /// The path given.
        path: PathBuf,
        /// What was found there.
        reason: ContainerError,
    },
    /// An output that would destroy or misuse what is at its path: an input
    /// of the same run, a folder, a block device (see `io::atomic`).
    #[error("{}: {reason}", path.display())]
    Output {
        /// The output path given.
        path: PathBuf,
        /// What is there and why it is not written.
        reason: String,
    },
    /// An allocation the operation needs was refused (an address-space limit,
    /// memory exhausted): the operation is abandoned, nothing else is lost.
    #[error("{what}: cannot allocate {bytes} bytes")]
    OutOfMemory {
        /// What the memory was for.
        what: String,
        /// Bytes asked for.
        bytes: u128,
    },
    /// The run was stopped by SIGINT (Ctrl-C) or SIGTERM (`interrupt`);
    /// the outputs of the run were not written, the previous ones are intact.
    #[error("interrupted by {}: no output written", signal_name(*signal))]
    Interrupted {
        /// The signal number (2 SIGINT, 15 SIGTERM).
        signal: i32,
    },
}

/// `SIGINT`, `SIGTERM` or `signal N` (the name [`Error::Interrupted`] gives).
pub fn signal_name(signal: i32) -> String {
    match signal {
        2 => "SIGINT".into(),
        15 => "SIGTERM".into(),
        s => format!("signal {s}"),
    }
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

    /// Shorthand for [`Error::Log`].
    pub fn log(path: &std::path::Path, reason: LogError) -> Self {
        Error::Log {
            path: path.to_path_buf(),
            reason: Box::new(reason),
        }
    }

    /// [`LogError::Samples`]: the samples of `topic` in `path` make no
    /// trajectory (or IMU stream), and why.
    pub fn samples(path: &std::path::Path, topic: &str, what: String) -> Self {
        Error::log(
            path,
            LogError::Samples {
                topic: topic.to_string(),
                what,
            },
        )
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

/// A number for a message: plain where it is short, in exponent form where
/// its plain form would be long (a stamp of `1e300` must not print 300 digits).
pub fn num(x: f64) -> String {
    if x == 0.0 || (1e-6..1e15).contains(&x.abs()) {
        // Six decimals at most (a sum of tenths prints as 3.9, not 3.9000000000000004).
        let s = format!("{x:.6}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        if s == "-0" || s.is_empty() {
            format!("{x:e}")
        } else {
            s.to_string()
        }
    } else {
        format!("{x:e}")
    }
}

/// Longest piece of user text quoted in a message, characters.
pub const QUOTE_MAX: usize = 80;

/// `text` quoted for a message, cut to [`QUOTE_MAX`] characters (with the full
/// length said) so that a bad 200 KB token does not become a 200 KB line.
pub fn cut(text: &str) -> String {
    let n = text.chars().count();
    if n <= QUOTE_MAX {
        format!("{text:?}")
    } else {
        let head: String = text.chars().take(QUOTE_MAX).collect();
        format!("{head:?}… ({n} characters)")
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_and_quotes_stay_short() {
        assert_eq!(num(0.1 + 0.2), "0.3");
        assert_eq!(num(3.9000000000000004), "3.9");
        assert_eq!(num(-50.0), "-50");
        assert_eq!(num(0.0), "0");
        assert_eq!(num(1e300), "1e300");
        assert_eq!(num(1.5e-9), "1.5e-9");
        let long = "x".repeat(200_000);
        let q = cut(&long);
        assert!(q.len() < 120 && q.contains("200000 characters"), "{q}");
        assert_eq!(cut("abc"), "\"abc\"");
    }
}
