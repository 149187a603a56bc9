//! `convert`: a recording in, the metric world out.
//!
//! - [`source`]: what a conversion reads, one [`Recording`] from any input;
//! - [`reconstruction`]: the reconstruction sources (COLMAP / GLOMAP models,
//!   DROID-SLAM folders, trajectory files + PLY) and the reference files
//!   beside them (poses by time, positions by image name); [`native`]: what
//!   a reconstruction brings besides poses and points (its own model, frame
//!   names, how its stamps were read);
//! - [`options`]: everything it can be told ([`ConvertOptions`], checked once);
//! - [`poses`] / [`imu`] / [`gnss`] / [`prior`]: where `T_world_slam` comes
//!   from — a metric reference trajectory, the raw IMU when there is none,
//!   GNSS fixes (then the world frame is ENU at an origin the report
//!   carries), or with no sensor the ground plane and the cameras' known
//!   height;
//! - [`report`]: the typed model of every JSON document the commands write;
//! - [`outputs`]: `world.mcap`, `cloud.ply`, `trajectory.txt`, `map.bt`,
//!   `report.json`, `report.html` and the input's own model (`model/`),
//!   written as one set;
//! - [`figures`] / [`html`]: what the report page draws, and the page;
//! - `live_world` (feature `live`): the world of a running [`session`] as
//!   `follow` writes it and `Session.serve` sends it.
//!
//! The SLAM poses (keyframes, or frames without depth) are associated with
//! the reference by time and `T_world_slam` is fitted; the keyframes are
//! backprojected with `T_world_slam · T_slam_cam` fused per keyframe (a cloud
//! that came without keyframes is carried by `T_world_slam`). With
//! [`ConvertOptions::map`] the world cloud also becomes an occupancy octree
//! (OctoMap semantics): each keyframe's points are inserted as one scan from
//! that keyframe's camera centre in the world frame; a cloud without
//! keyframes whose points have ray origins ([`Recording::cloud_origins`], a
//! COLMAP point's nearest observing image) is inserted from those.

pub mod figures;
pub mod gnss;
pub mod html;
pub mod imu;
#[cfg(feature = "live")]
pub mod live_world;
pub mod native;
pub mod options;
pub mod outputs;
pub mod poses;
pub mod prior;
pub mod reconstruction;
pub mod report;
pub mod session;
pub mod source;
pub mod startup;

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use crate::align::trajectories::SkipInit;
use rayon::prelude::*;

use crate::cloud::{
    backproject_batch_counted, backproject_counted, backproject_per_keyframe_counted, NonFinite,
    PointCloud,
};
use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::imu::{ImuAlignment, ImuSamples};
use crate::io::spill::{CloudFile, SpilledKeyframes};
use crate::keyframe::Keyframe;
use crate::map::{Grid2d, GridParams, MapParams, OccupancyMap, VoxelState};
use crate::trajectory::Trajectory;

pub use native::NativeModel;
pub use options::ConvertOptions;
pub use outputs::{
    CLOUD_PLY, COLMAP_MODEL, MAP_BT, REPORT_HTML, REPORT_JSON, TRAJECTORY_TUM, WORLD_MCAP,
};
pub use poses::PoseFit;
pub use report::Report;
pub use source::{Recording, Source, SourceInfo};

use report::{
    ApeReport, FitReport, GridReport, OctreeReport, PairReport, ReconstructionReport,
    ReferenceReport, Timing, TransformReport,
};

/// Where `T_world_slam` came from.
#[derive(Clone, Debug)]
pub enum WorldFrame {
    /// Fitted to reference poses.
    Poses(Box<PoseFit>),
    /// The inertial initialisation from raw IMU samples (no reference poses).
    Imu(Box<ImuAlignment>),
    /// The ground plane and the cameras' known height (no sensor).
    Prior(Box<prior::PriorFit>),
}

impl WorldFrame {
    /// `T_world_slam`: maps SLAM-frame points to metres in the world frame.
    pub fn transform(&self) -> Sim3 {
        match self {
            WorldFrame::Poses(p) => p.alignment.transform(),
            WorldFrame::Imu(a) => a.transform,
            WorldFrame::Prior(p) => p.transform(),
        }
    }

