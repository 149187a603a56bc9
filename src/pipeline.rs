//! `convert`: a SLAM log in, the metric world out.
//!
//! Keyframe stamps (the messages' own `time`) are associated with the reference
//! poses (`max_diff`, `offset`), `T_world_slam` is fitted on the keyframe
//! positions (Horn, Sim(3)), and the keyframes are backprojected with
//! `T_world_slam · T_slam_cam` fused per keyframe. The result carries the
//! alignment, the world cloud, both trajectories in the world frame and a report
//! (alignment, residuals, frames used and dropped, timing).
//!
//! With [`ConvertOptions::octree_resolution`] set, the world cloud also
//! becomes an occupancy octree ([`OccupancyMap`], OctoMap semantics): each
//! keyframe's points are inserted as one scan whose sensor origin is that
//! keyframe's camera centre in the world frame (the translation of
//! `T_world_slam · T_slam_cam`); the outputs then include `map.bt` and the
//! occupied voxels in `world.mcap`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use crate::align::extended::{align_trajectories_extended, ExtendedAlignment, ExtendedOptions};
use crate::align::windowed::{align_windowed, Window, WindowedOptions};
use crate::cloud::{backproject, backproject_per_keyframe, PointCloud, PointFilter};
use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::io::mcap::{
    read_mcap, write_world_mcap_with_octomap, Log, ReadOptions, WorldFlavor, WorldScene,
};
use crate::map::{MapParams, OccupancyMap, VoxelState};
use crate::trajectory::{ApeStats, Trajectory, TrajectoryAlignOptions};

/// Everything `convert` can be told.
#[derive(Clone, Debug, Default)]
pub struct ConvertOptions {
    /// Topics to read (found by schema when `None`).
    pub read: ReadOptions,
    /// Association and fit: `max_diff` (s), `offset` (s, added to the SLAM
    /// stamps), `first_n` (fit on the first n pairs: the CLI's `--n-to-align`), scale.
    pub align: TrajectoryAlignOptions,
    /// Which pixels become points (the LSD-SLAM viewer's defaults by default).
    pub filter: PointFilter,
    /// Start-up cut, robust fit, orientations, time offset, extrinsic.
    pub beyond: ExtendedOptions,
    /// Also fit a windowed (drift-aware) alignment and compare it with the
    /// single Sim(3) in the report.
    pub compare_windowed: Option<Window>,
    /// Carry each keyframe (its points, camera centre and world pose) with the
    /// windowed alignment at its time instead of the single Sim(3); needs
    /// `compare_windowed` (the window). The report's `t_world_slam` stays the
    /// single fit.
    pub windowed_cloud: bool,
    /// Inertial initialisation, used when the log has raw IMU samples: for
    /// `T_world_slam` without reference poses, as a consistency check with them.
    pub imu: crate::imu::ImuInitOptions,
    /// Voxel edge (metres) of the occupancy octree built from the world cloud;
    /// `None` builds none.
    pub octree_resolution: Option<f64>,
    /// Rays longer than this (metres) only clear space in the octree and mark
    /// no endpoint; `None` for no limit. Used only with `octree_resolution`.
    pub octree_max_range: Option<f64>,
}

impl ConvertOptions {
    /// Checks the options that do not depend on the log (the octree's
    /// parameters; `windowed_cloud` needs `compare_windowed`).
    pub fn check(&self) -> Result<()> {
        if self.windowed_cloud && self.compare_windowed.is_none() {
            return Err(Error::invalid(
                "windowed_cloud",
                "needs the window of the windowed alignment (compare_windowed)",
            ));
        }
        self.octree_params().map(|_| ())
    }

    /// The octree's parameters (OctoMap's sensor model defaults), `None` when
    /// no octree is asked for; checks the resolution and the max range.
    pub fn octree_params(&self) -> Result<Option<MapParams>> {
        let Some(resolution) = self.octree_resolution else {
            return Ok(None);
        };
        let params = MapParams {
            max_range: self.octree_max_range,
            ..MapParams::new(resolution)
        };
        OccupancyMap::try_new(params)?;
        Ok(Some(params))
    }
}

