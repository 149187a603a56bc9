//! COLMAP / GLOMAP sparse models: `cameras`, `images`, `points3D` and, from
//! COLMAP 3.12 on, `rigs` and `frames`, each as `.bin` or `.txt`.
//!
//! The layouts are those of COLMAP's `src/colmap/scene/reconstruction_io_binary.cc`
//! and `reconstruction_io_text.cc` (little-endian; `camera_t`, `image_t`,
//! `rig_t`, `frame_t`, `point2D_t` are `u32`, `point3D_t` and data ids `u64`).
//!
//! Poses are stored as COLMAP stores them: **world-to-camera**
//! (`cam_from_world`, `x_cam = R·x_world + t`), quaternion `(w, x, y, z)`;
//! [`ColmapImage::world_from_cam`] and [`ColmapImage::centre`] give the inverse.
//!
//! Flavour rule ([`detect_format`]): a folder holds one model, either every
//! `cameras/images/points3D` file as `.bin` or every one as `.txt`; `rigs` and
//! `frames` of that flavour come both or not at all. A folder with both
//! complete flavours is refused unless the caller names one (COLMAP itself
//! silently prefers `.bin`); a flavour with only some of its files is refused.

mod binary;
mod camera;
mod reference;
mod text;

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::trajectory::Trajectory;

pub use camera::{CameraModel, ColmapCamera};
pub use reference::{image_name_time, read_name_positions, NamedPosition};

/// The two file flavours of a COLMAP model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColmapFormat {
    /// `*.bin`, little-endian binary.
    Binary,
    /// `*.txt`, one record a line (two for an image).
    Text,
}

impl ColmapFormat {
    /// The file extension, `"bin"` or `"txt"`.
    pub fn extension(self) -> &'static str {
        match self {
            ColmapFormat::Binary => "bin",
            ColmapFormat::Text => "txt",
        }
    }

    /// From `"bin"`/`"binary"`/`".bin"` or `"txt"`/`"text"`/`".txt"`.
    pub fn parse(s: &str) -> Result<Self> {
        match s.trim_start_matches('.').to_ascii_lowercase().as_str() {
            "bin" | "binary" => Ok(ColmapFormat::Binary),
            "txt" | "text" => Ok(ColmapFormat::Text),
            _ => Err(Error::invalid(
                "format",
                format!("expected \"bin\" or \"txt\", got {s:?}"),
            )),
        }
    }
}

/// A rigid transform as COLMAP stores it: `x_a = R·x_b + t` for `a_from_b`,
/// with the quaternion of `R` kept exactly as read, `(w, x, y, z)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rigid3 {
    /// Quaternion `(w, x, y, z)` of the rotation (COLMAP's order).
    pub qvec: [f64; 4],
    /// Translation, model units.
    pub tvec: [f64; 3],
}

impl Rigid3 {
    /// The identity.
    pub fn identity() -> Self {
        Rigid3 {
            qvec: [1.0, 0.0, 0.0, 0.0],
            tvec: [0.0; 3],
        }
    }

    /// From a rotation and a translation.
    pub fn from_parts(rotation: &UnitQuaternion<f64>, translation: &Vector3<f64>) -> Self {
        let q = rotation.quaternion();
        Rigid3 {
            qvec: [q.w, q.i, q.j, q.k],
            tvec: [translation.x, translation.y, translation.z],
        }
    }