    /// The pose fit, `None` on the IMU path.
    pub fn poses(&self) -> Option<&PoseFit> {
        match self {
            WorldFrame::Poses(p) => Some(p),
            WorldFrame::Imu(_) | WorldFrame::Prior(_) => None,
        }
    }
}

/// The result of [`convert`].
#[derive(Clone, Debug)]
pub struct Conversion {
    /// Where `T_world_slam` came from, with everything the fit found.
    pub world: WorldFrame,
    /// The world cloud (metres, world frame).
    pub cloud: PointCloud,
    /// The SLAM poses (`T_world_cam`) in the world frame, by time.
    pub slam_trajectory: Trajectory,
    /// The same poses in the SLAM frame (`T_slam_cam`), the rows the fit's
    /// pairs index.
    pub slam_frame: Trajectory,
    /// The reference trajectory (`T_world_body`), when there is one: the
    /// recording's own (shared), or the one made of its GNSS fixes.
    pub reference: Option<Arc<Trajectory>>,
    /// The reference on disk, when a bounded conversion left it there
    /// (`reference` is then `None`; [`Conversion::reference_ref`] gives
    /// either).
    pub reference_on_disk: Option<Arc<crate::io::spill::TrajectoryFile>>,
    /// The report.
    pub report: Report,
    /// The occupancy octree of the world cloud (world frame), when asked for.
    pub octree: Option<OccupancyMap>,
    /// The input's own model carried by `T_world_slam` (metres, world frame),
    /// for reconstructions that have one (COLMAP).
    pub native: Option<NativeModel>,
    /// The ENU frame the world is, when the reference was GNSS (its origin
    /// is in the report's `gnss`).
    pub enu: Option<crate::geo::EnuFrame>,
    /// The georeferenced clouds to write beside the others.
    pub geo_outputs: gnss::GeoOutputs,
    /// The 2-D occupancy grid projected from the octree, when asked for
    /// ([`ConvertOptions::grid`]), with its parameters.
    pub grid: Option<(Grid2d, GridParams)>,
    /// The world cloud on disk, when the conversion kept it there (a
    /// recording read with its pixels on disk, [`convert_path_bounded`]);
    /// `cloud` is then empty and the writers read this one.
    pub cloud_file: Option<std::sync::Arc<crate::io::spill::CloudFile>>,
}

impl Conversion {
    /// `T_world_slam`.
    pub fn transform(&self) -> Sim3 {
        self.world.transform()
    }

    /// The reference to read (the writers take it a piece at a time): on
    /// disk when the conversion left it there, else `reference`.
    pub fn reference_ref(&self) -> Option<crate::io::spill::TrajectoryRef<'_>> {
        match (&self.reference, &self.reference_on_disk) {
            (Some(r), _) => Some(crate::io::spill::TrajectoryRef::Memory(r)),
            (None, Some(f)) => Some(crate::io::spill::TrajectoryRef::File(f)),
            (None, None) => None,
        }
    }

    /// The world cloud to write: in memory, or on disk.
    pub fn cloud_ref(&self) -> crate::io::spill::CloudRef<'_> {
        match &self.cloud_file {
            Some(f) => crate::io::spill::CloudRef::File(f),
            None => {
                crate::io::spill::CloudRef::Memory(&self.cloud.points, self.cloud.colors.as_deref())
            }
        }
    }
}

fn secs(t: Instant) -> f64 {
    t.elapsed().as_secs_f64()
}

/// A keyframe's camera centre in the world frame (OctoMap's `f32`): the
/// translation of `T_world_slam · T_slam_cam`.
fn camera_center(kf: &Keyframe, t_world_slam: &Sim3) -> [f32; 3] {
    let c = t_world_slam.transform_point(&kf.pose.translation);
    [c.x as f32, c.y as f32, c.z as f32]
}