/// What the report says of the octree.
#[derive(Clone, Debug, Serialize)]
pub struct OctreeReport {
    /// Voxel edge length, metres.
    pub resolution: f64,
    /// Max range of the rays, metres (`None`: no limit).
    pub max_range: Option<f64>,
    /// Scans inserted (keyframes with points).
    pub scans: usize,
    /// Points inserted.
    pub points: usize,
    /// Occupied leaves (pruned leaves count once).
    pub leaves_occupied: usize,
    /// Free leaves (pruned leaves count once).
    pub leaves_free: usize,
    /// Nodes of the tree, inner and leaf.
    pub nodes: usize,
    /// Heap bytes held by the tree.
    pub memory_bytes: usize,
    /// Wall time of the insertion, seconds.
    pub time_s: f64,
}

/// `T_world_slam` as the report writes it.
#[derive(Clone, Debug, Serialize)]
pub struct TransformReport {
    /// Rotation `(x, y, z, w)`.
    pub quaternion_xyzw: [f64; 4],
    /// Translation, metres.
    pub translation: [f64; 3],
    /// Scale, metres per SLAM unit.
    pub scale: f64,
    /// The 4×4 matrix `[sR t; 0 1]`, row-major.
    pub matrix: [[f64; 4]; 4],
}

/// One keyframe matched with a reference pose.
#[derive(Clone, Debug, Serialize)]
pub struct PairReport {
    /// Keyframe id.
    pub keyframe_id: i32,
    /// Keyframe time, seconds.
    pub keyframe_time: f64,
    /// Time of the matched reference pose, seconds.
    pub reference_time: f64,
    /// `‖p_ref − T(p_slam)‖`, metres.
    pub error: f64,
    /// True when the pair was used in the fit (the first `n_to_align`).
    pub fitted: bool,
}

/// Wall time of each stage, seconds.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Timing {
    /// Reading and decoding the log.
    pub read_s: f64,
    /// Association and fit.
    pub align_s: f64,
    /// Backprojection into the world frame.
    pub backproject_s: f64,
    /// Writing the outputs (set by [`Conversion::write_all`]).
    pub write_s: f64,
}

/// What `report.json` holds.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// The log read.
    pub input: PathBuf,
    /// Topics used.
    pub keyframe_topic: Option<String>,
    /// Topic of the graph updates.
    pub graph_topic: Option<String>,
    /// Topic of the reference poses.
    pub reference_topic: Option<String>,
    /// Keyframes in the log (latest version per id).
    pub keyframes: usize,
    /// Reference poses in the log.
    pub reference_poses: usize,
    /// Keyframes matched with a reference pose (frames used).
    pub frames_used: usize,
    /// Keyframes without a reference pose within `max_diff` (frames dropped), by id.
    pub frames_dropped: Vec<i32>,
    /// Pairs the fit used.
    pub pairs_fitted: usize,
    /// Association parameters, seconds.
    pub max_diff: f64,
    /// Seconds added to the SLAM stamps.
    pub offset: f64,
    /// `T_world_slam`.
    pub t_world_slam: TransformReport,
    /// Fit residual rms over the fitted pairs, metres.
    pub fit_rmse: f64,
    /// APE over all pairs, metres: rmse, mean, median, std, min, max.
    pub ape: ApeReport,
    /// Every matched pair.
    pub pairs: Vec<PairReport>,
    /// What the options beyond one fit did: start-up cut and why, offset,
    /// inliers, 95 % confidence intervals.
    pub beyond: serde_json::Value,
    /// The windowed alignment against the single Sim(3), when asked for.
    pub windowed: Option<serde_json::Value>,
    /// Points in the world cloud.
    pub points: usize,
    /// Stage timings.
    pub timing: Timing,
    /// The inertial initialisation, when the log has raw IMU samples.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub imu: Option<crate::imu::convert::ImuReport>,
    /// The occupancy octree, when one was built.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub octree: Option<OctreeReport>,
}