    /// The rotation (the stored quaternion normalised).
    pub fn rotation(&self) -> UnitQuaternion<f64> {
        let [w, x, y, z] = self.qvec;
        UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z))
    }

    /// The translation.
    pub fn translation(&self) -> Vector3<f64> {
        Vector3::from(self.tvec)
    }

    /// As a [`Sim3`] of scale 1 (`T_a_b` for a stored `a_from_b`).
    pub fn to_sim3(&self) -> Sim3 {
        Sim3 {
            rotation: self.rotation(),
            translation: self.translation(),
            scale: 1.0,
        }
    }

    /// `T_world_cam` for a stored `cam_from_world`, with `new_from_old` applied
    /// to the world: `R' = R·R_Tᵀ`, `t' = s·t − R'·t_T` (COLMAP's
    /// `TransformCameraWorld`; the camera centre moves as a point does).
    ///
    /// The stored quaternion is multiplied as it is (not renormalised first), so
    /// the identity transform returns every pose bit for bit.
    fn world_transformed(&self, new_from_old: &Sim3) -> Rigid3 {
        let [w, x, y, z] = self.qvec;
        let q = Quaternion::new(w, x, y, z) * new_from_old.rotation.inverse().into_inner();
        let r = UnitQuaternion::from_quaternion(q);
        let t = self.translation() * new_from_old.scale - r * new_from_old.translation;
        Rigid3 {
            qvec: [q.w, q.i, q.j, q.k],
            tvec: [t.x, t.y, t.z],
        }
    }

    /// Checks that the numbers are finite and the quaternion is not zero.
    fn check(&self) -> std::result::Result<(), String> {
        if self.qvec.iter().chain(&self.tvec).any(|v| !v.is_finite()) {
            return Err(format!("non-finite pose {:?} {:?}", self.qvec, self.tvec));
        }
        let n2: f64 = self.qvec.iter().map(|v| v * v).sum();
        if n2 < 1e-12 {
            return Err(format!("zero quaternion {:?}", self.qvec));
        }
        Ok(())
    }
}

/// One 2-D feature of an image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point2D {
    /// Pixel position `(x, y)`, COLMAP's convention (upper-left corner at 0).
    pub xy: [f64; 2],
    /// The 3-D point it observes, if any (`-1` in text, `u64::MAX` in binary).
    pub point3d_id: Option<u64>,
}

/// One registered image.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapImage {
    /// COLMAP's `image_id`.
    pub id: u32,
    /// World-to-camera pose.
    pub cam_from_world: Rigid3,
    /// The camera it was taken with.
    pub camera_id: u32,
    /// File name relative to the image folder (e.g. `1403636579763555584.png`).
    pub name: String,
    /// Its 2-D features; a point's index is its `point2D_idx` in tracks.
    pub points2d: Vec<Point2D>,
}

impl ColmapImage {
    /// `T_world_cam` (the inverse of the stored pose): camera-frame points into
    /// the model's world frame.
    pub fn world_from_cam(&self) -> Sim3 {
        self.cam_from_world.to_sim3().inverse()
    }

    /// The camera centre in the world frame, `−Rᵀ·t`.
    pub fn centre(&self) -> Vector3<f64> {
        -(self.cam_from_world.rotation().inverse() * self.cam_from_world.translation())
    }
}

/// One observation of a 3-D point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TrackElement {
    /// The observing image.
    pub image_id: u32,
    /// Index into that image's [`ColmapImage::points2d`].
    pub point2d_idx: u32,
}

/// One 3-D point.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapPoint3D {
    /// COLMAP's `point3D_id`.
    pub id: u64,
    /// Position in the world frame, model units.
    pub xyz: [f64; 3],
    /// Colour.
    pub rgb: [u8; 3],
    /// Mean reprojection error, pixels.
    pub error: f64,
    /// The observations.
    pub track: Vec<TrackElement>,
}

/// Kind of a rig sensor (COLMAP's `SensorType`: −1, 0, 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum SensorType {
    /// `INVALID` (−1).
    Invalid,
    /// `CAMERA` (0); the sensor id is a `camera_id`.
    Camera,
    /// `IMU` (1).
    Imu,
}

impl SensorType {
    /// From COLMAP's integer.
    pub fn from_id(v: i32) -> Option<Self> {
        match v {
            -1 => Some(SensorType::Invalid),
            0 => Some(SensorType::Camera),
            1 => Some(SensorType::Imu),
            _ => None,
        }
    }

    /// COLMAP's integer.
    pub fn id(self) -> i32 {
        match self {
            SensorType::Invalid => -1,
            SensorType::Camera => 0,
            SensorType::Imu => 1,
        }
    }

