//! What the report page draws beyond the report: the paths, the per-pair
//! errors over time, the scale factors `p_k`, a decimated cloud and the
//! occupied voxels — one typed [`FigureData`], made from a [`Conversion`] (or
//! from a trajectory fit for `align --html`) and embedded in `report.html`.
//!
//! Frames and units: every position is metres in the world frame (the
//! reference's, z up); the cloud and the voxels are stored as `f32` offsets
//! from [`FigureData::origin`] (so that coordinates of a georeferenced map keep
//! their millimetres in `f32`), the paths as `f64` world coordinates.
//! Times are seconds on the SLAM clock (the offset of the fit applied).

use serde::{Serialize, Serializer};

use crate::align::stages::detect_stages;
use crate::align::trajectories::{fit_scale_factors, TrajectoryAlignment};
use crate::defaults;
use crate::error::{Error, Result};
use crate::io::spill::{CloudRef, TrajectoryRef};
use crate::map::{OccupancyMap, VoxelState};
use crate::trajectory::Trajectory;

use super::report::StagesReport;
use super::Conversion;

/// A little-endian `f32` array, serialised as base64 text (a tenth of the
/// size of JSON numbers, and decoded in the page without parsing).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct F32Array(pub Vec<f32>);

/// A byte array, serialised as base64 text.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct U8Array(pub Vec<u8>);

fn base64_of(bytes: &[u8]) -> String {
    use base64::Engine;
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

impl Serialize for F32Array {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        let bytes: Vec<u8> = self.0.iter().flat_map(|v| v.to_le_bytes()).collect();
        s.serialize_str(&base64_of(&bytes))
    }
}

impl Serialize for U8Array {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(&base64_of(&self.0))
    }
}

/// A path: times and world positions.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct PathData {
    /// Times, seconds.
    pub t: Vec<f64>,
    /// Positions, metres, world frame.
    pub xyz: Vec<[f64; 3]>,
    /// Poses in the trajectory.
    pub n_total: usize,
    /// Every `stride`-th pose is kept (and the last one).
    pub stride: usize,
}

impl From<&Trajectory> for PathData {
    fn from(t: &Trajectory) -> Self {
        PathData::decimated(t, usize::MAX)
    }
}

impl PathData {
    /// Poses `0, stride, 2·stride, …` and the last of `t`, at most `max + 1`
    /// (the smallest stride that keeps `max` or fewer before the last).
    pub fn decimated(t: &Trajectory, max: usize) -> Self {
        let n = t.len();
        let stride = stride_for(n, max);
        let mut keep: Vec<usize> = (0..n).step_by(stride).collect();
        if n > 0 && keep.last() != Some(&(n - 1)) {
            keep.push(n - 1);
        }
        PathData {
            t: keep.iter().map(|&i| t.timestamps[i]).collect(),
            xyz: keep
                .iter()
                .map(|&i| {
                    let p = t.positions[i];
                    [p.x, p.y, p.z]
                })
                .collect(),
            n_total: n,
            stride,
        }
    }

    /// [`PathData::decimated`] of a trajectory in memory or on disk, read a
    /// piece at a time.
    pub fn decimated_ref(t: TrajectoryRef<'_>, max: usize) -> Result<Self> {
        if let TrajectoryRef::Memory(t) = t {
            return Ok(PathData::decimated(t, max));
        }
        let n = t.len();
        let stride = stride_for(n, max);
        let mut path = PathData {
            n_total: n,
            stride,
            ..PathData::default()
        };
        t.for_each_piece(PIECE, |first, times, positions, _| {
            for (j, (time, p)) in times.iter().zip(positions).enumerate() {
                let i = first + j;
                if i % stride == 0 || i + 1 == n {
                    path.t.push(*time);
                    path.xyz.push([p.x, p.y, p.z]);
                }
            }
            Ok(())
        })?;
        Ok(path)
    }
}

/// The matched pairs as columns, in SLAM time order.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct PairSeries {
    /// Row of the pair's SLAM pose in [`FigureData::estimate`].
    pub slam_index: Vec<usize>,
    /// Time of the SLAM pose, seconds.
    pub t: Vec<f64>,
    /// `‖p_ref − T(p_slam)‖`, metres.
    pub error: Vec<f64>,
    /// True when the pair was used in the fit.
    pub fitted: Vec<bool>,
}

/// The start-up stages drawn on the `p_k` plot.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StagesFigure {
    /// The stages (indices into [`FigureData::scale_factors`]).
    #[serde(flatten)]
    pub stages: StagesReport,
    /// True when the fit cut them (`skip_init = auto`); false when they were
    /// detected for the figure only.
    pub used_by_fit: bool,
}

