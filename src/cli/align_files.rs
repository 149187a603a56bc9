//! The files of `slam2world align`: reading a trajectory file in its format
//! with its stamps (TUM, EuRoC, KITTI with a `times.txt`, a rate or the pose
//! index, `transforms.json` by image names or frame order), pairing two
//! files without stamps by index and two scenes by file name, and the
//! outputs (`-o`: the estimate carried by the fit, `--save-transform`).

use std::path::Path;

use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::io::colmap::image_name_time;
use crate::io::kitti::{self, read_kitti, read_times, KittiStamps};
use crate::io::text::{euroc_bytes, tum_bytes, TimeUnit, TrajectoryFormat};
use crate::io::transforms::{read_transforms, Frame, Transforms};
use crate::pipeline::report::TransformReport;
use crate::trajectory::Trajectory;

/// The estimate carried by `t` (every pose) as `format` writes it; TUM
/// stamps in `unit`, the one EST was written in.
pub(super) fn aligned_bytes(
    est: &Trajectory,
    scene: Option<&Transforms>,
    t: &Sim3,
    format: TrajectoryFormat,
    unit: TimeUnit,
) -> Result<Vec<u8>> {
    let mut aligned = est.transformed(t);
    match format {
        TrajectoryFormat::Transforms => match scene {
            Some(s) => s.carried_bytes(t),
            None => Err(Error::invalid(
                "--output-format",
                "transforms needs EST to be a transforms.json (its other keys are written back)",
            )),
        },
        TrajectoryFormat::Tum => {
            aligned.timestamps = unit.written(&aligned.timestamps);
            tum_bytes(&aligned)
        }
        TrajectoryFormat::Euroc => euroc_bytes(&aligned),
        TrajectoryFormat::Kitti => kitti::kitti_bytes(&aligned),
    }
}

/// `t` as `--save-transform` writes it: JSON for a `.json` path (the
/// reports' transform: quaternion, translation, scale, matrix), else the
/// 4×4 matrix as 4 lines of 4 numbers (the shortest form that reads back
/// exactly).
pub(super) fn transform_bytes(path: &Path, t: &Sim3) -> Result<Vec<u8>> {
    let json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    if json {
        let mut v = serde_json::to_vec_pretty(&TransformReport::from(t))
            .map_err(|e| Error::invalid("--save-transform", e.to_string()))?;
        v.push(b'\n');
        return Ok(v);
    }
    let m = t.matrix();
    let rows: Vec<String> = (0..4)
        .map(|r| {
            let row: Vec<String> = (0..4).map(|c| m[(r, c)].to_string()).collect();
            row.join(" ") + "\n"
        })
        .collect();
    Ok(rows.concat().into_bytes())
}

/// A trajectory file and the unit its stamps were read in: TUM stamps as
/// they are written (seconds; every row kept, as evo reads them), EuRoC's
/// nanoseconds, a KITTI file's from `times` / `rate` (seconds) or its pose
/// index (`indexed`).
pub(super) struct Read {
    pub(super) trajectory: Trajectory,
    pub(super) unit: TimeUnit,
    /// The stamps are the poses' index (a KITTI file without stamps).
    pub(super) indexed: bool,
    /// `unit` is the format's (EuRoC nanoseconds; a KITTI rate or index),
    /// not to be found from the values.
    pub(super) known: bool,
    /// The scene, when the file is a `transforms.json`.
    pub(super) scene: Option<Transforms>,
}

/// Reads `path` as `format`; `times` and `rate` (the `--*-times`,
/// `--*-rate` of `side`) give a KITTI file its stamps.
pub(super) fn read_as_written(
    format: TrajectoryFormat,
    path: &Path,
    times: Option<&Path>,
    rate: Option<f64>,
    side: &str,
) -> Result<Read> {
    if format != TrajectoryFormat::Kitti && (times.is_some() || rate.is_some()) {
        return Err(Error::invalid(
            format!("--{side}-times/--{side}-rate"),
            format!(
                "give stamps to KITTI files only; {} is read as {format:?} (stamps in the file)",
                path.display()
            ),
        ));
    }
    let read = |trajectory, unit, known| Read {
        trajectory,
        unit,
        indexed: false,
        known,
        scene: None,
    };
    Ok(match format {
        TrajectoryFormat::Tum => read(format.read(path)?, TimeUnit::Seconds, false),
        TrajectoryFormat::Euroc => read(format.read(path)?, TimeUnit::Nanoseconds, true),
        TrajectoryFormat::Kitti => {
            let stamps = match (times, rate) {
                (Some(t), _) => KittiStamps::Times(read_times(t)?),
                (None, Some(r)) => KittiStamps::Rate(r),
                (None, None) => KittiStamps::Index,
            };
            let indexed = stamps == KittiStamps::Index;
            Read {
                known: !matches!(stamps, KittiStamps::Times(_)),
                trajectory: read_kitti(path, &stamps)?,
                unit: TimeUnit::Seconds,
                indexed,
                scene: None,
            }
        }
        TrajectoryFormat::Transforms => {
            let scene = read_transforms(path)?;
            // Frames named by stamps are timed by them; else the frame order.
            let indexed = scene
                .frames
                .iter()
                .any(|f| image_name_time(&f.file_path).is_none());
            Read {
                trajectory: scene.trajectory()?,
                unit: TimeUnit::Seconds,
                indexed,
                // Seconds: the names' stamps or the frame order.
                known: true,
                scene: Some(scene),
            }
        }
    })
}