    /// COLMAP's name in text files.
    pub fn name(self) -> &'static str {
        match self {
            SensorType::Invalid => "INVALID",
            SensorType::Camera => "CAMERA",
            SensorType::Imu => "IMU",
        }
    }

    /// From COLMAP's name.
    pub fn from_name(s: &str) -> Option<Self> {
        [SensorType::Invalid, SensorType::Camera, SensorType::Imu]
            .into_iter()
            .find(|t| t.name() == s)
    }
}

/// A sensor of a rig: its kind and id.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SensorId {
    /// Kind.
    pub kind: SensorType,
    /// Id (a `camera_id` for cameras).
    pub id: u32,
}

/// A non-reference sensor of a rig and its pose in the rig.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigSensor {
    /// The sensor.
    pub sensor: SensorId,
    /// `sensor_from_rig`, when calibrated.
    pub sensor_from_rig: Option<Rigid3>,
}

/// A rig (COLMAP ≥ 3.12): a reference sensor (whose frame is the rig frame)
/// and further sensors with their poses in it.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapRig {
    /// COLMAP's `rig_id`.
    pub id: u32,
    /// The reference sensor (absent only for a rig with no sensors).
    pub ref_sensor: Option<SensorId>,
    /// The other sensors.
    pub sensors: Vec<RigSensor>,
}

/// One datum of a frame: a sensor and the id of its measurement (an
/// `image_id` for cameras).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct DataId {
    /// The sensor.
    pub sensor: SensorId,
    /// The measurement's id.
    pub id: u64,
}

/// A frame (COLMAP ≥ 3.12): one pose of a rig and the data taken at it.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapFrame {
    /// COLMAP's `frame_id`.
    pub id: u32,
    /// The rig.
    pub rig_id: u32,
    /// World-to-rig pose.
    pub rig_from_world: Rigid3,
    /// The data taken at this pose.
    pub data_ids: Vec<DataId>,
}

/// A whole sparse model, in the order its files list the records.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapModel {
    /// The flavour it was read from (and is written back in by default).
    pub format: ColmapFormat,
    /// Cameras.
    pub cameras: Vec<ColmapCamera>,
    /// Registered images.
    pub images: Vec<ColmapImage>,
    /// 3-D points.
    pub points3d: Vec<ColmapPoint3D>,
    /// Rigs, `None` for a model without `rigs.*` (before COLMAP 3.12).
    pub rigs: Option<Vec<ColmapRig>>,
    /// Frames, `None` for a model without `frames.*`.
    pub frames: Option<Vec<ColmapFrame>>,
}

/// The five file stems, in reading order.
const STEMS: [&str; 5] = ["cameras", "rigs", "frames", "images", "points3D"];
/// Those every model has.
const REQUIRED: [&str; 3] = ["cameras", "images", "points3D"];

fn file(dir: &Path, stem: &str, f: ColmapFormat) -> PathBuf {
    dir.join(format!("{stem}.{}", f.extension()))
}

fn present(dir: &Path, f: ColmapFormat) -> Vec<String> {
    STEMS
        .iter()
        .map(|s| format!("{s}.{}", f.extension()))
        .filter(|n| dir.join(n).is_file())
        .collect()
}

