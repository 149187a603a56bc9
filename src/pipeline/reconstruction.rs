//! Reconstructions as sources, and the reference files that make them metric.
//!
//! [`detect_reconstruction`] tells from a path's contents which reconstruction
//! it is; [`ReconstructionSource`] reads it into a [`Recording`]:
//!
//! | input | frames | cloud | kept for the output |
//! |---|---|---|---|
//! | COLMAP / GLOMAP model folder (`.bin` / `.txt`, rigs/frames) | images: `T_slam_cam` = the inverse of the stored world-to-camera pose, name, pinhole camera | points3D with colour; each point's ray origin is the centre of the observing image nearest to it | the [`ColmapModel`] |
//! | DROID-SLAM folder (`*.npy`) | keyframes (world-to-camera poses inverted), disparities filtered by multi-view consistency ([`DepthFilter`]) | backprojected | — |
//! | TUM-order trajectory (DPVO, MASt3R-SLAM, DSO, ORB-SLAM3; time unit detected) + PLY | poses | the PLY beside it (same stem), no rays | — |
//!
//! COLMAP frame stamps: the image names when every name is a time stamp
//! (EuRoC's `1403636579763555584.png`: nanoseconds; `1305031102.175304.png`:
//! seconds) — where a rig's cameras share a stamp, the time pairing uses the
//! image of the lowest camera id at each stamp; otherwise the images' rank in
//! name order, which only a reference by name can pair.
//!
//! References ([`ReferenceSpec`], [`attach_reference`]): poses by time (TUM
//! order with the time unit detected or given, or EuRoC CSV), or positions by
//! image name (`name x y z`, as COLMAP's `model_aligner` takes them). Pairing
//! by name gives each reference position the stamp of the frame of the same
//! name, and the conversion then matches equal stamps only (`max_diff = 0`,
//! no offset; [`effective_options`]): the one associate-then-fit path of
//! [`crate::align::trajectories`] pairs them exactly, with every option of the
//! fit (start-up cut, robust fit, windowed comparison) unchanged.

use std::borrow::Cow;
use std::collections::{BTreeMap, HashMap};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use nalgebra::Vector3;

use super::native::{
    FrameInfo, FrameTimes, NamePairing, NativeModel, Pairing, ReconstructionInfo,
    ReconstructionKind, ReferenceFileInfo, ReferenceFormat,
};
use super::options::ConvertOptions;
use super::source::{open_log, Recording, Source, SourceInfo};
use crate::cloud::{PointCloud, PointFilter};
use crate::error::{cut, Error, Result};
use crate::io::colmap::{
    detect_format, image_name_time, read_colmap, read_name_positions, ColmapFormat, ColmapModel,
    NamedPosition,
};
use crate::io::droid::{filter_consistent, read_droid, DepthFilter};
use crate::io::text::{match_time_units, read_euroc, read_trajectory, TimeUnit};
use crate::io::ReadOptions;
use crate::trajectory::Trajectory;

/// How a reconstruction is read.
#[derive(Clone, Debug, PartialEq)]
pub struct ReconstructionOptions {
    /// Unit of a trajectory file's stamps (detected when `None`).
    pub time_unit: Option<TimeUnit>,
    /// The cloud of a trajectory input (PLY, or `x y z` text); when `None`,
    /// the PLY of the same stem beside the file (or, for DPVO's
    /// `saved_trajectories/NAME.txt`, `NAME.ply` one folder up).
    pub cloud: Option<PathBuf>,
    /// The flavour to read when a COLMAP folder holds both.
    pub colmap_format: Option<ColmapFormat>,
    /// DROID-SLAM's multi-view depth filter, applied to the keyframes as they
    /// are read; `None` keeps every pixel with a positive disparity.
    pub depth_filter: Option<DepthFilter>,
}

impl Default for ReconstructionOptions {
    fn default() -> Self {
        ReconstructionOptions {
            time_unit: None,
            cloud: None,
            colmap_format: None,
            depth_filter: Some(DepthFilter::default()),
        }
    }
}