/// The world-frame ray origins of a cloud without keyframes (`origins` in the
/// SLAM frame, by the ids of `cloud.keyframe_ids`); an error naming the first
/// point without one.
fn cloud_ray_origins(
    origins: &BTreeMap<i32, nalgebra::Vector3<f64>>,
    cloud: &PointCloud,
    t_world_slam: &Sim3,
) -> Result<BTreeMap<i32, [f32; 3]>> {
    if let Some(i) = cloud
        .keyframe_ids
        .iter()
        .position(|id| !origins.contains_key(id))
    {
        let n = cloud
            .keyframe_ids
            .iter()
            .filter(|id| !origins.contains_key(id))
            .count();
        return Err(Error::invalid(
            "octree",
            format!(
                "point {i} (and {} more) has no ray origin (a point observed by no image): \
                 the octree cannot say what space its ray crossed",
                n - 1
            ),
        ));
    }
    Ok(origins
        .iter()
        .map(|(&id, c)| {
            let w = t_world_slam.transform_point(c);
            (id, [w.x as f32, w.y as f32, w.z as f32])
        })
        .collect())
}

/// Inserts the world cloud keyframe by keyframe, each from its camera centre
/// (`origins`, by keyframe id).
fn build_octree(
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
    let report = octree_report(&map, params, scans.len(), cloud.len(), time_s);
    Ok((map, report))
}

/// The report of an octree built from `points` points in `scans` scans.
fn octree_report(
    map: &OccupancyMap,
    params: MapParams,
    scans: usize,
    points: usize,
    time_s: f64,
) -> OctreeReport {
    OctreeReport {
        resolution: params.resolution,
        max_range: params.max_range,
        prob_hit: params.prob_hit,
        prob_miss: params.prob_miss,
        clamp_min: params.clamp_min,
        clamp_max: params.clamp_max,
        scans,
        points,
        leaves_occupied: map.leaves(VoxelState::Occupied).len(),
        leaves_free: map.leaves(VoxelState::Free).len(),
        nodes: map.num_nodes(),
        memory_bytes: map.memory_bytes(),
        time_s,
    }
}

/// Each keyframe's camera centre in the world frame, by id (`t_of(Some(i))`
/// carries keyframe `i`).
fn keyframe_origins(
    keyframes: &[Keyframe],
    t_of: &dyn Fn(Option<usize>) -> Sim3,
) -> BTreeMap<i32, [f32; 3]> {
    keyframes
        .iter()
        .enumerate()
        .map(|(i, kf)| (kf.id, camera_center(kf, &t_of(Some(i)))))
        .collect()
}

/// Keyframes per batch of a bounded conversion: a few per thread.
fn batch_len() -> usize {
    (2 * rayon::current_num_threads()).clamp(4, 32)
}

/// Keyframe `i` of `kfs` (the poses) with its pixels read back from `px`.
fn load_keyframe(kfs: &[Keyframe], px: &SpilledKeyframes, i: usize) -> Result<Keyframe> {
    let (idepth, var, color) = px.spill.get(px.at[i])?;
    let k = &kfs[i];
    Keyframe::try_new(
        k.id,
        k.timestamp,
        k.pose,
        k.camera,
        idepth,
        Some(var),
        Some(color),
    )
}

/// What [`stream_keyframes`] made.
struct Streamed {
    file: CloudFile,
    non_finite: NonFinite,
    octree: Option<(OccupancyMap, OctreeReport)>,
    report: report::StreamReport,
}