/// Which flavour the folder holds, by the rule in the module documentation;
/// `requested` picks one when both are complete (and must itself be complete).
pub fn detect_format(dir: &Path, requested: Option<ColmapFormat>) -> Result<ColmapFormat> {
    if !dir.is_dir() {
        return Err(Error::Reconstruction {
            path: dir.into(),
            reason: "not a folder (a COLMAP model is a folder of cameras/images/points3D files)"
                .into(),
        });
    }
    let complete = |f: ColmapFormat| -> std::result::Result<(), String> {
        let missing: Vec<String> = REQUIRED
            .iter()
            .filter(|s| !file(dir, s, f).is_file())
            .map(|s| format!("{s}.{}", f.extension()))
            .collect();
        let (rigs, frames) = (
            file(dir, "rigs", f).is_file(),
            file(dir, "frames", f).is_file(),
        );
        let mut problems = Vec::new();
        if !missing.is_empty() {
            problems.push(format!("missing {}", missing.join(", ")));
        }
        if rigs != frames {
            problems.push(format!(
                "rigs.{e} and frames.{e} come together, found only {}.{e}",
                if rigs { "rigs" } else { "frames" },
                e = f.extension()
            ));
        }
        if problems.is_empty() {
            Ok(())
        } else {
            Err(problems.join("; "))
        }
    };
    let found = |f| present(dir, f);
    let describe = |f: ColmapFormat, why: String| Error::Reconstruction {
        path: dir.into(),
        reason: format!(
            "incomplete .{} model: {why} (found: {})",
            f.extension(),
            found(f).join(", ")
        ),
    };
    if let Some(f) = requested {
        complete(f).map_err(|why| describe(f, why))?;
        return Ok(f);
    }
    let (bin, txt) = (found(ColmapFormat::Binary), found(ColmapFormat::Text));
    match (bin.is_empty(), txt.is_empty()) {
        (true, true) => Err(Error::Reconstruction {
            path: dir.into(),
            reason: "no COLMAP model files (cameras, images, points3D as .bin or .txt)".into(),
        }),
        (false, true) => complete(ColmapFormat::Binary)
            .map(|_| ColmapFormat::Binary)
            .map_err(|w| describe(ColmapFormat::Binary, w)),
        (true, false) => complete(ColmapFormat::Text)
            .map(|_| ColmapFormat::Text)
            .map_err(|w| describe(ColmapFormat::Text, w)),
        (false, false) => Err(Error::Reconstruction {
            path: dir.into(),
            reason: format!(
                "both flavours present ({} and {}); name the one to read (format \"bin\" or \"txt\")",
                bin.join(", "),
                txt.join(", ")
            ),
        }),
    }
}

/// Reads the regular file `path` whole (a device or folder is refused, so a
/// path to `/dev/zero` cannot grow memory).
fn read_file(path: &Path) -> Result<Vec<u8>> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(Error::Reconstruction {
            path: path.into(),
            reason: "not a regular file".into(),
        });
    }
    std::fs::read(path).map_err(|e| Error::io(path, e))
}

/// Reads the model in `dir` (flavour by [`detect_format`]) and checks that its
/// records refer to one another consistently.
pub fn read_colmap(dir: &Path, format: Option<ColmapFormat>) -> Result<ColmapModel> {
    let format = detect_format(dir, format)?;
    let load = |stem: &str| -> Result<Option<(PathBuf, Vec<u8>)>> {
        let p = file(dir, stem, format);
        if p.is_file() {
            let b = read_file(&p)?;
            Ok(Some((p, b)))
        } else {
            Ok(None)
        }
    };
    let req = |stem: &str| -> Result<(PathBuf, Vec<u8>)> {
        let p = file(dir, stem, format);
        Ok((p.clone(), read_file(&p)?))
    };
    let (cam_p, cam_b) = req("cameras")?;
    let (img_p, img_b) = req("images")?;
    let (pts_p, pts_b) = req("points3D")?;
    let rigs = load("rigs")?;
    let frames = load("frames")?;
    let model = match format {
        ColmapFormat::Binary => ColmapModel {
            format,
            cameras: binary::read_cameras(&cam_p, &cam_b)?,
            images: binary::read_images(&img_p, &img_b)?,
            points3d: binary::read_points3d(&pts_p, &pts_b)?,
            rigs: rigs.map(|(p, b)| binary::read_rigs(&p, &b)).transpose()?,
            frames: frames
                .map(|(p, b)| binary::read_frames(&p, &b))
                .transpose()?,
        },
        ColmapFormat::Text => ColmapModel {
            format,
            cameras: text::read_cameras(&cam_p, text::utf8(&cam_p, &cam_b)?)?,
            images: text::read_images(&img_p, text::utf8(&img_p, &img_b)?)?,
            points3d: text::read_points3d(&pts_p, text::utf8(&pts_p, &pts_b)?)?,
            rigs: rigs
                .map(|(p, b)| text::read_rigs(&p, text::utf8(&p, &b)?))
                .transpose()?,
            frames: frames
                .map(|(p, b)| text::read_frames(&p, text::utf8(&p, &b)?))
                .transpose()?,
        },
    };
    model.validate(dir)?;
    Ok(model)
}

