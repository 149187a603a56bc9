//! `T_world_slam` with no second sensor (`convert --camera-height`,
//! `--known-distance`, `--planar-motion`): what the user knows of the
//! scene ends in the level frame of [`crate::align::priors::level_frame`]
//! (z up, the first camera over the origin, x along its heading).
//!
//! - "Up" is the normal of the ground plane of the recording's SLAM-frame
//!   cloud ([`crate::align::ground::fit_ground_plane`]), or with
//!   `planar_motion` the normal of the plane the cameras ride in
//!   ([`crate::align::priors::planar_motion`]; no cloud needed).
//! - The scale is that of a known distance between two poses
//!   ([`crate::align::priors::scale_from_distance`]; poses named by index,
//!   image name or stamp) when given, else the cameras' known height over
//!   the ground plane ([`crate::align::ground::metric_from_height`]).
//! - The first camera's height is its height over the ground plane when
//!   there is one, else the height given, else 0.
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
use crate::align::priors::{
    level_frame, planar_motion, scale_from_distance, KnownDistance, PlanarMotion,
};
use crate::cloud::{backproject_batch_counted, PointFilter};
use crate::defaults;
use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::keyframe::Keyframe;
use crate::trajectory::Trajectory;

use super::report::{DistanceReport, HeightGiven, PlanarReport, PlaneReport, PriorReport};
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

/// A pose named on the command line: its index, its image name, or its stamp.
#[derive(Clone, Debug, PartialEq)]
pub enum PoseRef {
    /// Index among the SLAM poses (keyframes, or frames), from 0.
    Index(usize),
    /// Stamp, seconds (the nearest pose within `max_diff`).
    Stamp(f64),
    /// Image name (a reconstruction's frame).
    Name(String),
}

impl std::str::FromStr for PoseRef {
    type Err = Error;

    /// `12` (an index), `1403715278.762` (a stamp: a number with a point or
    /// an exponent), else an image name.
    fn from_str(s: &str) -> Result<Self> {
        let t = s.trim();
        if let Ok(i) = t.parse::<usize>() {
            return Ok(PoseRef::Index(i));
        }
        match t.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(PoseRef::Stamp(v)),
            Ok(v) => Err(Error::invalid(
                "known_distance",
                format!("a pose's stamp must be finite, got {v}"),
            )),
            Err(_) if t.is_empty() => Err(Error::invalid(
                "known_distance",
                "a pose is an index, a stamp or an image name, got an empty string",
            )),
            Err(_) => Ok(PoseRef::Name(t.to_string())),
        }
    }
}

impl std::fmt::Display for PoseRef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PoseRef::Index(i) => write!(f, "pose {i}"),
            PoseRef::Stamp(t) => write!(f, "the pose at {t} s"),
            PoseRef::Name(n) => write!(f, "image {n:?}"),
        }
    }
}

/// Two poses a known distance apart.
#[derive(Clone, Debug, PartialEq)]
pub struct DistanceSpec {
    /// The first pose.
    pub a: PoseRef,
    /// The second pose.
    pub b: PoseRef,
    /// Their distance, metres.
    pub metres: f64,
}

/// The prior a conversion is told (`ConvertOptions::prior`): a scale
/// (`known_distance`, else `camera_height`) and an "up" (the ground plane,
/// or `planar_motion`).
#[derive(Clone, Debug, PartialEq)]
pub struct PriorOptions {
    /// The cameras' height above the ground.
    pub camera_height: Option<HeightSpec>,
    /// Two poses a known distance apart (the scale, before a height).
    pub known_distance: Option<DistanceSpec>,
    /// "Up" from the plane the cameras ride in instead of the ground plane.
    pub planar_motion: bool,
    /// How the ground plane is found.
    pub ground: GroundOptions,
}

impl PriorOptions {
    /// A height with the default ground search.
    pub fn height(camera_height: HeightSpec) -> Self {
        PriorOptions {
            camera_height: Some(camera_height),
            known_distance: None,
            planar_motion: false,
            ground: GroundOptions::default(),
        }
    }

    /// The prior of a conversion's `camera_height`, `known_distance` and
    /// `planar_motion` (the CLI's flags, Python's arguments): `None` when
    /// none is given; planar motion alone is refused (it gives no scale).
    pub fn from_parts(
        camera_height: Option<HeightSpec>,
        known_distance: Option<DistanceSpec>,
        planar_motion: bool,
    ) -> Result<Option<Self>> {
        if camera_height.is_none() && known_distance.is_none() {
            if planar_motion {
                return Err(Error::invalid(
                    "planar_motion",
                    "gives \"up\" only: give the scale too (camera_height or known_distance)",
                ));
            }
            return Ok(None);
        }
        Ok(Some(PriorOptions {
            camera_height,
            known_distance,
            planar_motion,
            ground: GroundOptions::default(),
        }))
    }