/// APE statistics, metres.
#[derive(Clone, Debug, Serialize)]
pub struct ApeReport {
    /// Root mean square.
    pub rmse: f64,
    /// Mean.
    pub mean: f64,
    /// Median.
    pub median: f64,
    /// Population standard deviation.
    pub std: f64,
    /// Smallest.
    pub min: f64,
    /// Largest.
    pub max: f64,
}

impl From<&ApeStats> for ApeReport {
    fn from(a: &ApeStats) -> Self {
        ApeReport {
            rmse: a.rmse,
            mean: a.mean,
            median: a.median,
            std: a.std,
            min: a.min,
            max: a.max,
        }
    }
}

/// The result of [`convert`].
#[derive(Clone, Debug)]
pub struct Conversion {
    /// The fit with what the options beyond one fit found (start-up cut,
    /// inliers, offset, covariance): `alignment.trajectory.alignment.transform`
    /// is `T_world_slam`.
    pub alignment: ExtendedAlignment,
    /// The world cloud (metres, world frame).
    pub cloud: PointCloud,
    /// Keyframe positions and orientations (`T_world_cam`) in the world frame, by time.
    pub slam_trajectory: Trajectory,
    /// The reference trajectory (`T_world_body`).
    pub reference: Trajectory,
    /// The report.
    pub report: Report,
    /// The occupancy octree of the world cloud (world frame), when asked for.
    pub octree: Option<OccupancyMap>,
}

fn secs(t: Instant) -> f64 {
    t.elapsed().as_secs_f64()
}

/// The keyframe poses as a trajectory sorted by time, with the keyframe index of each row.
pub(crate) fn keyframe_trajectory(log: &Log) -> Result<(Trajectory, Vec<usize>)> {
    let mut order: Vec<usize> = (0..log.keyframes.len()).collect();
    order.sort_by(|&a, &b| {
        log.keyframes[a]
            .timestamp
            .total_cmp(&log.keyframes[b].timestamp)
    });
    let times = order.iter().map(|&i| log.keyframes[i].timestamp).collect();
    let positions = order
        .iter()
        .map(|&i| log.keyframes[i].pose.translation)
        .collect();
    let rotations = order
        .iter()
        .map(|&i| log.keyframes[i].pose.rotation)
        .collect();
    Ok((
        Trajectory::try_new(times, positions, Some(rotations))?,
        order,
    ))
}

fn mcap_err(path: &Path, reason: String) -> Error {
    Error::Mcap {
        path: path.to_path_buf(),
        reason,
    }
}