impl ColmapModel {
    /// Reads a model folder ([`read_colmap`]).
    pub fn read(dir: impl AsRef<Path>, format: Option<ColmapFormat>) -> Result<Self> {
        read_colmap(dir.as_ref(), format)
    }

    /// Checks the references between records: unique ids; every image's camera
    /// exists; every track element names an existing image and a valid
    /// `point2D_idx`; every image's 3-D point ids exist; with rigs/frames,
    /// every frame's rig exists and every image belongs to one frame (what
    /// COLMAP needs to load the model). `dir` names the model in errors.
    pub fn validate(&self, dir: &Path) -> Result<()> {
        let err = |stem: &str, reason: String| Error::Reconstruction {
            path: file(dir, stem, self.format),
            reason,
        };
        let mut cams = HashSet::new();
        for c in &self.cameras {
            if !cams.insert(c.id) {
                return Err(err("cameras", format!("camera id {} appears twice", c.id)));
            }
            if c.params.len() != c.model.num_params() {
                return Err(err(
                    "cameras",
                    format!(
                        "camera {} ({}) has {} parameters, the model has {}",
                        c.id,
                        c.model.name(),
                        c.params.len(),
                        c.model.num_params()
                    ),
                ));
            }
        }
        let mut points2d = HashMap::new();
        for im in &self.images {
            if points2d.insert(im.id, im.points2d.len()).is_some() {
                return Err(err("images", format!("image id {} appears twice", im.id)));
            }
            if !cams.contains(&im.camera_id) {
                return Err(err(
                    "images",
                    format!(
                        "image {} uses camera {}, which cameras does not list",
                        im.id, im.camera_id
                    ),
                ));
            }
            im.cam_from_world
                .check()
                .map_err(|r| err("images", format!("image {}: {r}", im.id)))?;
        }
        let mut pts = HashSet::new();
        for p in &self.points3d {
            if !pts.insert(p.id) {
                return Err(err("points3D", format!("point id {} appears twice", p.id)));
            }
            for t in &p.track {
                match points2d.get(&t.image_id) {
                    None => {
                        return Err(err(
                            "points3D",
                            format!("point {} is observed by image {}, which images does not list", p.id, t.image_id),
                        ))
                    }
                    Some(&n) if t.point2d_idx as usize >= n => {
                        return Err(err(
                            "points3D",
                            format!(
                                "point {} is observed by feature {} of image {}, which has {n} features",
                                p.id, t.point2d_idx, t.image_id
                            ),
                        ))
                    }
                    _ => {}
                }
            }
        }
        for im in &self.images {
            if let Some((k, id)) = im.points2d.iter().enumerate().find_map(|(k, q)| {
                q.point3d_id
                    .filter(|id| !pts.contains(id))
                    .map(|id| (k, id))
            }) {
                return Err(err(
                    "images",
                    format!(
                        "feature {k} of image {} observes point {id}, which points3D does not list",
                        im.id
                    ),
                ));
            }
        }
        match (&self.rigs, &self.frames) {
            (None, None) => Ok(()),
            (Some(rigs), Some(frames)) => {
                let mut rig_ids = HashSet::new();
                for r in rigs {
                    if !rig_ids.insert(r.id) {
                        return Err(err("rigs", format!("rig id {} appears twice", r.id)));
                    }
                    for s in &r.sensors {
                        if let Some(p) = &s.sensor_from_rig {
                            p.check()
                                .map_err(|why| err("rigs", format!("rig {}: {why}", r.id)))?;
                        }
                    }
                }
                let mut in_frame = HashSet::new();
                let mut frame_ids = HashSet::new();
                for f in frames {
                    if !frame_ids.insert(f.id) {
                        return Err(err("frames", format!("frame id {} appears twice", f.id)));
                    }
                    if !rig_ids.contains(&f.rig_id) {
                        return Err(err(
                            "frames",
                            format!(
                                "frame {} uses rig {}, which rigs does not list",
                                f.id, f.rig_id
                            ),
                        ));
                    }
                    f.rig_from_world
                        .check()
                        .map_err(|r| err("frames", format!("frame {}: {r}", f.id)))?;
                    for d in &f.data_ids {
                        if d.sensor.kind == SensorType::Camera {
                            in_frame.insert(d.id);
                        }
                    }
                }
                match self
                    .images
                    .iter()
                    .find(|im| !in_frame.contains(&(im.id as u64)))
                {
                    Some(im) => Err(err(
                        "frames",
                        format!("image {} belongs to no frame", im.id),
                    )),
                    None => Ok(()),
                }
            }
            _ => Err(err(
                "rigs",
                "rigs and frames come together; the model has only one of them".into(),
            )),
        }
    }