/// File stems of a COLMAP model.
const COLMAP_STEMS: [&str; 3] = ["cameras", "images", "points3D"];
/// Files of a DROID-SLAM folder.
const DROID_FILES: [&str; 5] = [
    "tstamps.npy",
    "images.npy",
    "poses.npy",
    "disps.npy",
    "intrinsics.npy",
];

fn not_found(path: &Path, reason: impl Into<String>) -> Error {
    Error::Reconstruction {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

/// Which reconstruction `path` holds, from its contents, or `None` when it is
/// a log (an MCAP file, a ROS bag, a rosbag2 folder or database: their first
/// bytes or `metadata.yaml`), or no regular file or folder (left to the log
/// reader to refuse):
/// - a folder with any `cameras` / `images` / `points3D` file → COLMAP, the
///   flavour by [`detect_format`] (`colmap_format` picks one when both are
///   complete; an incomplete model is an error naming what is missing);
/// - a folder with any DROID-SLAM array file → DROID-SLAM;
/// - a folder with one trajectory `.txt` (or one whose stem has a `.ply`
///   beside it, as MASt3R-SLAM's `logs/`) → that trajectory;
/// - a text file → a trajectory (its lines are checked when it is read);
///   a PLY file alone is refused (it has no poses).
pub fn detect_reconstruction(
    path: &Path,
    colmap_format: Option<ColmapFormat>,
) -> Result<Option<ReconstructionKind>> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if meta.is_dir() {
        let any_colmap = COLMAP_STEMS.iter().any(|s| {
            ["bin", "txt"]
                .iter()
                .any(|e| path.join(format!("{s}.{e}")).is_file())
        });
        if any_colmap {
            return Ok(Some(ReconstructionKind::Colmap(detect_format(
                path,
                colmap_format,
            )?)));
        }
        if DROID_FILES.iter().any(|f| path.join(f).is_file()) {
            return Ok(Some(ReconstructionKind::Droid));
        }
        if path.join("metadata.yaml").is_file() {
            return Ok(None);
        }
        if trajectory_in(path)?.is_some() {
            return Ok(Some(ReconstructionKind::Trajectory));
        }
        return Err(not_found(
            path,
            "no reconstruction in this folder: looked for a COLMAP model (cameras, images, points3D as .bin or .txt), \
             a DROID-SLAM folder (tstamps, images, poses, disps, intrinsics .npy), a trajectory .txt, \
             and a rosbag2 metadata.yaml",
        ));
    }
    if !meta.is_file() {
        return Ok(None);
    }
    let mut head = Vec::with_capacity(64);
    std::fs::File::open(path)
        .and_then(|f| f.take(64).read_to_end(&mut head))
        .map_err(|e| Error::io(path, e))?;
    if crate::io::container::classify(&head).is_ok() {
        return Ok(None);
    }
    if head.starts_with(b"ply\n") || head.starts_with(b"ply\r") {
        return Err(not_found(
            path,
            "a PLY cloud alone has no poses: give the trajectory file (a PLY of the same stem beside it is read as its cloud)",
        ));
    }
    // Text (a cut multi-byte character at the end of the head is text too).
    let text = match std::str::from_utf8(&head) {
        Ok(_) => true,
        Err(e) => e.error_len().is_none(),
    };
    Ok((text && !head.contains(&0)).then_some(ReconstructionKind::Trajectory))
}

/// The trajectory file of a folder: its one `.txt`, or of several the one
/// whose stem has a `.ply` beside it; `None` without `.txt` files.
fn trajectory_in(dir: &Path) -> Result<Option<PathBuf>> {
    let mut txt: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && p.extension().is_some_and(|x| x == "txt"))
        .collect();
    txt.sort();
    match txt.len() {
        0 => Ok(None),
        1 => Ok(txt.pop()),
        _ => {
            let mut paired: Vec<PathBuf> = txt
                .iter()
                .filter(|t| t.with_extension("ply").is_file())
                .cloned()
                .collect();
            if paired.len() == 1 {
                return Ok(paired.pop());
            }
            let names: Vec<String> = txt
                .iter()
                .take(5)
                .map(|p| p.file_name().unwrap_or_default().to_string_lossy().into())
                .collect();
            Err(not_found(
                dir,
                format!(
                    "{} trajectory files ({}{}): give the file",
                    txt.len(),
                    names.join(", "),
                    if txt.len() > 5 { ", …" } else { "" }
                ),
            ))
        }
    }
}

