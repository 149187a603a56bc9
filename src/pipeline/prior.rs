//! `T_world_slam` with no second sensor (`convert --camera-height`): the
//! ground plane of the recording's SLAM-frame cloud
//! ([`crate::align::ground::fit_ground_plane`]) and the cameras' known
//! height above it ([`crate::align::ground::metric_from_height`]) give the
//! scale, "up" and the height; the world frame has its origin on the ground
//! under the first camera and x along its heading.
//!
//! The cloud is the keyframes' backprojections (read back a batch at a time
//! when the pixels are on disk) or the reconstruction's points, at most
//! [`MAX_POINTS`] of them (every k-th). A reference sensor, when the
//! recording has one, still sets the frame; the prior is then fitted beside
//! it and the report says how far its scale and "up" lie from the sensor's.

use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use rayon::prelude::*;

use crate::align::ground::{
    fit_ground_plane, metric_from_height, CameraHeight, GroundOptions, GroundPlane, HeightScale,
};
use crate::cloud::{backproject_batch_counted, PointFilter};
use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::keyframe::Keyframe;
use crate::trajectory::Trajectory;

use super::report::{GroundReport, HeightGiven};
use super::source::Recording;

/// Most points the plane is fitted to (every k-th of the cloud beyond it).
pub const MAX_POINTS: usize = 1_000_000;

/// The cameras' height above the ground, as the user gives it.
#[derive(Clone, Debug, PartialEq)]
pub enum HeightSpec {
    /// Metres at every pose (the median distance is scaled to it).
    Constant(f64),
    /// Metres at the first pose (a drone on the floor or a stand).
    First(f64),
    /// A file of `stamp height` lines (seconds, metres), interpolated at
    /// the poses' stamps.
    File(PathBuf),
}

impl std::str::FromStr for HeightSpec {
    type Err = Error;

    /// `1.2` (every pose), `first:0.95` (the first pose), else a file path.
    fn from_str(s: &str) -> Result<Self> {
        let metres = |v: &str| -> Result<f64> {
            match v.trim().parse::<f64>() {
                Ok(m) if m.is_finite() && m > 0.0 => Ok(m),
                _ => Err(Error::invalid(
                    "camera_height",
                    format!("must be a positive number of metres, got {v:?}"),
                )),
            }
        };
        if let Some(v) = s.strip_prefix("first:") {
            return metres(v).map(HeightSpec::First);
        }
        if s.trim().parse::<f64>().is_ok() {
            return metres(s).map(HeightSpec::Constant);
        }
        Ok(HeightSpec::File(PathBuf::from(s)))
    }
}

/// The prior a conversion is told (`ConvertOptions::prior`).
#[derive(Clone, Debug, PartialEq)]
pub struct PriorOptions {
    /// The cameras' height above the ground.
    pub camera_height: HeightSpec,
    /// How the ground plane is found.
    pub ground: GroundOptions,
}

impl PriorOptions {
    /// A height with the default ground search.
    pub fn height(camera_height: HeightSpec) -> Self {
        PriorOptions {
            camera_height,
            ground: GroundOptions::default(),
        }
    }
}

/// The prior's fit.
#[derive(Clone, Debug, PartialEq)]
pub struct PriorFit {
    /// The ground plane (SLAM frame).
    pub plane: GroundPlane,
    /// Scale and `T_world_slam` from the plane and the heights.
    pub metric: HeightScale,
    /// The heights given, as used (per pose when from a file).
    pub given: CameraHeight,
    /// Stamps of the poses the heights are of.
    pub stamps: Vec<f64>,
}

impl PriorFit {
    /// `T_world_slam` of the prior.
    pub fn transform(&self) -> Sim3 {
        self.metric.t_world_slam
    }

    /// The report of the fit, `spec` as given; `sensor` is `T_world_slam`
    /// of a reference sensor that set the frame instead.
    pub fn report(&self, spec: &HeightSpec, sensor: Option<&Sim3>) -> GroundReport {
        let p = &self.plane;
        let m = &self.metric;
        GroundReport {
            used_for_transform: sensor.is_none(),
            camera_height: match spec {
                HeightSpec::Constant(v) => HeightGiven::Constant { metres: *v },
                HeightSpec::First(v) => HeightGiven::First { metres: *v },
                HeightSpec::File(f) => HeightGiven::File { path: f.clone() },
            },
            normal: [p.normal.x, p.normal.y, p.normal.z],
            offset: p.offset,
            inliers: p.inliers,
            n_points: p.n_points,
            spread: p.spread,
            below: p.below,
            cameras_above: p.cameras_above,
            tilt_from_cameras_deg: p.tilt_from_cameras_deg,
            runner_up: p.runner_up,
            scale: m.scale,
            height_rms: m.height_rms,
            heights: self
                .stamps
                .iter()
                .zip(&m.heights)
                .map(|(&t, &h)| [t, m.scale * h])
                .collect(),
            scale_vs_sensor: sensor.map(|s| m.scale / s.scale - 1.0),
            up_vs_sensor_deg: sensor.map(|s| {
                (s.rotation * p.normal)
                    .z
                    .clamp(-1.0, 1.0)
                    .acos()
                    .to_degrees()
            }),
        }
    }
}