/// REF's poses restamped to pair with EST's by file name
/// ([`Transforms::key`]): each REF frame takes the stamp of the EST frame of
/// its name; frames of no shared name are left out. Fewer than three shared
/// names, or a name twice in one scene, is an error.
pub(super) fn paired_by_name(
    est: &Transforms,
    est_traj: &Trajectory,
    r: &Transforms,
    ref_path: &Path,
) -> Result<Trajectory> {
    let (stamps, frames) = est.stamped();
    let mut by_key = std::collections::HashMap::new();
    for (t, f) in stamps.iter().zip(&frames) {
        if by_key.insert(Transforms::key(&f.file_path), *t).is_some() {
            return Err(Error::invalid(
                "EST",
                format!("two frames named {}: frames pair by file name", f.file_path),
            ));
        }
    }
    let mut rows: Vec<(f64, &Frame)> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for f in &r.frames {
        let key = Transforms::key(&f.file_path);
        if !seen.insert(key) {
            return Err(Error::invalid(
                "REF",
                format!("two frames named {}: frames pair by file name", f.file_path),
            ));
        }
        if let Some(&t) = by_key.get(key) {
            rows.push((t, f));
        }
    }
    if rows.len() < 3 {
        return Err(Error::invalid(
            "EST/REF",
            format!(
                "{} of the {} frames of {} share a file name with the {} of EST: two \
                 transforms.json pair by file name, and a fit needs 3",
                rows.len(),
                r.frames.len(),
                ref_path.display(),
                est_traj.len()
            ),
        ));
    }
    rows.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (positions, orientations) = rows.iter().map(|r| r.1.pose()).unzip();
    Trajectory::try_new(
        rows.iter().map(|r| r.0).collect(),
        positions,
        Some(orientations),
    )
}

/// Two KITTI files without stamps pair by index (as many poses in each);
/// one without stamps beside stamped poses cannot be paired.
pub(super) fn check_indexed(est: &Read, r: &Read, est_path: &Path, ref_path: &Path) -> Result<()> {
    let (n, m) = (est.trajectory.len(), r.trajectory.len());
    match (est.indexed, r.indexed) {
        (true, true) if n != m => Err(Error::invalid(
            "EST/REF",
            format!(
                "{} has {n} poses and {} has {m}: files without stamps (KITTI, a \
                 transforms.json timed by its frame order) pair by index and need as many \
                 poses (or give KITTI files --est-times/--ref-times)",
                est_path.display(),
                ref_path.display()
            ),
        )),
        (true, false) | (false, true) => {
            let (side, path, read) = if est.indexed {
                ("est", est_path, est)
            } else {
                ("ref", ref_path, r)
            };
            Err(unstamped(read, path, side, "the other side's stamps"))
        }
        _ => Ok(()),
    }
}

/// The error of a file without stamps (`side` its flags' prefix) that was
/// to pair with `what` by time.
pub(super) fn unstamped(read: &Read, path: &Path, side: &str, what: &str) -> Error {
    if read.scene.is_some() {
        return Error::invalid(
            "EST/REF",
            format!(
                "{}: no frame's file name is a stamp, so its frames are timed by their order \
                 and cannot pair with {what}; it pairs with another transforms.json of the \
                 same images (by file name) or by index with KITTI poses without stamps",
                path.display()
            ),
        );
    }
    Error::invalid(
        format!("--{side}-times"),
        format!(
            "{} is a KITTI file without stamps: give --{side}-times times.txt or --{side}-rate \
             HZ to pair it with {what}",
            path.display()
        ),
    )
}

/// `t`, read in `read`, with its stamps in seconds of `unit`.
pub(super) fn in_unit(mut t: Trajectory, read: TimeUnit, unit: TimeUnit) -> Trajectory {
    read.reread(&mut t.timestamps, unit);
    t
}