/// The cloud of a trajectory file when none is given: `STEM.ply` beside it,
/// or for DPVO's `saved_trajectories/STEM.txt`, `STEM.ply` one folder up.
fn cloud_beside(file: &Path) -> Option<PathBuf> {
    let ply = file.with_extension("ply");
    if ply.is_file() {
        return Some(ply);
    }
    let dir = file.parent()?;
    if dir.file_name().is_some_and(|n| n == "saved_trajectories") {
        let up = dir.parent()?.join(ply.file_name()?);
        if up.is_file() {
            return Some(up);
        }
    }
    None
}

/// A reconstruction input (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct ReconstructionSource {
    /// The folder or file.
    pub path: PathBuf,
    /// How to read it.
    pub options: ReconstructionOptions,
}

impl Source for ReconstructionSource {
    fn read(&self) -> Result<Recording> {
        read_reconstruction(&self.path, &self.options)
    }
}

/// Reads the reconstruction at `path` ([`detect_reconstruction`]) into a
/// recording without reference.
///
/// Errors: [`Error::Reconstruction`] for a log or a path that holds no
/// reconstruction, and each reader's own errors (files missing or malformed,
/// inconsistent records, a trajectory file's bad line).
pub fn read_reconstruction(path: &Path, opts: &ReconstructionOptions) -> Result<Recording> {
    match detect_reconstruction(path, opts.colmap_format)? {
        Some(ReconstructionKind::Colmap(f)) => {
            let model = read_colmap(path, Some(f))?;
            colmap_recording(path, model)
        }
        Some(ReconstructionKind::Droid) => droid_recording(path, opts.depth_filter.as_ref()),
        Some(ReconstructionKind::Trajectory) => {
            let file = if path.is_dir() {
                trajectory_in(path)?.ok_or_else(|| not_found(path, "no trajectory file"))?
            } else {
                path.to_path_buf()
            };
            trajectory_recording(&file, opts)
        }
        None => Err(not_found(
            path,
            "a log (MCAP, ROS bag), not a reconstruction: convert reads it as a log",
        )),
    }
}

/// The frames of a COLMAP model: `(row order as image indices, stamps, how
/// the stamps were made, a note)`. With `all_images` false a rig's images
/// that share a stamp give one frame (the lowest camera id); with it true
/// such a model falls back to the rank stamps, which keep every image.
fn colmap_frame_rows(
    model: &ColmapModel,
    all_images: bool,
) -> (Vec<usize>, Vec<f64>, FrameTimes, Option<String>) {
    let im = &model.images;
    let n = im.len();
    let times: Option<Vec<f64>> = im.iter().map(|i| image_name_time(&i.name)).collect();
    if let Some(t) = times {
        let mut idx: Vec<usize> = (0..n).collect();
        idx.sort_by(|&a, &b| {
            t[a].total_cmp(&t[b])
                .then(im[a].camera_id.cmp(&im[b].camera_id))
                .then(im[a].id.cmp(&im[b].id))
        });
        let repeated = idx.windows(2).any(|w| t[w[0]] == t[w[1]]);
        if !repeated {
            let stamps = idx.iter().map(|&i| t[i]).collect();
            return (idx, stamps, FrameTimes::ImageNames, None);
        }
        if !all_images {
            let mut kept: Vec<usize> = Vec::with_capacity(n);
            for i in idx {
                if kept.last().is_none_or(|&k| t[k] != t[i]) {
                    kept.push(i);
                }
            }
            let note = format!(
                "{} of {n} images share their time stamp with another image (a rig's cameras): \
                 the time pairing uses, per stamp, the image of the lowest camera id",
                n - kept.len()
            );
            let stamps = kept.iter().map(|&i| t[i]).collect();
            return (kept, stamps, FrameTimes::ImageNames, Some(note));
        }
    }
    let mut idx: Vec<usize> = (0..n).collect();
    idx.sort_by(|&a, &b| im[a].name.cmp(&im[b].name).then(im[a].id.cmp(&im[b].id)));
    let stamps = (0..n).map(|k| k as f64).collect();
    (idx, stamps, FrameTimes::ImageRank, None)
}