/// Fits the prior to the recording's cloud and its SLAM poses `slam`.
/// Errors: no cloud (a trajectory without points), the ground plane's
/// refusals, the heights' (a file that does not cover the poses, a height
/// that is not a positive number).
pub fn fit(
    rec: &Recording,
    slam: &Trajectory,
    opts: &PriorOptions,
    filter: &PointFilter,
) -> Result<PriorFit> {
    let points = slam_points(rec, filter)?;
    if points.is_empty() {
        return Err(Error::invalid(
            "camera_height",
            format!(
                "{} has no points in its cloud: the ground plane needs the map",
                rec.source.path.display()
            ),
        ));
    }
    let plane = fit_ground_plane(&points, slam, &opts.ground)?;
    let given = match &opts.camera_height {
        HeightSpec::Constant(v) => CameraHeight::Constant(*v),
        HeightSpec::First(v) => CameraHeight::First(*v),
        HeightSpec::File(f) => CameraHeight::PerPose(heights_at(f, &slam.timestamps)?),
    };
    let metric = metric_from_height(&plane, slam, &given)?;
    Ok(PriorFit {
        plane,
        metric,
        given,
        stamps: slam.timestamps.clone(),
    })
}

/// The recording's cloud in the SLAM frame, at most [`MAX_POINTS`] (every
/// k-th): its keyframes backprojected (their pixels read back a batch at a
/// time when on disk), else its own cloud.
fn slam_points(rec: &Recording, filter: &PointFilter) -> Result<Vec<Vector3<f64>>> {
    let kfs = &rec.keyframes;
    if kfs.is_empty() {
        let Some(c) = &rec.cloud else {
            return Ok(Vec::new());
        };
        let stride = (c.len().div_ceil(MAX_POINTS)).max(1);
        return Ok(c
            .points
            .chunks_exact(3)
            .step_by(stride)
            .map(|p| Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64))
            .filter(|p| p.iter().all(|v| v.is_finite()))
            .collect());
    }
    // The pixels with depth are a share of the images: the stride bounds
    // the points kept by the pixels there are.
    let pixels: usize = kfs
        .iter()
        .map(|k| k.camera.width as usize * k.camera.height as usize)
        .sum();
    let stride = (pixels.div_ceil(MAX_POINTS)).max(1);
    let mut out = Vec::new();
    let batch = super::batch_len();
    let order: Vec<usize> = (0..kfs.len()).collect();
    for (b, idx) in order.chunks(batch).enumerate() {
        crate::interrupt::check()?;
        let loaded;
        let keyframes: &[Keyframe] = match &rec.pixels {
            Some(px) => {
                loaded = idx
                    .par_iter()
                    .map(|&i| super::load_keyframe(kfs, px, i))
                    .collect::<Result<Vec<_>>>()?;
                &loaded
            }
            None => &kfs[b * batch..b * batch + idx.len()],
        };
        let (c, _) =
            backproject_batch_counted(keyframes, b * batch, filter, |_| Sim3::identity(), false)?;
        out.extend(
            c.points
                .chunks_exact(3)
                .step_by(stride)
                .map(|p| Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64)),
        );
    }
    Ok(out)
}

/// The heights of the `stamp height` file at `path` at each of `stamps`
/// (linear between its lines). Errors: a line that is not two numbers,
/// stamps not increasing, a pose outside the file's span.
fn heights_at(path: &Path, stamps: &[f64]) -> Result<Vec<f64>> {
    let mut rows: Vec<(f64, f64)> = Vec::new();
    crate::io::lines::for_each_line(path, "camera height file", |line, text| {
        let t = text.trim();
        if t.is_empty() || t.starts_with('#') || t.starts_with("//") {
            return Ok(());
        }
        let fields: Vec<&str> = t
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|f| !f.is_empty())
            .collect();
        if fields.len() != 2 {
            return Err(Error::parse(
                path,
                line,
                format!("expected `stamp height`, got {} fields", fields.len()),
            ));
        }
        let v = crate::io::lines::parse_fields(path, line, &fields)?;
        if let Some(&(prev, _)) = rows.last() {
            if v[0] <= prev {
                return Err(Error::parse(
                    path,
                    line,
                    format!("stamps must increase: {} after {prev}", v[0]),
                ));
            }
        }
        rows.push((v[0], v[1]));
        Ok(())
    })?;
    let (Some(&(t0, _)), Some(&(t1, _))) = (rows.first(), rows.last()) else {
        return Err(Error::parse(path, 1, "no `stamp height` line"));
    };
    stamps
        .iter()
        .map(|&t| {
            if t < t0 || t > t1 {
                return Err(Error::invalid(
                    "camera_height",
                    format!(
                        "{}: a pose at {t} s lies outside the heights' span {t0} .. {t1} s",
                        path.display()
                    ),
                ));
            }
            // The first line at or after t (there is one: t <= t1).
            let k = rows.partition_point(|&(s, _)| s < t);
            let (sb, hb) = rows[k];
            Ok(match k.checked_sub(1).map(|j| rows[j]) {
                Some((sa, ha)) if sb > t => ha + (hb - ha) * (t - sa) / (sb - sa),
                _ => hb,
            })
        })
        .collect()
}