    /// The model with its world moved by `new_from_old` (`T_new_old`, e.g.
    /// `T_world_slam`), as COLMAP's `Reconstruction::Transform(Sim3d)` does:
    /// - points: `x' = s·R_T·x + t_T`;
    /// - images' and frames' world-to-camera / world-to-rig poses:
    ///   `R' = R·R_Tᵀ`, `t' = s·t − R'·t_T` (centres move as points do);
    /// - rigs: each `sensor_from_rig` translation times `s`, rotations kept.
    ///   The rig is measured in model units like the rest of the model, so a
    ///   rescaled world rescales the lever arms (a rig calibrated in metres in
    ///   a model already in metres has `s = 1` and is unchanged);
    /// - cameras untouched.
    pub fn transformed(&self, new_from_old: &Sim3) -> ColmapModel {
        let s = new_from_old.scale;
        let mut out = self.clone();
        for p in &mut out.points3d {
            let x = new_from_old.transform_point(&Vector3::from(p.xyz));
            p.xyz = [x.x, x.y, x.z];
        }
        for im in &mut out.images {
            im.cam_from_world = im.cam_from_world.world_transformed(new_from_old);
        }
        if let Some(frames) = &mut out.frames {
            for f in frames {
                f.rig_from_world = f.rig_from_world.world_transformed(new_from_old);
            }
        }
        if let Some(rigs) = &mut out.rigs {
            for r in rigs {
                for sensor in &mut r.sensors {
                    if let Some(p) = &mut sensor.sensor_from_rig {
                        p.tvec = p.tvec.map(|v| v * s);
                    }
                }
            }
        }
        out
    }

    /// Writes the model into `dir` (created if missing) in `format` (default:
    /// the flavour it was read from), atomically per folder: every file goes to
    /// a temporary name in `dir` first and all are renamed once all are
    /// written; on an error nothing under the final names changes. A stale
    /// `rigs`/`frames` file of the same flavour is removed when the model has
    /// none (it would otherwise be read with the new files). A folder that
    /// holds model files of the other flavour is refused, so the result is
    /// never a folder with two models.
    pub fn write(&self, dir: &Path, format: Option<ColmapFormat>) -> Result<()> {
        let format = format.unwrap_or(self.format);
        let other = match format {
            ColmapFormat::Binary => ColmapFormat::Text,
            ColmapFormat::Text => ColmapFormat::Binary,
        };
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let clash = present(dir, other);
        if !clash.is_empty() {
            return Err(Error::Reconstruction {
                path: dir.into(),
                reason: format!(
                    "holds a .{} model ({}); writing .{} beside it would leave two models",
                    other.extension(),
                    clash.join(", "),
                    format.extension()
                ),
            });
        }
        if self.rigs.is_some() != self.frames.is_some() {
            return Err(Error::Reconstruction {
                path: dir.into(),
                reason: "rigs and frames come together; the model has only one of them".into(),
            });
        }
        let files = self.encode(dir, format)?;
        // One output set: every file written under a temporary name, then all
        // renamed together.
        let mut set = crate::io::atomic::OutputSet::new();
        for (stem, bytes) in &files {
            set.write_bytes(&file(dir, stem, format), bytes)?;
        }
        set.commit()?;
        if self.rigs.is_none() {
            for stem in ["rigs", "frames"] {
                let p = file(dir, stem, format);
                if p.is_file() {
                    std::fs::remove_file(&p).map_err(|e| Error::io(&p, e))?;
                }
            }
        }
        Ok(())
    }