/// The frames trajectory (`T_slam_cam`) and frame infos of `rows`.
fn colmap_frames(
    model: &ColmapModel,
    rows: &[usize],
    stamps: Vec<f64>,
) -> Result<(Trajectory, Vec<FrameInfo>)> {
    let mut positions = Vec::with_capacity(rows.len());
    let mut rotations = Vec::with_capacity(rows.len());
    let mut info = Vec::with_capacity(rows.len());
    for &i in rows {
        let im = &model.images[i];
        let pose = im.world_from_cam();
        positions.push(pose.translation);
        rotations.push(pose.rotation);
        info.push(FrameInfo {
            name: Some(im.name.clone()),
            camera: model.camera(im.camera_id).and_then(|c| c.pinhole().ok()),
        });
    }
    Ok((
        Trajectory::try_new(stamps, positions, Some(rotations))?,
        info,
    ))
}

/// The points3D as a cloud (SLAM frame, colours) whose `keyframe_ids` are,
/// per point, the id of the observing image whose centre is nearest to it
/// (`-1` for a point without observations or an id above `i32::MAX`), and the
/// image centres by id: the ray origins of an octree.
fn colmap_cloud(model: &ColmapModel) -> (PointCloud, BTreeMap<i32, Vector3<f64>>) {
    let centres: HashMap<u32, Vector3<f64>> =
        model.images.iter().map(|im| (im.id, im.centre())).collect();
    let n = model.points3d.len();
    let mut points = Vec::with_capacity(3 * n);
    let mut colors = Vec::with_capacity(3 * n);
    let mut ids = Vec::with_capacity(n);
    for p in &model.points3d {
        let x = Vector3::from(p.xyz);
        points.extend(p.xyz.map(|v| v as f32));
        colors.extend(p.rgb);
        let mut best: Option<(f64, u32)> = None;
        for t in &p.track {
            if let Some(c) = centres.get(&t.image_id) {
                let d = (c - x).norm_squared();
                if best.is_none_or(|(bd, bid)| d < bd || (d == bd && t.image_id < bid)) {
                    best = Some((d, t.image_id));
                }
            }
        }
        ids.push(
            best.and_then(|(_, id)| i32::try_from(id).ok())
                .unwrap_or(-1),
        );
    }
    let origins = centres
        .iter()
        .filter_map(|(&id, c)| i32::try_from(id).ok().map(|id| (id, *c)))
        .collect();
    let cloud = PointCloud {
        points,
        colors: Some(colors),
        keyframe_ids: ids,
    };
    (cloud, origins)
}

/// A COLMAP model as a recording (see the module documentation).
fn colmap_recording(dir: &Path, model: ColmapModel) -> Result<Recording> {
    if model.images.is_empty() {
        return Err(not_found(dir, "the model has no registered images"));
    }
    let (rows, stamps, frame_times, note) = colmap_frame_rows(&model, false);
    let (frames, frame_info) = colmap_frames(&model, &rows, stamps)?;
    let (cloud, origins) = colmap_cloud(&model);
    let format = model.format;
    Ok(Recording {
        source: SourceInfo {
            path: dir.to_path_buf(),
            format: "colmap".into(),
            reconstruction: Some(ReconstructionInfo {
                kind: ReconstructionKind::Colmap(format),
                frame_times,
                slam_text: None,
                octree_origins: Some(
                    "each point from the centre of the observing image nearest to it".into(),
                ),
                notes: note.into_iter().collect(),
            }),
            ..SourceInfo::default()
        },
        frames: Some(frames),
        frame_info,
        cloud: Some(cloud),
        cloud_origins: Some(origins),
        native: Some(NativeModel::Colmap(Box::new(model))),
        ..Recording::default()
    })
}