/// The decimated world cloud.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct CloudData {
    /// Points in the full cloud.
    pub n_total: usize,
    /// Every `stride`-th point is kept (points `0, stride, 2·stride, …`).
    pub stride: usize,
    /// Points kept.
    pub n: usize,
    /// Offsets from [`FigureData::origin`], metres, `n × 3`.
    pub xyz: F32Array,
    /// Image colours of the kept points, `n × 3` bytes (RGB), when the cloud has them.
    pub rgb: Option<U8Array>,
}

/// The occupied leaves of the octree, as cubes.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct VoxelData {
    /// The octree's resolution, metres.
    pub resolution: f64,
    /// Edge of the smallest cube shown, metres: the resolution, or a coarser
    /// level when there were more leaves than the page shows.
    pub shown_resolution: f64,
    /// Occupied leaves in the octree (pruned leaves count once).
    pub n_total: usize,
    /// Cubes kept.
    pub n: usize,
    /// Cube centres as offsets from [`FigureData::origin`], metres, `n × 3`.
    pub center: F32Array,
    /// Cube edges, metres, `n`.
    pub size: F32Array,
}

/// Limits of what the page embeds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FigureOptions {
    /// Most cloud points kept ([`defaults::HTML_MAX_POINTS`]).
    pub max_points: usize,
    /// Most voxels kept ([`defaults::HTML_MAX_VOXELS`]).
    pub max_voxels: usize,
}

impl Default for FigureOptions {
    fn default() -> Self {
        FigureOptions {
            max_points: defaults::HTML_MAX_POINTS,
            max_voxels: defaults::HTML_MAX_VOXELS,
        }
    }
}

impl FigureOptions {
    /// Both limits at least 1.
    pub fn check(&self) -> Result<()> {
        for (what, v) in [
            ("max_points", self.max_points),
            ("max_voxels", self.max_voxels),
        ] {
            if v == 0 {
                return Err(Error::invalid(what, "must be at least 1"));
            }
        }
        Ok(())
    }
}

/// Everything the page draws that the report does not hold.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FigureData {
    /// World point the cloud and voxel offsets are taken from, metres.
    pub origin: [f64; 3],
    /// The SLAM poses carried into the world frame.
    pub estimate: PathData,
    /// The reference `T_world_body`, when there is one.
    pub reference: Option<PathData>,
    /// The matched pairs.
    pub pairs: PairSeries,
    /// The paper's `p_k` of consecutive matched pairs (reference step² over
    /// SLAM-frame step²; about `s²` once SLAM has settled), the factors the
    /// start-up detection sees.
    pub scale_factors: Vec<f64>,
    /// The start-up stages in `scale_factors`, when found.
    pub stages: Option<StagesFigure>,
    /// The decimated world cloud.
    pub cloud: Option<CloudData>,
    /// The occupied voxels.
    pub voxels: Option<VoxelData>,
    /// The ground plane of a prior, when one was fitted.
    pub ground: Option<GroundFigure>,
}

/// The ground plane in the world frame.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GroundFigure {
    /// Unit normal ("up" of the plane), world frame.
    pub normal: [f64; 3],
    /// A point of the plane, metres, offset from [`FigureData::origin`].
    pub point: [f64; 3],
}

impl FigureData {
    /// The figures of a conversion; `octree` is the map to draw (the
    /// conversion's own, or the Python side's). Errors: the options'.
    pub fn of_conversion(
        c: &Conversion,
        octree: Option<&OccupancyMap>,
        opts: &FigureOptions,
    ) -> Result<Self> {
        opts.check()?;
        let mut f = FigureData {
            estimate: PathData::from(&c.slam_trajectory),
            reference: c
                .reference_ref()
                .map(|r| PathData::decimated_ref(r, defaults::HTML_MAX_PATH_POINTS))
                .transpose()?,
            ..FigureData::default()
        };
        if let Some(p) = c.world.poses() {
            let offset = p.alignment.offset;
            f.estimate.t.iter_mut().for_each(|t| *t += offset);
            f.add_pairs(&c.slam_frame, c.reference_ref(), &p.alignment)?;
        }
        let cloud = c.cloud_ref();
        f.origin = center_of(cloud, &f.estimate)?;
        if !cloud.is_empty() {
            f.cloud = Some(decimate(cloud, f.origin, opts.max_points)?);
        }
        f.voxels = octree.map(|m| voxels(m, f.origin, opts.max_voxels));
        f.ground = c
            .report
            .prior
            .as_ref()
            .and_then(|p| p.plane.as_ref())
            .map(|p| {
                let t = c.transform();
                let n = nalgebra::Vector3::from(p.normal);
                let w = t.transform_point(&(-p.offset * n));
                let nw = t.rotation * n;
                GroundFigure {
                    normal: [nw.x, nw.y, nw.z],
                    point: [w.x - f.origin[0], w.y - f.origin[1], w.z - f.origin[2]],
                }
            });
        Ok(f)
    }