/// The world cloud (on disk) and octree of a recording whose pixels are on
/// disk: a batch of keyframes at a time read back, backprojected, inserted
/// and appended, the same points and map as [`convert`] in memory (the
/// octree inserts keyframes in id order there: here too, in a second sweep
/// when the ids did not arrive in order).
fn stream_keyframes(
    rec: &Recording,
    px: &SpilledKeyframes,
    opts: &ConvertOptions,
    t_of: &(dyn Fn(Option<usize>) -> Sim3 + Sync),
) -> Result<Streamed> {
    let kfs = &rec.keyframes;
    let n = kfs.len();
    if px.at.len() != n {
        return Err(Error::invalid(
            "keyframes",
            format!(
                "{n} keyframes and the pixels of {}: the recording is not whole",
                px.at.len()
            ),
        ));
    }
    let batch = batch_len();
    let load_all = |idx: &[usize]| -> Result<Vec<Keyframe>> {
        idx.par_iter().map(|&i| load_keyframe(kfs, px, i)).collect()
    };
    let ascending = kfs.windows(2).all(|w| w[0].id < w[1].id);
    let origins = keyframe_origins(kfs, t_of);
    let mut map = opts.map.map(OccupancyMap::try_new).transpose()?;
    let mut file = CloudFile::new(true)?;
    let mut non_finite = NonFinite::default();
    let (mut in_memory, mut insert_s) = (0usize, 0.0);
    let mut scans: std::collections::BTreeSet<i32> = std::collections::BTreeSet::new();
    let order: Vec<usize> = (0..n).collect();
    for (b, idx) in order.chunks(batch).enumerate() {
        crate::interrupt::check()?;
        let first = b * batch;
        let keyframes = load_all(idx)?;
        in_memory = in_memory.max(keyframes.len());
        let (c, nf) = backproject_batch_counted(
            &keyframes,
            first,
            &opts.filter,
            |i| t_of(Some(first + i)),
            true,
        )?;
        drop(keyframes);
        non_finite.extend(nf);
        scans.extend(c.keyframe_ids.iter().copied());
        if let (Some(m), true) = (map.as_mut(), ascending) {
            let t = Instant::now();
            m.insert_keyframes(&c.points, &c.keyframe_ids, &origins)?;
            insert_s += secs(t);
        }
        file.push(&c.points, c.colors.as_deref())?;
    }
    if let (Some(m), false) = (map.as_mut(), ascending) {
        let mut by_id = order;
        by_id.sort_by_key(|&i| kfs[i].id);
        for idx in by_id.chunks(batch) {
            crate::interrupt::check()?;
            let keyframes = load_all(idx)?;
            in_memory = in_memory.max(keyframes.len());
            for (kf, &i) in keyframes.iter().zip(idx) {
                let (c, _) = backproject_batch_counted(
                    std::slice::from_ref(kf),
                    i,
                    &opts.filter,
                    |_| t_of(Some(i)),
                    true,
                )?;
                let t = Instant::now();
                m.insert_keyframes(&c.points, &c.keyframe_ids, &origins)?;
                insert_s += secs(t);
            }
        }
    }
    let octree = match (map, opts.map) {
        (Some(m), Some(params)) => {
            let r = octree_report(&m, params, scans.len(), file.len(), insert_s);
            Some((m, r))
        }
        _ => None,
    };
    Ok(Streamed {
        report: report::StreamReport {
            batch_keyframes: batch,
            max_keyframes_in_memory: in_memory,
            pixel_bytes: px.spill.len(),
            cloud_bytes: file.bytes(),
        },
        file,
        non_finite,
        octree,
    })
}

/// The 2-D grid of `map` in `params`' band, with its report; an error when
/// the band holds no known voxel (nothing to plan on).
pub fn project_grid(map: &OccupancyMap, params: &GridParams) -> Result<(Grid2d, GridReport)> {
    let t = Instant::now();
    let grid = map.grid_of(params)?;
    if grid.is_empty() {
        return Err(Error::invalid(
            "grid",
            format!(
                "no known voxel has its centre in the band z {} .. {} m: nothing to project \
                 (the map spans the heights of its points and the rays to them)",
                params.z_min, params.z_max
            ),
        ));
    }
    let report = GridReport::of(&grid, params.occupied_threshold, secs(t));
    Ok((grid, report))
}

/// Aligns the recording's SLAM poses with its reference (or initialises from
/// its raw IMU) and builds the world cloud (and the octree, when asked for).
///
/// Errors: the options' ([`ConvertOptions::check`]); no SLAM poses, or neither
/// reference nor IMU (naming the file); no SLAM stamp within `max_diff` of a
/// reference pose (naming the file and topics); the fit's own errors (fewer
/// than 3 pairs, degenerate motion); an octree for a cloud without keyframes.
pub fn convert(rec: &Recording, opts: &ConvertOptions) -> Result<Conversion> {
    let motion = Motion {
        imu: rec.imu.as_ref().map(Cow::Borrowed),
        live: rec.live.as_ref().map(Cow::Borrowed),
    };
    convert_with(rec, motion, opts)
}

/// The recording's raw IMU and live frames, which only the fit and its
/// checks read: borrowed from the recording by [`convert`], owned in a
/// bounded conversion, which frees them before the keyframes are streamed
/// (on a long log they are most of what the conversion holds). A bounded
/// read leaves the IMU on disk ([`Recording::imu_on_disk`]): it is read
/// back where it is used, the live frames freed first.
struct Motion<'a> {
    imu: Option<Cow<'a, ImuSamples>>,
    live: Option<Cow<'a, Trajectory>>,
}