/// A DROID-SLAM folder as a recording of keyframes, filtered by `filter`.
fn droid_recording(dir: &Path, filter: Option<&DepthFilter>) -> Result<Recording> {
    let r = read_droid(dir)?;
    let mut notes = vec![format!(
        "images {}x{} pixels, disparities at 1/{} of that",
        r.image_size.1, r.image_size.0, r.downsample
    )];
    let keyframes = match filter {
        Some(f) => {
            notes.push(format!(
                "disparities kept where at least {} of the neighbouring keyframes {:?} agree within {} \
                 (depth units) and above {} x the keyframe's mean",
                f.min_count, f.neighbours, f.threshold, f.min_disparity_ratio
            ));
            filter_consistent(&r.keyframes, f)?
        }
        None => {
            notes.push("no depth filter: every positive disparity kept".into());
            r.keyframes
        }
    };
    Ok(Recording {
        source: SourceInfo {
            path: dir.to_path_buf(),
            format: "droid".into(),
            reconstruction: Some(ReconstructionInfo {
                kind: ReconstructionKind::Droid,
                frame_times: FrameTimes::Tstamps,
                slam_text: None,
                octree_origins: Some("each keyframe's points from its camera centre".into()),
                notes,
            }),
            ..SourceInfo::default()
        },
        keyframes,
        ..Recording::default()
    })
}

/// A trajectory file (and its cloud) as a recording.
fn trajectory_recording(file: &Path, opts: &ReconstructionOptions) -> Result<Recording> {
    let (frames, info) = read_trajectory(file, opts.time_unit)?;
    let cloud_path = opts.cloud.clone().or_else(|| cloud_beside(file));
    let cloud = match &cloud_path {
        Some(p) => Some(crate::io::ply::read_cloud(p)?),
        None => None,
    };
    let mut notes = Vec::new();
    if info.repeated_stamps > 0 {
        notes.push(format!(
            "{} rows repeat the previous row's stamp: the first row of each stamp is kept",
            info.repeated_stamps
        ));
    }
    Ok(Recording {
        source: SourceInfo {
            path: file.to_path_buf(),
            format: "trajectory".into(),
            cloud_path,
            reconstruction: Some(ReconstructionInfo {
                kind: ReconstructionKind::Trajectory,
                frame_times: FrameTimes::File,
                slam_text: Some(info),
                octree_origins: None,
                notes,
            }),
            ..SourceInfo::default()
        },
        frames: Some(frames),
        cloud,
        ..Recording::default()
    })
}

/// A reference file and how to read it.
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceSpec {
    /// The file.
    pub path: PathBuf,
    /// Its format ([`detect_reference_format`] when `None`).
    pub format: Option<ReferenceFormat>,
    /// The unit of its stamps (detected for TUM order; EuRoC's are
    /// nanoseconds unless given).
    pub time_unit: Option<TimeUnit>,
}

/// A reference as read.
#[derive(Clone, Debug)]
pub enum Reference {
    /// Poses `T_world_body` by time (seconds).
    Poses(Trajectory),
    /// Positions by image name (metres, world frame).
    Names(Vec<NamedPosition>),
}

/// Bytes of a reference file looked at to detect its format.
const DETECT_BYTES: u64 = 64 * 1024;