    /// The figures of a trajectory fit (`align --html`): `slam` in the SLAM
    /// frame, `reference` in the world frame, `fit` the result of
    /// [`crate::align::trajectories::align_trajectories`] on them.
    pub fn of_alignment(
        slam: &Trajectory,
        reference: &Trajectory,
        fit: &TrajectoryAlignment,
    ) -> Result<Self> {
        let t = fit.transform();
        let world = Trajectory {
            timestamps: slam.timestamps.iter().map(|x| x + fit.offset).collect(),
            positions: slam
                .positions
                .iter()
                .map(|p| t.transform_point(p))
                .collect(),
            orientations: None,
        };
        let mut f = FigureData {
            estimate: PathData::from(&world),
            reference: Some(PathData::decimated(
                reference,
                defaults::HTML_MAX_PATH_POINTS,
            )),
            ..FigureData::default()
        };
        f.add_pairs(slam, Some(TrajectoryRef::Memory(reference)), fit)?;
        f.origin = center_of(CloudRef::Memory(&[], None), &f.estimate)?;
        Ok(f)
    }

    /// The pairs, `p_k` and the stages of `fit` (`slam` in the SLAM frame,
    /// the rows the pairs index).
    fn add_pairs(
        &mut self,
        slam: &Trajectory,
        reference: Option<TrajectoryRef<'_>>,
        fit: &TrajectoryAlignment,
    ) -> Result<()> {
        let n = fit.pairs.len().min(fit.errors.len());
        for (k, &(s, _)) in fit.pairs.iter().take(n).enumerate() {
            self.pairs.slam_index.push(s);
            self.pairs
                .t
                .push(slam.timestamps.get(s).copied().unwrap_or(f64::NAN) + fit.offset);
            self.pairs.error.push(fit.errors[k]);
            self.pairs.fitted.push(fit.fitted(k));
        }
        let Some(reference) = reference else {
            return Ok(());
        };
        let rows: Vec<usize> = fit.pairs.iter().map(|&(_, r)| r).collect();
        let ref_at = reference.positions_at(&rows)?;
        type Points = Vec<nalgebra::Vector3<f64>>;
        let pos: Option<(Points, Points)> = fit
            .pairs
            .iter()
            .zip(ref_at)
            .map(|(&(s, _), r)| Some((slam.positions.get(s).copied()?, r?)))
            .collect::<Option<Vec<_>>>()
            .map(|v| v.into_iter().unzip());
        let Some((src, dst)) = pos else {
            return Ok(());
        };
        self.scale_factors = fit_scale_factors(&src, &dst);
        self.stages = match &fit.stages {
            Some(s) => Some(StagesFigure {
                stages: StagesReport::from(s),
                used_by_fit: true,
            }),
            // Found for the figure only; too few or bad factors leave it out.
            None => detect_stages(&self.scale_factors)
                .ok()
                .map(|s| StagesFigure {
                    stages: StagesReport::from(&s),
                    used_by_fit: false,
                }),
        };
        Ok(())
    }
}

/// Points (or poses) per piece when the figures read a cloud (or a path).
const PIECE: usize = 1 << 16;