/// Aligns the log's keyframes with its reference and builds the world cloud.
///
/// Errors: no keyframes or no reference in the log, no keyframe stamp within
/// `max_diff` of a reference pose (naming the file and topics), and the fit's
/// own errors (fewer than 3 pairs, degenerate motion).
pub fn convert(log: &Log, opts: &ConvertOptions) -> Result<Conversion> {
    opts.check()?;
    let octree_params = opts.octree_params()?;
    let kf_topic = log.keyframe_topic.clone().unwrap_or_default();
    if log.keyframes.is_empty() {
        return Err(mcap_err(
            &log.path,
            if log.keyframe_topic.is_some() {
                format!("topic {kf_topic}: no keyframe with a point cloud")
            } else {
                "no lsd_slam_viewer/keyframeMsg topic in the log".into()
            },
        ));
    }
    let Some(reference) = &log.reference else {
        if let Some(imu) = &log.imu {
            return crate::imu::convert::convert_imu(log, imu, opts);
        }
        return Err(mcap_err(
            &log.path,
            "no reference pose topic and no raw IMU topic in the log".into(),
        ));
    };
    let ref_topic = log.reference_topic.clone().unwrap_or_default();
    let t0 = Instant::now();
    let (slam, order) = keyframe_trajectory(log)?;
    let ext = match align_trajectories_extended(&slam, reference, &opts.align, &opts.beyond) {
        Ok(ext) => ext,
        Err(Error::TooFew { need, got, .. }) => {
            return Err(mcap_err(
                &log.path,
                format!(
                    "{got} keyframe stamps of topic {kf_topic} match a reference pose of topic {ref_topic} \
                     within max_diff {} s (offset {} s), need {need}",
                    opts.align.max_diff, opts.align.offset
                ),
            ))
        }
        Err(e) => return Err(e),
    };
    let beyond = ext.report_json(0.95);
    let fit_start = ext.fit_start;
    let inliers = ext.inliers.clone();
    let offset = ext.offset;
    let ta = &ext.trajectory;
    // With `windowed_cloud`: T_world_slam per keyframe, in the log's order.
    let mut per_keyframe: Option<Vec<Sim3>> = None;
    let windowed = match opts.compare_windowed {
        Some(window) => {
            let w = align_windowed(
                &slam,
                reference,
                &WindowedOptions {
                    window,
                    max_diff: opts.align.max_diff,
                    offset,
                    scale: opts.align.scale,
                },
            )?;
            let scales = w.transforms.iter().map(|t| t.scale);
            let (lo, hi) = scales.fold((f64::INFINITY, 0.0f64), |(a, b), s| (a.min(s), b.max(s)));
            if opts.windowed_cloud {
                per_keyframe = Some(
                    log.keyframes
                        .iter()
                        .map(|k| w.transform_at(k.timestamp))
                        .collect(),
                );
            }
            Some(serde_json::json!({
                "cloud": if opts.windowed_cloud { "windowed" } else { "single" },
                "window": format!("{window:?}"),
                "windowed_rmse": w.rmse,
                "single_rmse": w.global.rmse,
                "scale_min": lo,
                "scale_max": hi,
            }))
        }
        None => None,
    };
    let align_s = secs(t0);
    let t = ta.alignment.transform;

    let t1 = Instant::now();
    let cloud = match &per_keyframe {
        Some(ts) => backproject_per_keyframe(&log.keyframes, &opts.filter, ts)?,
        None => backproject(&log.keyframes, &opts.filter, Some(&t))?,
    };
    let backproject_s = secs(t1);
    // T_world_slam of keyframe `i` of the log.
    let t_of = |i: usize| per_keyframe.as_ref().map_or(t, |ts| ts[i]);

    let (octree, octree_report) = match octree_params {
        Some(params) => {
            let origins = log
                .keyframes
                .iter()
                .enumerate()
                .map(|(i, kf)| (kf.id, camera_center(kf, &t_of(i))))
                .collect();
            let (map, report) = build_octree(&origins, &cloud, params)?;
            (Some(map), Some(report))
        }
        None => (None, None),
    };

    let world_slam = Trajectory::try_new(
        slam.timestamps.clone(),
        slam.positions
            .iter()
            .zip(&order)
            .map(|(p, &i)| t_of(i).transform_point(p))
            .collect(),
        slam.orientations.as_ref().map(|o| {
            o.iter()
                .zip(&order)
                .map(|(q, &i)| t_of(i).rotation * q)
                .collect()
        }),
    )?;

    let n_fit = opts
        .align
        .first_n
        .map_or(ta.pairs.len() - fit_start.min(ta.pairs.len()), |n| {
            n.min(ta.pairs.len() - fit_start.min(ta.pairs.len()))
        });
    let mut used = vec![false; slam.len()];
    let pairs: Vec<PairReport> = ta
        .pairs
        .iter()
        .zip(&ta.errors)
        .enumerate()
        .map(|(k, (&(s, r), &error))| {
            used[s] = true;
            PairReport {
                keyframe_id: log.keyframes[order[s]].id,
                keyframe_time: slam.timestamps[s],
                reference_time: reference.timestamps[r],
                error,
                fitted: k >= fit_start
                    && k < fit_start + n_fit
                    && inliers.as_ref().is_none_or(|m| m[k - fit_start]),
            }
        })
        .collect();
    let frames_dropped = (0..slam.len())
        .filter(|&s| !used[s])
        .map(|s| log.keyframes[order[s]].id)
        .collect();
    let imu = log.imu.as_ref().map(|imu| {
        crate::imu::convert::consistency_report(&slam, imu, log.imu_topic.clone(), &opts.imu, &t)
    });
    let report = Report {
        input: log.path.clone(),
        keyframe_topic: log.keyframe_topic.clone(),
        graph_topic: log.graph_topic.clone(),
        reference_topic: log.reference_topic.clone(),
        keyframes: log.keyframes.len(),
        reference_poses: reference.len(),
        frames_used: used.iter().filter(|u| **u).count(),
        frames_dropped,
        pairs_fitted: n_fit,
        max_diff: opts.align.max_diff,
        offset,
        t_world_slam: transform_report(&t),
        fit_rmse: ta.alignment.rmse,
        ape: ApeReport::from(&ta.ape),
        pairs,
        beyond,
        windowed,
        points: cloud.len(),
        timing: Timing {
            read_s: 0.0,
            align_s,
            backproject_s,
            write_s: 0.0,
        },
        imu,
        octree: octree_report,
    };
    Ok(Conversion {
        alignment: ext,
        cloud,
        slam_trajectory: world_slam,
        reference: reference.clone(),
        report,
        octree,
    })
}