/// The format of a reference file from its first lines:
/// - `names` when the first record has 4 fields and the first is no number
///   (`image.png x y z`; a `name x y z` header line counts too);
/// - `euroc` when the fields are comma-separated and either there are more
///   than 8 of them (EuRoC ground truth has 17) or the last `#` line before
///   the first record names the quaternion's `w` before its `x` (`q_RS_w`,
///   `qw`, `q_w`);
/// - `tum` otherwise (TUM column order, white space or commas).
pub fn detect_reference_format(path: &Path) -> Result<ReferenceFormat> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(Error::parse(path, 0, "not a regular file"));
    }
    let mut head = Vec::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(DETECT_BYTES).read_to_end(&mut head))
        .map_err(|e| Error::io(path, e))?;
    let text = String::from_utf8_lossy(&head);
    let mut header = "";
    for raw in text.lines() {
        let line = raw.trim().trim_start_matches('\u{feff}');
        if line.is_empty() {
            continue;
        }
        if line.starts_with('#') {
            header = line;
            continue;
        }
        let comma = line.contains(',');
        let fields: Vec<&str> = if comma {
            line.split(',').map(str::trim).collect()
        } else {
            line.split_whitespace().collect()
        };
        if fields.len() == 4 && fields[0].parse::<f64>().is_err() {
            return Ok(ReferenceFormat::Names);
        }
        if comma && fields.len() > 8 {
            return Ok(ReferenceFormat::Euroc);
        }
        if comma && w_before_x(&header.to_ascii_lowercase()) {
            return Ok(ReferenceFormat::Euroc);
        }
        return Ok(ReferenceFormat::Tum);
    }
    Err(Error::parse(path, 0, "no records in the reference file"))
}

/// True when a header names the quaternion's `w` before its `x`.
fn w_before_x(header: &str) -> bool {
    let find = |keys: &[&str]| keys.iter().filter_map(|k| header.find(k)).min();
    match (
        find(&["q_rs_w", "q_w", "qw"]),
        find(&["q_rs_x", "q_x", "qx"]),
    ) {
        (Some(w), Some(x)) => w < x,
        _ => false,
    }
}

/// Reads a reference file, its format detected unless given.
pub fn read_reference(spec: &ReferenceSpec) -> Result<(Reference, ReferenceFileInfo)> {
    let (format, detected) = match spec.format {
        Some(f) => (f, false),
        None => (detect_reference_format(&spec.path)?, true),
    };
    let mut info = ReferenceFileInfo {
        path: spec.path.clone(),
        format,
        format_detected: detected,
        text: None,
        pairing: Pairing::Time,
        names: None,
    };
    let reference = match format {
        ReferenceFormat::Tum => {
            let (t, text) = read_trajectory(&spec.path, spec.time_unit)?;
            info.text = Some(text);
            Reference::Poses(t)
        }
        ReferenceFormat::Euroc => {
            let mut t = read_euroc(&spec.path)?;
            if let Some(u) = spec.time_unit {
                // read_euroc reads nanoseconds; another unit reads again.
                TimeUnit::Nanoseconds.reread(&mut t.timestamps, u);
            }
            Reference::Poses(t)
        }
        ReferenceFormat::Names => {
            if spec.time_unit.is_some() {
                return Err(Error::invalid(
                    "reference_time_unit",
                    "a reference by name has no stamps",
                ));
            }
            info.pairing = Pairing::Name;
            Reference::Names(read_name_positions(&spec.path)?)
        }
    };
    Ok((reference, info))
}

/// Gives `rec` the reference in `spec`: poses by time become its reference
/// trajectory; positions by name are paired with the frames of the same name
/// (each gets that frame's stamp, see the module documentation).
///
/// Errors: the reader's; a reference by time for COLMAP images whose names
/// are no time stamps; a reference by name for an input without frame names;
/// fewer than 3 reference names among the frames' ([`Error::TooFew`], with
/// examples of both sides' names).
pub fn attach_reference(rec: &mut Recording, spec: &ReferenceSpec) -> Result<()> {
    let (reference, mut info) = read_reference(spec)?;
    match reference {
        Reference::Poses(mut t) => {
            match_reference_unit(rec, &mut t, &mut info);
            if let Some(r) = &rec.source.reconstruction {
                if r.frame_times == FrameTimes::ImageRank {
                    let example = rec
                        .frame_info
                        .first()
                        .and_then(|f| f.name.clone())
                        .unwrap_or_default();
                    return Err(Error::invalid(
                        "reference",
                        format!(
                            "the image names of {} are no time stamps (e.g. {}), so a reference by time cannot be \
                             paired with them: give positions by image name (reference format \"names\")",
                            rec.source.path.display(),
                            cut(&example)
                        ),
                    ));
                }
            }
            rec.reference = Some(Arc::new(t));
        }
        Reference::Names(named) => {
            rebuild_for_names(rec)?;
            let (t, names) = paired_by_name(rec, &named, &spec.path)?;
            rec.reference = Some(Arc::new(t));
            info.names = Some(names);
        }
    }
    // The file's reference replaces the log's, wherever that was.
    rec.reference_on_disk = None;
    rec.source.reference_topic = None;
    rec.source.reference_path = Some(spec.path.clone());
    rec.source.reference_file = Some(info);
    Ok(())
}