/// The recording's raw IMU: `imu`, else read back from disk; `None` when
/// the recording has none.
fn imu_of<'a>(
    imu: Option<Cow<'a, ImuSamples>>,
    rec: &Recording,
) -> Result<Option<Cow<'a, ImuSamples>>> {
    match (imu, &rec.imu_on_disk) {
        (Some(i), _) => Ok(Some(i)),
        (None, Some(d)) => d.load().map(|i| Some(Cow::Owned(i))),
        (None, None) => Ok(None),
    }
}

/// [`convert`] with the recording's IMU and live frames given apart
/// (`rec.imu` and `rec.live` are not read).
fn convert_with(rec: &Recording, motion: Motion<'_>, opts: &ConvertOptions) -> Result<Conversion> {
    opts.check()?;
    let effective = reconstruction::effective_options(rec, opts)?;
    let opts: &ConvertOptions = &effective;
    let t0 = Instant::now();
    let (slam, rows) = rec.slam_trajectory()?;
    // GNSS fixes are the reference when present: ENU at an origin, the
    // lever arm as a known extrinsic, the covariances as weights.
    let gnss_ref = match &rec.gnss {
        Some(f) => Some(gnss::reference(
            f,
            &slam,
            &opts.gnss,
            opts.align.offset,
            opts.align.estimate_offset.is_none(),
            opts.align.body_from_cam.as_ref(),
        )?),
        None => None,
    };
    opts.geo_outputs.las_for(gnss_ref.is_some())?;
    // A bounded read leaves the reference on disk: read back for the fit,
    // it goes again once the fit and the report have what they need of it.
    let on_disk = match (&rec.reference, &rec.reference_on_disk, &gnss_ref) {
        (None, Some(d), None) => Some(d),
        _ => None,
    };
    let loaded = on_disk.map(|d| d.load().map(Arc::new)).transpose()?;
    let gnss_opts;
    let (reference, weights, opts) = match &gnss_ref {
        Some(g) => {
            let (align, w) = g.fit_options(&opts.align);
            gnss_opts = ConvertOptions {
                align,
                ..opts.clone()
            };
            (Some(g.trajectory.clone()), w, &gnss_opts)
        }
        None => (rec.reference.clone().or(loaded), None, opts),
    };
    let Motion { mut imu, live } = motion;
    if reference.is_none() {
        // The IMU is the reference.
        imu = imu_of(imu, rec)?;
    }
    let live_frames = live.as_deref();
    // The prior (ground plane and camera height) when given: the frame when
    // no sensor is there, else compared with the sensor's.
    // Name of SLAM row `s` (frames of a reconstruction that names them).
    let name_of = |s: usize| match rows[s] {
        None => rec.frame_info.get(s).and_then(|f| f.name.clone()),
        Some(_) => None,
    };
    let prior_fit = match &opts.prior {
        Some(p) => {
            let names: Vec<Option<String>> = (0..slam.len()).map(name_of).collect();
            Some(prior::fit(
                rec,
                &slam,
                &rows,
                &names,
                p,
                &opts.filter,
                opts.align.max_diff,
            )?)
        }
        None => None,
    };
    let world = match (reference.as_ref(), imu.as_deref(), &prior_fit) {
        (Some(r), _, _) => {
            // Against fixes, the live frames are paired with the fixes
            // interpolated at their own stamps (the online session's rule).
            let live = match (&rec.gnss, live_frames, opts.align.skip_init) {
                (Some(f), Some(live), SkipInit::Auto) if opts.align.estimate_offset.is_none() => {
                    Some(gnss::live_cut(f, live, &opts.gnss, opts.align.offset)?)
                }
                _ => None,
            };
            let fit = poses::fit(rec, &slam, r, weights, (live_frames, live), opts)?;
            WorldFrame::Poses(Box::new(fit))
        }
        (None, Some(imu), _) => WorldFrame::Imu(Box::new(imu::fit(&slam, imu, opts)?)),
        (None, None, Some(f)) => WorldFrame::Prior(Box::new(f.clone())),
        (None, None, None) if rec.source.reconstruction.is_some() => {
            return Err(Error::invalid(
                "reference",
                format!(
                    "{} is a reconstruction without a metric reference: give a reference file \
                     (poses by time, or positions by image name) or the cameras' height over \
                     the ground (camera_height)",
                    rec.source.path.display()
                ),
            ))
        }
        (None, None, None) => {
            return Err(Error::Mcap {
                path: rec.source.path.clone(),
                reason: "no reference pose topic and no raw IMU topic in the log: give a \
                         reference file, or the cameras' height over the ground (camera_height)"
                    .into(),
            })
        }
    };
    let align_s = secs(t0);
    let t = world.transform();
    // What the report takes of the reference; then a reference read back
    // from disk goes (the writers read it there), before the IMU comes back.
    let reference_poses = reference.as_ref().map_or(0, |r| r.len());
    let pair_reference_times: Vec<f64> = match (&world, &reference) {
        (WorldFrame::Poses(p), Some(r)) => p
            .alignment
            .pairs
            .iter()
            .map(|&(_, i)| r.timestamps.get(i).copied().unwrap_or(f64::NAN))
            .collect(),
        _ => Vec::new(),
    };
    let reference = match on_disk {
        Some(_) => {
            drop(reference);
            crate::buffer::release_free_memory();
            None
        }
        None => reference,
    };
    // What reads the IMU and the live frames besides the fit, before they go:
    // the live frames first, so that an IMU read back from disk is not held
    // beside them either.
    let live_frames = live.as_deref().map_or(0, Trajectory::len);
    if matches!(live, Some(Cow::Owned(_))) {
        drop(live);
        crate::buffer::release_free_memory();
    }
    let imu_check = match &world {
        WorldFrame::Poses(_) => imu_of(imu, rec)?.map(|imu| {
            let report =
                imu::consistency_report(&slam, &imu, rec.source.imu_topic.clone(), opts, &t);
            if matches!(imu, Cow::Owned(_)) {
                drop(imu);
                crate::buffer::release_free_memory();
            }
            report
        }),
        _ => {
            if matches!(imu, Some(Cow::Owned(_))) {
                drop(imu);
                crate::buffer::release_free_memory();
            }
            None
        }
    };
    let ray_origins = rec.keyframes.is_empty() && rec.cloud_origins.is_some();
    if rec.keyframes.is_empty() && ((opts.map.is_some() && !ray_origins) || opts.windowed_cloud) {
        return Err(Error::invalid(
            if opts.map.is_some() {
                "octree"
            } else {
                "windowed_cloud"
            },
            "needs keyframes (each point with its camera); this input has poses and a cloud without rays",
        ));
    }
    // With `windowed_cloud`: T_world_slam per keyframe, in the recording's order.
    let per_keyframe: Option<Vec<Sim3>> = match (&world, opts.windowed_cloud) {
        (WorldFrame::Poses(p), true) => p.windowed.as_ref().map(|w| {
            rec.keyframes
                .iter()
                .map(|k| w.transform_at(k.timestamp))
                .collect()
        }),
        _ => None,
    };
    // T_world_slam of keyframe `i` of the recording.
    let t_of = |i: Option<usize>| match (&per_keyframe, i) {
        (Some(ts), Some(i)) => ts[i],
        _ => t,
    };

    let t1 = Instant::now();
    crate::interrupt::check()?;
    let (cloud, cloud_file, non_finite, octree, octree_report, stream_report) = match &rec.pixels {
        Some(px) if !rec.keyframes.is_empty() => {
            let s = stream_keyframes(rec, px, opts, &t_of)?;
            let (octree, octree_report) =
                s.octree.map_or((None, None), |(m, r)| (Some(m), Some(r)));
            let file = std::sync::Arc::new(s.file);
            (
                PointCloud::default(),
                Some(file),
                s.non_finite,
                octree,
                octree_report,
                Some(s.report),
            )
        }
        _ => {
            let (cloud, non_finite) = if !rec.keyframes.is_empty() {
                match &per_keyframe {
                    Some(ts) => backproject_per_keyframe_counted(&rec.keyframes, &opts.filter, ts)?,
                    None => backproject_counted(&rec.keyframes, &opts.filter, Some(&t))?,
                }
            } else {
                let mut c = match &rec.cloud {
                    Some(c) => c.transformed(&t)?,
                    None => PointCloud::default(),
                };
                let dropped = c.drop_non_finite();
                (c, dropped)
            };
            crate::interrupt::check()?;
            let (octree, octree_report) = match opts.map {
                Some(params) => {
                    let origins = match (&rec.cloud_origins, rec.keyframes.is_empty()) {
                        (Some(o), true) => cloud_ray_origins(o, &cloud, &t)?,
                        _ => keyframe_origins(&rec.keyframes, &t_of),
                    };
                    let (map, report) = build_octree(&origins, &cloud, params)?;
                    (Some(map), Some(report))
                }
                None => (None, None),
            };
            (cloud, None, non_finite, octree, octree_report, None)
        }
    };
    let backproject_s = secs(t1) - octree_report.as_ref().map_or(0.0, |o| o.time_s);
    let points = cloud_file.as_ref().map_or(cloud.len(), |f| f.len());
    let (grid, grid_report) = match (&opts.grid, &octree) {
        (Some(g), Some(map)) => {
            let (grid, report) = project_grid(map, g)?;
            (Some((grid, *g)), Some(report))
        }
        _ => (None, None),
    };

    let world_slam = Trajectory::try_new(
        slam.timestamps.clone(),
        slam.positions
            .iter()
            .zip(&rows)
            .map(|(p, &i)| t_of(i).transform_point(p))
            .collect(),
        slam.orientations.as_ref().map(|o| {
            o.iter()
                .zip(&rows)
                .map(|(q, &i)| t_of(i).rotation * q)
                .collect()
        }),
    )?;

    // Keyframe id of SLAM row `s` (the row index for frames without keyframes).
    let id_of = |s: usize| rows[s].map_or(s as i32, |i| rec.keyframes[i].id);
    let mut used = vec![false; slam.len()];
    let (pairs, fit, fit_rmse, ape, pairs_fitted, imu_report) = match &world {
        WorldFrame::Poses(p) => {
            let a = &p.alignment;
            let pairs: Vec<PairReport> = a
                .pairs
                .iter()
                .zip(&a.errors)
                .enumerate()
                .map(|(k, (&(s, _), &error))| {
                    used[s] = true;
                    PairReport {
                        keyframe_id: id_of(s),
                        name: name_of(s),
                        keyframe_time: slam.timestamps[s],
                        reference_time: pair_reference_times[k],
                        error,
                        fitted: a.fitted(k),
                    }
                })
                .collect();
            (
                pairs,
                Some(FitReport::of(a, opts.confidence)),
                Some(a.alignment.rmse),
                Some(ApeReport::from(&a.ape)),
                a.n_fit,
                imu_check,
            )
        }
        WorldFrame::Imu(a) => {
            for (s, u) in used.iter_mut().enumerate() {
                *u = a
                    .timestamps
                    .binary_search_by(|x| x.total_cmp(&slam.timestamps[s]))
                    .is_ok();
            }
            let imu = report::ImuReport::new(rec.source.imu_topic.clone(), true, a, None);
            (Vec::new(), None, None, None, 0, Some(imu))
        }
        WorldFrame::Prior(_) => {
            used.fill(true);
            (Vec::new(), None, None, None, 0, None)
        }
    };
    let prior = match (&prior_fit, &opts.prior) {
        (Some(f), Some(p)) => {
            Some(f.report(p, (!matches!(world, WorldFrame::Prior(_))).then_some(&t)))
        }
        _ => None,
    };
    let frames_dropped = (0..slam.len()).filter(|&s| !used[s]).map(id_of).collect();
    let windowed = world.poses().and_then(|p| p.windowed_report(opts));
    let report = Report {
        input: rec.source.path.clone(),
        format: rec.source.format.clone(),
        keyframe_topic: rec.source.keyframe_topic.clone(),
        graph_topic: rec.source.graph_topic.clone(),
        reference_topic: world.poses().and(rec.source.reference_topic.clone()),
        keyframes: slam.len(),
        reference_poses,
        frames_used: used.iter().filter(|u| **u).count(),
        frames_dropped,
        pairs_fitted,
        max_diff: opts.align.max_diff,
        offset: world
            .poses()
            .map_or(opts.align.offset, |p| p.alignment.offset),
        t_world_slam: TransformReport::from(&t),
        fit_rmse,
        ape,
        pairs,
        fit,
        windowed,
        points,
        points_non_finite: non_finite.points,
        non_finite_keyframes: non_finite.keyframes,
        timing: Timing {
            read_s: 0.0,
            align_s,
            backproject_s,
            write_s: 0.0,
        },
        imu: imu_report,
        prior,
        octree: octree_report,
        grid: grid_report,
        startup: world
            .poses()
            .and_then(|p| p.startup.as_ref())
            .map(|c| report::StartupReport {
                topic: rec.source.live_topic.clone(),
                live_frames,
                pairs: c.pairs,
                converging_time: c.converging_time,
                stable_time: c.stable_time,
                stages: report::StagesReport::from(&c.stages),
            }),
        reconstruction: rec
            .source
            .reconstruction
            .as_ref()
            .map(|r| ReconstructionReport::of(r, slam.len(), rec.source.cloud_path.clone())),
        reference_file: rec
            .source
            .reference_file
            .as_ref()
            .map(ReferenceReport::from),
        gnss: gnss_ref.as_ref().map(|g| report::GnssReport {
            topic: rec.source.gnss_topic.clone(),
            file: rec.source.gnss_path.clone(),
            weighted: weights.is_some(),
            weight_range: weights.and(g.report.weight_range),
            ..g.report.clone()
        }),
        stream: stream_report,
    };
    Ok(Conversion {
        world,
        cloud,
        slam_trajectory: world_slam,
        slam_frame: slam,
        reference,
        reference_on_disk: on_disk.cloned(),
        report,
        octree,
        native: rec.native.as_ref().map(|m| m.transformed(&t)),
        enu: gnss_ref.map(|g| g.frame),
        geo_outputs: opts.geo_outputs,
        grid,
        cloud_file,
    })
}