/// Camera centres of the keyframes in the world frame (metres), by id: the
/// translation of `T_world_slam · T_slam_cam`.
pub fn camera_centers(log: &Log, t_world_slam: &Sim3) -> BTreeMap<i32, [f32; 3]> {
    log.keyframes
        .iter()
        .map(|kf| (kf.id, camera_center(kf, t_world_slam)))
        .collect()
}

/// A keyframe's camera centre in the world frame (OctoMap's `f32`).
fn camera_center(kf: &crate::keyframe::Keyframe, t_world_slam: &Sim3) -> [f32; 3] {
    let c = t_world_slam.transform_point(&kf.pose.translation);
    [c.x as f32, c.y as f32, c.z as f32]
}

/// A transform as the report writes it (quaternion, translation, scale, 4×4).
pub(crate) fn transform_report(t: &Sim3) -> TransformReport {
    let m = t.matrix();
    TransformReport {
        quaternion_xyzw: t.quaternion_xyzw(),
        translation: [t.translation.x, t.translation.y, t.translation.z],
        scale: t.scale,
        matrix: std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)])),
    }
}

/// Inserts the world cloud keyframe by keyframe, each from its camera centre.
pub(crate) fn build_octree(
    origins: &BTreeMap<i32, [f32; 3]>,
    cloud: &PointCloud,
    params: MapParams,
) -> Result<(OccupancyMap, OctreeReport)> {
    let t = Instant::now();
    let mut map = OccupancyMap::try_new(params)?;
    map.insert_keyframes(&cloud.points, &cloud.keyframe_ids, origins)?;
    let time_s = secs(t);
    let mut scans: Vec<i32> = cloud.keyframe_ids.clone();
    scans.sort_unstable();
    scans.dedup();
    let report = OctreeReport {
        resolution: params.resolution,
        max_range: params.max_range,
        scans: scans.len(),
        points: cloud.len(),
        leaves_occupied: map.leaves(VoxelState::Occupied).len(),
        leaves_free: map.leaves(VoxelState::Free).len(),
        nodes: map.num_nodes(),
        memory_bytes: map.memory_bytes(),
        time_s,
    };
    Ok((map, report))
}

/// Reads `path` and converts it; the report's `read_s` is filled in.
pub fn convert_file(path: impl AsRef<Path>, opts: &ConvertOptions) -> Result<Conversion> {
    opts.check()?;
    let t = Instant::now();
    let log = read_mcap(path, &opts.read)?;
    let read_s = secs(t);
    let mut c = convert(&log, opts)?;
    c.report.timing.read_s = read_s;
    Ok(c)
}