    /// The model's files in `format`, as `(stem, bytes)` (`cameras`, `rigs`
    /// and `frames` when the model has them, `images`, `points3D`); `dir` is
    /// where they will go, for the messages. The file names are
    /// `STEM.bin` / `STEM.txt` ([`ColmapFormat::extension`]).
    pub fn encode(&self, dir: &Path, format: ColmapFormat) -> Result<Vec<(&'static str, Vec<u8>)>> {
        if self.rigs.is_some() != self.frames.is_some() {
            return Err(Error::Reconstruction {
                path: dir.into(),
                reason: "rigs and frames come together; the model has only one of them".into(),
            });
        }
        let mut files: Vec<(&'static str, Vec<u8>)> = Vec::new();
        match format {
            ColmapFormat::Binary => {
                files.push(("cameras", binary::write_cameras(&self.cameras)));
                if let (Some(r), Some(f)) = (&self.rigs, &self.frames) {
                    files.push(("rigs", binary::write_rigs(r)));
                    files.push(("frames", binary::write_frames(f)));
                }
                files.push(("images", binary::write_images(&self.images)));
                files.push(("points3D", binary::write_points3d(&self.points3d)));
            }
            ColmapFormat::Text => {
                files.push(("cameras", text::write_cameras(&self.cameras).into_bytes()));
                if let (Some(r), Some(f)) = (&self.rigs, &self.frames) {
                    files.push(("rigs", text::write_rigs(r).into_bytes()));
                    files.push(("frames", text::write_frames(f).into_bytes()));
                }
                let images = text::write_images(&file(dir, "images", format), &self.images)?;
                files.push(("images", images.into_bytes()));
                files.push((
                    "points3D",
                    text::write_points3d(&self.points3d).into_bytes(),
                ));
            }
        }
        Ok(files)
    }

    /// The camera with this id.
    pub fn camera(&self, id: u32) -> Option<&ColmapCamera> {
        self.cameras.iter().find(|c| c.id == id)
    }

    /// Each image's name and camera centre (world frame, model units), in the
    /// order of the model: the input of an alignment by image name.
    pub fn camera_centres(&self) -> Vec<NamedPosition> {
        self.images
            .iter()
            .map(|im| NamedPosition {
                name: im.name.clone(),
                position: im.centre(),
            })
            .collect()
    }

    /// The images as a trajectory of `T_world_cam` poses timed by their names,
    /// for images named by time stamps ([`image_name_time`]: EuRoC's
    /// `1403636579763555584.png` is nanoseconds, `1305031102.175304.png`
    /// seconds), sorted by time. Errors naming the first image whose name is
    /// not a time stamp, and on two images with the same stamp.
    pub fn trajectory_by_name_time(&self) -> Result<Trajectory> {
        let mut rows = Vec::with_capacity(self.images.len());
        for im in &self.images {
            let t = image_name_time(&im.name).ok_or_else(|| {
                Error::invalid(
                    "image names",
                    format!(
                        "image {} is named {:?}, not a time stamp (digits: nanoseconds, or seconds with a decimal point)",
                        im.id, im.name
                    ),
                )
            })?;
            rows.push((t, im));
        }
        rows.sort_by(|a, b| a.0.total_cmp(&b.0));
        if let Some(w) = rows.windows(2).find(|w| w[0].0 == w[1].0) {
            return Err(Error::invalid(
                "image names",
                format!(
                    "images {:?} and {:?} have the same time stamp",
                    w[0].1.name, w[1].1.name
                ),
            ));
        }
        let times = rows.iter().map(|r| r.0).collect();
        let poses: Vec<Sim3> = rows.iter().map(|r| r.1.world_from_cam()).collect();
        Trajectory::try_new(
            times,
            poses.iter().map(|p| p.translation).collect(),
            Some(poses.iter().map(|p| p.rotation).collect()),
        )
    }

    /// Number of observations (track elements over all points).
    pub fn num_observations(&self) -> usize {
        self.points3d.iter().map(|p| p.track.len()).sum()
    }
}
