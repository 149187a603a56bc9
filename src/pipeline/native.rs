//! What a reconstruction brings besides poses and points, carried in the
//! `Recording` (`pipeline::source`) so that a conversion can pair its
//! frames by name, give its points ray origins, say how its stamps were read,
//! and write the result back in the input's own format.
//!
//! - [`NativeModel`]: the input's own model (a COLMAP model), carried by
//!   `T_world_slam` into the output;
//! - [`FrameInfo`]: a frame's name and pinhole camera;
//! - [`ReconstructionInfo`]: which reader read it, how the frame stamps were
//!   made, what the trajectory reader found (time unit, delimiter);
//! - [`ReferenceFileInfo`]: the reference file beside the input (format,
//!   time unit, pairing by time or by image name).

use std::path::PathBuf;

use crate::error::{Error, Result};
use crate::geometry::{PinholeCamera, Sim3};
use crate::io::colmap::{ColmapFormat, ColmapModel};
use crate::io::text::TextInfo;

/// The kinds of reconstruction slam2world reads (see
/// `pipeline::reconstruction::detect_reconstruction`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReconstructionKind {
    /// A COLMAP / GLOMAP sparse model folder of this flavour.
    Colmap(ColmapFormat),
    /// A DROID-SLAM reconstruction folder (`tstamps/images/poses/disps/intrinsics.npy`).
    Droid,
    /// A trajectory in TUM column order (DPVO, MASt3R-SLAM, DSO, ORB-SLAM3),
    /// with an optional PLY cloud.
    Trajectory,
}

impl ReconstructionKind {
    /// `"colmap"`, `"droid"` or `"trajectory"`.
    pub fn name(self) -> &'static str {
        match self {
            ReconstructionKind::Colmap(_) => "colmap",
            ReconstructionKind::Droid => "droid",
            ReconstructionKind::Trajectory => "trajectory",
        }
    }
}

/// The input's own model, kept so that the output can be written in its format.
#[derive(Clone, Debug, PartialEq)]
pub enum NativeModel {
    /// A COLMAP / GLOMAP sparse model (model units, its own world frame).
    Colmap(Box<ColmapModel>),
}

impl NativeModel {
    /// The model with its world moved by `new_from_old` (e.g. `T_world_slam`):
    /// [`ColmapModel::transformed`] for COLMAP.
    pub fn transformed(&self, new_from_old: &Sim3) -> NativeModel {
        match self {
            NativeModel::Colmap(m) => NativeModel::Colmap(Box::new(m.transformed(new_from_old))),
        }
    }

    /// The COLMAP model, when it is one.
    pub fn colmap(&self) -> Option<&ColmapModel> {
        match self {
            NativeModel::Colmap(m) => Some(m),
        }
    }
}

/// What a reconstruction knows of one frame besides its pose.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameInfo {
    /// The image name (COLMAP's, relative to its image folder).
    pub name: Option<String>,
    /// The pinhole part of its camera (principal point in this project's
    /// pixel-centre convention), where the camera model has one.
    pub camera: Option<PinholeCamera>,
}

/// How the stamps of a reconstruction's frames were made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameTimes {
    /// Read from the trajectory file (seconds, after the unit detection).
    File,
    /// The image names are time stamps ([`crate::io::colmap::image_name_time`]:
    /// EuRoC's nanosecond names, TUM's `seconds.fraction` names).
    ImageNames,
    /// The images' rank in name order (`0, 1, 2, …`): the names are no time
    /// stamps, so only a reference by name can be paired.
    ImageRank,
    /// DROID-SLAM's `tstamps.npy`: the index of each keyframe in the image
    /// stream it was given, unless the caller saved times there.
    Tstamps,
}

impl FrameTimes {
    /// One line for the report.
    pub fn describe(self) -> &'static str {
        match self {
            FrameTimes::File => "the trajectory file's stamps (seconds after the unit detection)",
            FrameTimes::ImageNames => "the image names, which are time stamps (seconds)",
            FrameTimes::ImageRank => {
                "the images' rank in name order (the names are no time stamps: pair by name)"
            }
            FrameTimes::Tstamps => {
                "tstamps.npy (DROID-SLAM stores the frame index it was given; a reference by time must use that clock)"
            }
        }
    }
}

/// What was read, and how, for a reconstruction input.
#[derive(Clone, Debug, PartialEq)]
pub struct ReconstructionInfo {
    /// Which reader read it.
    pub kind: ReconstructionKind,
    /// How the frame stamps were made.
    pub frame_times: FrameTimes,
    /// What the trajectory reader found out (unit, delimiter, header,
    /// repeated stamps), for trajectory files.
    pub slam_text: Option<TextInfo>,
    /// How the cloud's points get their ray origins for an octree, when they have them.
    pub octree_origins: Option<String>,
    /// Decisions the reader made that the report should say.
    pub notes: Vec<String>,
}

/// The formats of a reference file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReferenceFormat {
    /// Poses in TUM column order (`t tx ty tz qx qy qz qw`; any time unit, CSV accepted).
    Tum,
    /// EuRoC ground truth CSV (`ns, x, y, z, qw, qx, qy, qz, …`).
    Euroc,
    /// Positions by image name (`name x y z`, COLMAP `model_aligner`'s file).
    Names,
}

impl ReferenceFormat {
    /// `"tum"`, `"euroc"` or `"names"`.
    pub fn name(self) -> &'static str {
        match self {
            ReferenceFormat::Tum => "tum",
            ReferenceFormat::Euroc => "euroc",
            ReferenceFormat::Names => "names",
        }
    }
}

impl std::str::FromStr for ReferenceFormat {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "tum" => Ok(ReferenceFormat::Tum),
            "euroc" => Ok(ReferenceFormat::Euroc),
            "names" | "name" => Ok(ReferenceFormat::Names),
            _ => Err(Error::invalid(
                "reference_format",
                format!(
                    "expected \"names\", \"tum\" or \"euroc\", got {}",
                    crate::error::cut(s)
                ),
            )),
        }
    }
}

/// How SLAM frames and reference poses are paired.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Pairing {
    /// By time stamp (the association of `align_trajectories`).
    #[default]
    Time,
    /// By image name: each reference position carries the stamp of the frame
    /// of the same name, and the association matches equal stamps only
    /// (`max_diff = 0`, no offset).
    Name,
}

/// The outcome of pairing by name.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct NamePairing {
    /// Names in the reference file.
    pub reference_names: usize,
    /// Of those, names of frames of the input.
    pub matched: usize,
    /// Reference names that no frame has.
    pub unknown: usize,
    /// The first of those (at most 10).
    pub unknown_examples: Vec<String>,
}

/// The reference file given beside the input.
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceFileInfo {
    /// The file.
    pub path: PathBuf,
    /// Its format.
    pub format: ReferenceFormat,
    /// True when the format was detected, false when it was given.
    pub format_detected: bool,
    /// What the trajectory reader found out, for TUM-order files.
    pub text: Option<TextInfo>,
    /// How the frames were paired with it.
    pub pairing: Pairing,
    /// The name pairing's counts, when paired by name.
    pub names: Option<NamePairing>,
}