/// Output file names inside the output folder.
pub const WORLD_MCAP: &str = "world.mcap";
/// The world cloud as PLY.
pub const CLOUD_PLY: &str = "cloud.ply";
/// The report.
pub const REPORT_JSON: &str = "report.json";
/// The occupancy octree (OctoMap binary), written when the conversion has one.
pub const MAP_BT: &str = "map.bt";

impl Conversion {
    /// `T_world_slam`.
    pub fn transform(&self) -> crate::geometry::Sim3 {
        self.alignment.trajectory.alignment.transform
    }

    /// Writes `world.mcap` (cloud, both trajectories, `world → slam`, and the
    /// occupied voxels of the octree when there is one).
    pub fn write_world_mcap(&self, path: impl AsRef<Path>, flavor: WorldFlavor) -> Result<()> {
        let stamp = self
            .slam_trajectory
            .timestamps
            .last()
            .copied()
            .unwrap_or(0.0)
            .max(0.0);
        let scene = WorldScene {
            points: &self.cloud.points,
            colors: self.cloud.colors.as_deref(),
            t_world_slam: self.transform(),
            slam_trajectory: Some(&self.slam_trajectory),
            reference: Some(&self.reference),
            stamp,
            world_frame: "world",
            slam_frame: "slam",
        };
        let leaves = self.octree.as_ref().map(|m| m.leaves(VoxelState::Occupied));
        write_world_mcap_with_octomap(path, &scene, leaves.as_deref(), flavor)
    }

    /// Writes the octree as an OctoMap `.bt` file (through a temporary file,
    /// renamed). Error when the conversion has no octree.
    pub fn write_bt(&self, path: impl AsRef<Path>) -> Result<()> {
        match &self.octree {
            Some(m) => m.write_bt(path.as_ref()),
            None => Err(Error::invalid(
                "octree",
                "the conversion has no octree (convert with an octree resolution)",
            )),
        }
    }

    /// Writes the world cloud as binary PLY.
    pub fn write_ply(&self, path: impl AsRef<Path>) -> Result<()> {
        crate::io::ply::write_ply(path, &self.cloud)
    }

    /// Writes `report.json` (through a temporary file, renamed).
    pub fn write_report(&self, path: impl AsRef<Path>) -> Result<()> {
        write_json(path.as_ref(), &self.report)
    }

    /// Writes `world.mcap`, `cloud.ply`, `report.json` and, with an octree,
    /// `map.bt` into `dir` (created when missing); the written report carries the write time. When one fails,
    /// the outputs written by this call are removed.
    pub fn write_all(&self, dir: impl AsRef<Path>, flavor: WorldFlavor) -> Result<()> {
        let dir = dir.as_ref();
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let t = Instant::now();
        let mut written: Vec<PathBuf> = Vec::new();
        let result = (|| {
            let p = dir.join(WORLD_MCAP);
            self.write_world_mcap(&p, flavor)?;
            written.push(p);
            let p = dir.join(CLOUD_PLY);
            self.write_ply(&p)?;
            written.push(p);
            if self.octree.is_some() {
                let p = dir.join(MAP_BT);
                self.write_bt(&p)?;
                written.push(p);
            }
            let mut report = self.report.clone();
            report.timing.write_s = secs(t);
            let p = dir.join(REPORT_JSON);
            write_json(&p, &report)?;
            written.push(p);
            Ok(())
        })();
        if result.is_err() {
            for p in &written {
                let _ = std::fs::remove_file(p);
            }
        }
        result
    }
}

fn write_json(path: &Path, report: &Report) -> Result<()> {
    let text = serde_json::to_string_pretty(report)
        .map_err(|e| Error::invalid("report", e.to_string()))?;
    crate::io::atomic::write_bytes_atomic(path, text.as_bytes())
}