/// A reference file's stamp unit found against the SLAM stamps, as `align`
/// finds it ([`match_time_units`]): where the reference's unit was detected
/// from its own stamps alone, the unit that makes the two time spans overlap
/// replaces it (relative stamps in milliseconds read as seconds, say). The
/// SLAM stamps keep the unit they were read in.
fn match_reference_unit(rec: &Recording, t: &mut Trajectory, info: &mut ReferenceFileInfo) {
    let Some(text) = info.text.as_mut().filter(|x| x.unit_detected) else {
        return;
    };
    let slam_unit = rec
        .source
        .reconstruction
        .as_ref()
        .and_then(|r| r.slam_text.as_ref())
        .map_or(TimeUnit::Seconds, |x| x.unit);
    let Some(frames) = rec.frames.as_ref().filter(|f| !f.is_empty()) else {
        return;
    };
    let (_, unit) = match_time_units(
        &slam_unit.written(&frames.timestamps),
        &text.unit.written(&t.timestamps),
        Some(slam_unit),
        None,
        0.0,
    );
    text.unit.reread(&mut t.timestamps, unit);
    text.unit = unit;
}

/// A COLMAP recording whose frames leave out images (a rig's shared stamps)
/// gets every image back, with the stamps that keep them apart.
fn rebuild_for_names(rec: &mut Recording) -> Result<()> {
    let Some(model) = rec.native.as_ref().and_then(NativeModel::colmap) else {
        return Ok(());
    };
    if rec.frame_info.len() == model.images.len() {
        return Ok(());
    }
    let (rows, stamps, frame_times, _) = colmap_frame_rows(model, true);
    let (frames, info) = colmap_frames(model, &rows, stamps)?;
    rec.frames = Some(frames);
    rec.frame_info = info;
    if let Some(r) = &mut rec.source.reconstruction {
        r.frame_times = frame_times;
        r.notes
            .retain(|n| !n.contains("share their time stamp with another image"));
    }
    Ok(())
}

/// The reference trajectory of `named` positions, each at the stamp of the
/// frame of the same name.
fn paired_by_name(
    rec: &Recording,
    named: &[NamedPosition],
    path: &Path,
) -> Result<(Trajectory, NamePairing)> {
    let Some(frames) = rec.frames.as_ref().filter(|_| !rec.frame_info.is_empty()) else {
        let why = format!(
            "a reference by name needs image names, and {} ({}) has none: give poses by time",
            rec.source.path.display(),
            rec.source.format
        );
        return Err(Error::invalid("reference", why));
    };
    let rows: HashMap<&str, usize> = rec
        .frame_info
        .iter()
        .enumerate()
        .filter_map(|(k, f)| f.name.as_deref().map(|n| (n, k)))
        .collect();
    let mut pairs: Vec<(f64, Vector3<f64>)> = Vec::with_capacity(named.len());
    let mut unknown = Vec::new();
    for p in named {
        match rows.get(p.name.as_str()) {
            Some(&k) => pairs.push((frames.timestamps[k], p.position)),
            None => unknown.push(p.name.clone()),
        }
    }
    if pairs.len() < 3 {
        let ours: Vec<String> = rec
            .frame_info
            .iter()
            .filter_map(|f| f.name.as_deref().map(cut))
            .take(3)
            .collect();
        let theirs: Vec<String> = unknown.iter().take(3).map(|n| cut(n)).collect();
        return Err(Error::TooFew {
            what: format!(
                "reference names that name an image of the input ({} names in {}; not images: {}; the images are named {}…)",
                named.len(),
                path.display(),
                theirs.join(", "),
                ours.join(", ")
            ),
            need: 3,
            got: pairs.len(),
        });
    }
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let report = NamePairing {
        reference_names: named.len(),
        matched: pairs.len(),
        unknown: unknown.len(),
        unknown_examples: unknown.into_iter().take(10).collect(),
    };
    let t = Trajectory::try_new(
        pairs.iter().map(|p| p.0).collect(),
        pairs.iter().map(|p| p.1).collect(),
        None,
    )?;
    Ok((t, report))
}