    /// Checks that a scale is given.
    pub fn check(&self) -> Result<()> {
        if self.camera_height.is_none() && self.known_distance.is_none() {
            return Err(Error::invalid(
                "prior",
                "the scale needs the cameras' height over the ground (camera_height) or a known \
                 distance between two poses (known_distance)",
            ));
        }
        if let Some(d) = &self.known_distance {
            if !(d.metres.is_finite() && d.metres > 0.0) {
                return Err(Error::invalid(
                    "known_distance",
                    format!(
                        "the distance must be a positive number of metres, got {}",
                        d.metres
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// Where the prior's "up" came from.
#[derive(Clone, Debug, PartialEq)]
pub enum Up {
    /// The ground plane's normal.
    Ground,
    /// The normal of the plane the cameras ride in.
    Planar(PlanarMotion),
}

/// The prior's fit.
#[derive(Clone, Debug, PartialEq)]
pub struct PriorFit {
    /// `T_world_slam`.
    pub transform: Sim3,
    /// The ground plane (SLAM frame), when one was fitted.
    pub plane: Option<GroundPlane>,
    /// Scale from the plane and the heights, when heights were given.
    pub height: Option<HeightScale>,
    /// The known distance, when given (it sets the scale).
    pub distance: Option<(usize, usize, KnownDistance)>,
    /// Where "up" came from.
    pub up: Up,
    /// Stamps of the SLAM poses.
    pub stamps: Vec<f64>,
}

impl PriorFit {
    /// `T_world_slam` of the prior.
    pub fn transform(&self) -> Sim3 {
        self.transform
    }

    /// The report of the fit, `opts` as given; `sensor` is `T_world_slam`
    /// of a reference sensor that set the frame instead.
    pub fn report(&self, opts: &PriorOptions, sensor: Option<&Sim3>) -> PriorReport {
        let scale = self.transform.scale;
        // "Up" in the SLAM frame: the world's z carried back.
        let up = self.transform.rotation.inverse() * Vector3::z();
        PriorReport {
            used_for_transform: sensor.is_none(),
            scale,
            scale_from: if self.distance.is_some() {
                "known_distance"
            } else {
                "camera_height"
            }
            .into(),
            up_from: match self.up {
                Up::Ground => "ground_plane",
                Up::Planar(_) => "planar_motion",
            }
            .into(),
            up: [up.x, up.y, up.z],
            camera_height: opts.camera_height.as_ref().map(|spec| match spec {
                HeightSpec::Constant(v) => HeightGiven::Constant { metres: *v },
                HeightSpec::First(v) => HeightGiven::First { metres: *v },
                HeightSpec::File(f) => HeightGiven::File { path: f.clone() },
            }),
            height_scale: self.height.as_ref().map(|m| m.scale),
            height_rms: self.height.as_ref().map(|m| m.height_rms),
            known_distance: self.distance.map(|(a, b, k)| DistanceReport {
                poses: [a, b],
                metres: k.metres,
                slam_distance: k.slam_distance,
                scale: k.scale,
            }),
            plane: self.plane.as_ref().map(|p| PlaneReport {
                normal: [p.normal.x, p.normal.y, p.normal.z],
                offset: p.offset,
                inliers: p.inliers,
                n_points: p.n_points,
                spread: p.spread,
                below: p.below,
                cameras_above: p.cameras_above,
                tilt_from_cameras_deg: p.tilt_from_cameras_deg,
                runner_up: p.runner_up,
            }),
            planar_motion: match &self.up {
                Up::Planar(m) => Some(PlanarReport {
                    normal: [m.normal.x, m.normal.y, m.normal.z],
                    rms: m.rms,
                    extent: m.extent,
                    tilt_bound_deg: m.tilt_bound_deg,
                    sigma_deg: m.sigma_deg,
                }),
                Up::Ground => None,
            },
            heights: match (&self.plane, &self.height) {
                (Some(_), Some(m)) => self
                    .stamps
                    .iter()
                    .zip(&m.heights)
                    .map(|(&t, &h)| [t, scale * h])
                    .collect(),
                _ => Vec::new(),
            },
            scale_vs_sensor: sensor.map(|s| scale / s.scale - 1.0),
            up_vs_sensor_deg: sensor
                .map(|s| (s.rotation * up).z.clamp(-1.0, 1.0).acos().to_degrees()),
        }
    }
}

/// Fits the prior to the recording's cloud and its SLAM poses `slam`
/// (`names[s]`: the image name of pose `s`, where it has one; `max_diff`:
/// how far a stamp may lie from the pose it names). Errors: no scale given,
/// no cloud where the ground plane is needed, the ground plane's and planar
/// motion's refusals, the heights' (a file that does not cover the poses,
/// a height that is not a positive number), a pose not found.
pub fn fit(
    rec: &Recording,
    slam: &Trajectory,
    names: &[Option<String>],
    opts: &PriorOptions,
    filter: &PointFilter,
    max_diff: f64,
) -> Result<PriorFit> {
    opts.check()?;
    // The ground plane: for "up", or for the heights.
    let plane = if !opts.planar_motion || opts.camera_height.is_some() {
        let points = slam_points(rec, filter)?;
        if points.is_empty() {
            return Err(Error::invalid(
                if opts.camera_height.is_some() {
                    "camera_height"
                } else {
                    "prior"
                },
                format!(
                    "{} has no points in its cloud: the ground plane needs the map (or give \
                     planar_motion for \"up\" and known_distance for the scale)",
                    rec.source.path.display()
                ),
            ));
        }
        Some(fit_ground_plane(&points, slam, &opts.ground)?)
    } else {
        None
    };
    let height = match (&plane, &opts.camera_height) {
        (Some(p), Some(spec)) => {
            let given = match spec {
                HeightSpec::Constant(v) => CameraHeight::Constant(*v),
                HeightSpec::First(v) => CameraHeight::First(*v),
                HeightSpec::File(f) => CameraHeight::PerPose(heights_at(f, &slam.timestamps)?),
            };
            Some(metric_from_height(p, slam, &given)?)
        }
        _ => None,
    };
    let distance = match &opts.known_distance {
        Some(d) => {
            let a = pose_index(&d.a, slam, names, max_diff)?;
            let b = pose_index(&d.b, slam, names, max_diff)?;
            Some((a, b, scale_from_distance(slam, a, b, d.metres)?))
        }
        None => None,
    };
    let up = if opts.planar_motion {
        Up::Planar(planar_motion(slam, defaults::PLANAR_MAX_TILT_BOUND_DEG)?)
    } else {
        Up::Ground
    };
    // The ground plane is fitted unless planar motion gives "up", and a
    // height or a distance is there (checked): both always match.
    let normal = match (&up, &plane) {
        (Up::Planar(m), _) => m.normal,
        (Up::Ground, Some(p)) => p.normal,
        (Up::Ground, None) => return Err(Error::invalid("prior", "no \"up\": no ground plane")),
    };
    let scale = match (&distance, &height) {
        (Some((_, _, k)), _) => k.scale,
        (None, Some(m)) => m.scale,
        (None, None) => {
            return Err(Error::invalid(
                "prior",
                "no scale: no height and no distance",
            ))
        }
    };
    // The first camera's height in metres: over the ground plane when there
    // is one, else as given, else 0.
    let first = match (&plane, &opts.camera_height) {
        (Some(p), _) => scale * p.height(&slam.positions[0]),
        (None, Some(HeightSpec::Constant(v) | HeightSpec::First(v))) => *v,
        (None, _) => 0.0,
    };
    Ok(PriorFit {
        transform: level_frame(&normal, slam, scale, first),
        plane,
        height,
        distance,
        up,
        stamps: slam.timestamps.clone(),
    })
}

/// The index among `slam` of the pose `r` names.
fn pose_index(
    r: &PoseRef,
    slam: &Trajectory,
    names: &[Option<String>],
    max_diff: f64,
) -> Result<usize> {
    let n = slam.len();
    let found = match r {
        PoseRef::Index(i) => (*i < n).then_some(*i),
        PoseRef::Name(name) => names.iter().position(|m| m.as_deref() == Some(name)),
        PoseRef::Stamp(t) => {
            let k = slam.timestamps.partition_point(|s| s < t);
            [k.checked_sub(1), (k < n).then_some(k)]
                .into_iter()
                .flatten()
                .min_by(|&i, &j| {
                    (slam.timestamps[i] - t)
                        .abs()
                        .total_cmp(&(slam.timestamps[j] - t).abs())
                })
                .filter(|&i| (slam.timestamps[i] - t).abs() <= max_diff)
        }
    };
    found.ok_or_else(|| {
        Error::invalid(
            "known_distance",
            format!(
                "{r} is not among the {n} SLAM poses{}",
                match r {
                    PoseRef::Index(_) => format!(" (0 .. {})", n.max(1) - 1),
                    PoseRef::Stamp(_) => format!(" (none within {max_diff} s)"),
                    PoseRef::Name(_) => String::new(),
                }
            ),
        )
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
        return Ok(c
            .points_every(c.len().div_ceil(MAX_POINTS))
            .filter(|p| p.iter().all(|v| v.is_finite()))
            .collect());
    }
    // The pixels with depth are a share of the images: the stride bounds
    // the points kept by the pixels there are.
    let pixels: usize = kfs
        .iter()
        .map(|k| k.camera.width as usize * k.camera.height as usize)
        .sum();
    let stride = pixels.div_ceil(MAX_POINTS);
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
        out.extend(c.points_every(stride));
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