/// The middle of the bounding box of the cloud and the path (the origin of
/// the page's `f32` offsets).
fn center_of(cloud: CloudRef<'_>, path: &PathData) -> Result<[f64; 3]> {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    let mut add = |p: [f64; 3]| {
        for k in 0..3 {
            if p[k].is_finite() {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
    };
    cloud.for_each_piece(PIECE, |points, _| {
        for p in points.chunks_exact(3) {
            add([f64::from(p[0]), f64::from(p[1]), f64::from(p[2])]);
        }
        Ok(())
    })?;
    for p in &path.xyz {
        add(*p);
    }
    Ok(std::array::from_fn(|k| {
        if lo[k] <= hi[k] {
            0.5 * (lo[k] + hi[k])
        } else {
            0.0
        }
    }))
}

/// The stride that keeps at most `max` of `n` items: `⌈n / max⌉`, at least 1.
fn stride_for(n: usize, max: usize) -> usize {
    n.div_ceil(max.max(1)).max(1)
}

/// Every `stride`-th point (`stride = ⌈n / max⌉`), as offsets from `origin`.
fn decimate(cloud: CloudRef<'_>, origin: [f64; 3], max: usize) -> Result<CloudData> {
    let n_total = cloud.len();
    let stride = stride_for(n_total, max);
    let mut xyz = Vec::new();
    let mut rgb = cloud.has_colors().then(Vec::new);
    let mut first = 0usize;
    cloud.for_each_piece(PIECE, |points, colors| {
        let n = points.len() / 3;
        // The first index of this piece that is a multiple of the stride.
        let mut i = (first.div_ceil(stride) * stride) - first;
        while i < n {
            for (p, o) in points[3 * i..3 * i + 3].iter().zip(origin) {
                xyz.push((f64::from(*p) - o) as f32);
            }
            if let (Some(rgb), Some(c)) = (rgb.as_mut(), colors) {
                rgb.extend_from_slice(&c[3 * i..3 * i + 3]);
            }
            i += stride;
        }
        first += n;
        Ok(())
    })?;
    Ok(CloudData {
        n_total,
        stride,
        n: xyz.len() / 3,
        xyz: F32Array(xyz),
        rgb: rgb.map(U8Array),
    })
}

/// The occupied leaves as cubes; with more than `max`, leaves smaller than a
/// coarser level are merged into the cells of that level (a cell is shown
/// when any leaf in it is occupied), one level up at a time.
fn voxels(map: &OccupancyMap, origin: [f64; 3], max: usize) -> VoxelData {
    let leaves = map.leaves(VoxelState::Occupied);
    let r = map.resolution();
    let n_total = leaves.len();
    let mut cubes = leaves;
    let mut level = r;
    while cubes.len() > max && level < r * 65536.0 {
        level *= 2.0;
        let mut cells: Vec<([i64; 3], f64)> = cubes
            .iter()
            .map(|&(c, size)| {
                if size >= level {
                    // Already as large: kept as it is (its own cell key, tagged by size).
                    (c.map(|v| (v / size).floor() as i64), size)
                } else {
                    (c.map(|v| (v / level).floor() as i64), level)
                }
            })
            .collect();
        cells.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
        cells.dedup();
        cubes = cells
            .into_iter()
            .map(|(k, size)| (k.map(|i| (i as f64 + 0.5) * size), size))
            .collect();
    }
    let mut center = Vec::with_capacity(cubes.len() * 3);
    let mut size = Vec::with_capacity(cubes.len());
    for (c, s) in &cubes {
        for (v, o) in c.iter().zip(origin) {
            center.push((v - o) as f32);
        }
        size.push(*s as f32);
    }
    VoxelData {
        resolution: r,
        shown_resolution: level,
        n_total,
        n: cubes.len(),
        center: F32Array(center),
        size: F32Array(size),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloud::PointCloud;
    use crate::map::MapParams;

    #[test]
    fn a_path_on_disk_decimates_as_in_memory() {
        use crate::io::spill::TrajectoryFile;
        for n in [0usize, 1, 5, 9_999, 10_000, 70_001] {
            let t = Trajectory::try_new(
                (0..n).map(|i| i as f64 * 0.01).collect(),
                (0..n)
                    .map(|i| nalgebra::Vector3::new(i as f64, (i % 7) as f64, -1.0))
                    .collect(),
                None,
            )
            .unwrap();
            let file = TrajectoryFile::write(&t, std::path::Path::new("log"), "/gt").unwrap();
            for max in [1, 10, 777, 5_000, usize::MAX] {
                let disk = PathData::decimated_ref(TrajectoryRef::File(&file), max).unwrap();
                assert_eq!(
                    disk,
                    PathData::decimated(&t, max),
                    "{n} poses, at most {max}"
                );
            }
        }
    }

    #[test]
    fn a_path_keeps_every_stride_th_pose_and_the_last() {
        let t = Trajectory::try_new(
            (0..10).map(f64::from).collect(),
            (0..10)
                .map(|i| nalgebra::Vector3::new(f64::from(i), 0.0, 0.0))
                .collect(),
            None,
        )
        .unwrap();
        let d = PathData::decimated(&t, 4);
        assert_eq!((d.n_total, d.stride), (10, 3));
        assert_eq!(d.t, [0.0, 3.0, 6.0, 9.0]);
        let d = PathData::decimated(&t, 3);
        assert_eq!((d.stride, d.t.clone()), (4, vec![0.0, 4.0, 8.0, 9.0]));
        assert_eq!(d.xyz[3], [9.0, 0.0, 0.0]);
        let all = PathData::from(&t);
        assert_eq!((all.stride, all.t.len()), (1, 10));
    }

    #[test]
    fn decimation_keeps_every_stride_th_point_and_its_colour() {
        let n = 10;
        let pts: Vec<f32> = (0..3 * n).map(|v| v as f32).collect();
        let rgb: Vec<u8> = (0..3 * n).map(|v| v as u8).collect();
        let c = PointCloud::try_new(pts, Some(rgb), None).unwrap();
        let c = CloudRef::Memory(&c.points, c.colors.as_deref());
        let d = decimate(c, [1.0, 0.0, 0.0], 4).unwrap();
        assert_eq!((d.n_total, d.stride, d.n), (10, 3, 4));
        // Points 0, 3, 6, 9, x offset by the origin.
        assert_eq!(&d.xyz.0[..6], &[-1.0, 1.0, 2.0, 8.0, 10.0, 11.0]);
        assert_eq!(d.rgb.unwrap().0[3..6], [9, 10, 11]);
        let all = decimate(c, [0.0; 3], 300).unwrap();
        assert_eq!((all.stride, all.n), (1, 10));
    }

    #[test]
    fn a_cloud_on_disk_decimates_as_in_memory_across_pieces() {
        // More points than one piece, a stride that does not divide it.
        let n = PIECE + PIECE / 2 + 7;
        let pts: Vec<f32> = (0..3 * n).map(|v| (v % 1000) as f32).collect();
        let rgb: Vec<u8> = (0..3 * n).map(|v| (v % 251) as u8).collect();
        let mut file = crate::io::spill::CloudFile::new(true).unwrap();
        file.push(&pts[..3 * 1000], Some(&rgb[..3 * 1000])).unwrap();
        file.push(&pts[3 * 1000..], Some(&rgb[3 * 1000..])).unwrap();
        let path = PathData::default();
        let mem = CloudRef::Memory(&pts, Some(&rgb));
        let disk = CloudRef::File(&file);
        assert_eq!(
            center_of(mem, &path).unwrap(),
            center_of(disk, &path).unwrap()
        );
        for max in [1000, 300_000, 10 * n] {
            let (a, b) = (
                decimate(mem, [1.0, 2.0, 3.0], max).unwrap(),
                decimate(disk, [1.0, 2.0, 3.0], max).unwrap(),
            );
            assert_eq!((a.n, a.stride), (b.n, b.stride));
            assert_eq!(a.n, n.div_ceil(a.stride));
            assert_eq!((a.xyz.0, a.rgb.unwrap().0), (b.xyz.0, b.rgb.unwrap().0));
        }
    }

    #[test]
    fn voxels_are_coarsened_to_the_limit_and_keep_their_extent() {
        let mut map = OccupancyMap::try_new(MapParams::new(0.1)).unwrap();
        // A 2 m line of endpoints along x, seen from above.
        let pts: Vec<f32> = (0..200)
            .flat_map(|i| [i as f32 * 0.01 + 0.005, 0.05, 0.05])
            .collect();
        map.insert_scan(&pts, [1.0, 0.05, 3.0]).unwrap();
        let all = voxels(&map, [0.0; 3], 1000);
        assert_eq!(all.n, all.n_total);
        assert_eq!(all.n, 20);
        assert_eq!(all.shown_resolution, 0.1);
        let few = voxels(&map, [0.0; 3], 6);
        assert!(few.n <= 6, "{}", few.n);
        assert!(few.shown_resolution >= 0.4);
        // The coarse cubes still cover the line from x = 0 to 2 m.
        let xs: Vec<f32> = few.center.0.chunks(3).map(|c| c[0]).collect();
        let half = few.size.0[0] / 2.0;
        let lo = xs.iter().fold(f32::INFINITY, |a, &b| a.min(b)) - half;
        let hi = xs.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b)) + half;
        assert!(lo <= 0.0 && hi >= 2.0, "{lo} {hi}");
    }

    #[test]
    fn arrays_serialise_as_little_endian_base64() {
        let j = serde_json::to_string(&F32Array(vec![1.0])).unwrap();
        assert_eq!(j, "\"AACAPw==\"");
        let j = serde_json::to_string(&U8Array(vec![0, 255])).unwrap();
        assert_eq!(j, "\"AP8=\"");
        assert!(FigureOptions {
            max_points: 0,
            ..Default::default()
        }
        .check()
        .is_err());
    }
}