/// Reads the log at `path` (its container found from its bytes) and converts
/// it; the report's `read_s` is filled in.
pub fn convert_path(path: impl AsRef<Path>, opts: &ConvertOptions) -> Result<Conversion> {
    opts.check()?;
    convert_source(&*source::open_log(path.as_ref(), &opts.read)?, opts)
}

/// [`convert_path`] in bounded memory: the keyframes' pixels, the raw IMU,
/// the reference poses and the world cloud stay on disk (temporary files,
/// [`crate::io::spill`]), each read back for the step that uses it, so that
/// the memory is the SLAM poses, the octree and a batch of keyframes
/// whatever the log's length (the reference whole only while it is fitted,
/// the IMU while it is checked); the conversion's `cloud` is then empty and
/// its writers read [`Conversion::cloud_file`] and
/// [`Conversion::reference_on_disk`]. The outputs are those of the
/// in-memory conversion, byte for byte.
pub fn convert_path_bounded(path: impl AsRef<Path>, opts: &ConvertOptions) -> Result<Conversion> {
    opts.check()?;
    convert_source_bounded(&*source::open_log(path.as_ref(), &opts.read)?, opts)
}

/// [`convert_source`] in bounded memory where the source can read so
/// ([`Source::read_bounded`]).
pub fn convert_source_bounded(source: &dyn Source, opts: &ConvertOptions) -> Result<Conversion> {
    let t = Instant::now();
    let mut rec = source.read_bounded()?;
    // The scan's message vectors are freed: give that memory back, so that
    // what follows does not add to it.
    crate::buffer::release_free_memory();
    let read_s = secs(t);
    let motion = Motion {
        imu: rec.imu.take().map(Cow::Owned),
        live: rec.live.take().map(Cow::Owned),
    };
    let mut c = convert_with(&rec, motion, opts)?;
    c.report.timing.read_s = read_s;
    // The recording (its trajectories and IMU) and the keyframe batches are
    // freed: the writers start from the conversion alone.
    drop(rec);
    crate::buffer::release_free_memory();
    Ok(c)
}

/// Reads `source` and converts it; the report's `read_s` is filled in.
pub fn convert_source(source: &dyn Source, opts: &ConvertOptions) -> Result<Conversion> {
    let t = Instant::now();
    let rec = source.read()?;
    let read_s = secs(t);
    let mut c = convert(&rec, opts)?;
    c.report.timing.read_s = read_s;
    Ok(c)
}