/// The options a conversion of `rec` runs with, where they differ from `opts`:
/// - paired by name: `max_diff = 0` (equal stamps only); a given `offset` or
///   an offset estimate is refused (names carry no clock); without a stated
///   reference noise, the refusals that rest on the noise estimated from
///   second differences (a static reference, an unmoved scale) are off;
/// - DROID-SLAM keyframes (depth-filtered as read, without variances) are
///   backprojected with [`PointFilter::none`] when `opts.filter` is the
///   LSD-SLAM viewer's default (which would drop the first six keyframes and
///   the border).
pub fn effective_options<'a>(
    rec: &Recording,
    opts: &'a ConvertOptions,
) -> Result<Cow<'a, ConvertOptions>> {
    let by_name = rec
        .source
        .reference_file
        .as_ref()
        .is_some_and(|r| r.pairing == Pairing::Name);
    let droid = rec
        .source
        .reconstruction
        .as_ref()
        .is_some_and(|r| r.kind == ReconstructionKind::Droid);
    let droid_filter = droid && opts.filter == PointFilter::default();
    if !by_name && !droid_filter {
        return Ok(Cow::Borrowed(opts));
    }
    let mut o = opts.clone();
    if by_name {
        if opts.align.offset != 0.0 || opts.align.estimate_offset.is_some() {
            return Err(Error::invalid(
                "offset",
                "a reference by image name is paired by name: a time offset does not apply",
            ));
        }
        o.align.max_diff = 0.0;
        // Images in name order are no path: the reference noise estimated
        // from second differences means nothing there, so the two refusals
        // that rest on it are made only with a stated noise.
        if o.align.checks.reference_noise.is_none() {
            o.align.checks.min_spread_over_noise = 0.0;
            o.align.checks.min_scale_change = 0.0;
        }
    }
    if droid_filter {
        o.filter = PointFilter::none();
    }
    Ok(Cow::Owned(o))
}

/// A source whose recording gets a reference file ([`attach_reference`]).
pub struct WithReference {
    /// The input.
    pub inner: Box<dyn Source>,
    /// The reference.
    pub reference: ReferenceSpec,
}

impl Source for WithReference {
    fn read(&self) -> Result<Recording> {
        let mut rec = self.inner.read()?;
        attach_reference(&mut rec, &self.reference)?;
        Ok(rec)
    }

    fn read_bounded(&self) -> Result<Recording> {
        let mut rec = self.inner.read_bounded()?;
        attach_reference(&mut rec, &self.reference)?;
        Ok(rec)
    }
}

/// The source of any input: a reconstruction ([`detect_reconstruction`]) or
/// a log ([`open_log`]), with `reference` attached when given.
pub fn open_input(
    path: &Path,
    read: &ReadOptions,
    recon: &ReconstructionOptions,
    reference: Option<&ReferenceSpec>,
) -> Result<Box<dyn Source>> {
    let inner: Box<dyn Source> = match detect_reconstruction(path, recon.colmap_format)? {
        Some(_) => Box::new(ReconstructionSource {
            path: path.to_path_buf(),
            options: recon.clone(),
        }),
        None => open_log(path, read)?,
    };
    Ok(match reference {
        Some(r) => Box::new(WithReference {
            inner,
            reference: r.clone(),
        }),
        None => inner,
    })
}
