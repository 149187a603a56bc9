//! The online conversion: a [`Session`] fed what a SLAM log holds, message by
//! message, in the order it arrives (tracked frames, keyframes, graph
//! updates, reference poses, IMU samples), keeping `T_world_slam` and the
//! occupancy map up to date while the SLAM runs.
//!
//! - Pairing: each tracked frame and keyframe is paired with the nearest
//!   reference pose within `max_diff` (after `offset`), the rule of the
//!   batch fit's `evo` association, decided as soon as a reference pose later
//!   than `t + max_diff` has arrived (no later pose can be nearer).
//! - Stages ([`Session::state`]), decided on the matched tracked frames seen
//!   so far only: the stable stage is reported once the medians of `ln p_k`
//!   over the last three spans of [`SessionOptions::stable_hold`] seconds
//!   agree within [`SETTLED_Z`] standard errors (a level that no longer
//!   wanders, jumps or ramps) after at least [`MIN_CONVERGING_HOLDS`] spans
//!   of converging were seen (or, without a convergence, after
//!   [`LONG_SETTLED_HOLDS`] spans of steadiness); before, a steady move over
//!   the spans is the converging stretch, anything else the start. Where the stable stage
//!   starts (the fit's cut) is then found by the batch rule on the data so
//!   far ([`super::startup`]). Before that, [`Session::transform`] says why
//!   there is none.
//! - Fit: once stable, the keyframe pairs stamped from the stable start on are
//!   fitted from running moments (one O(1) update per pair, a pair moved by a
//!   graph update taken out and put back); the closed form is that of the
//!   batch fit ([`crate::align`]), so a session fed a whole log ends on the
//!   transform of `convert --skip-init auto` of the same log (up to the
//!   rounding of the sums). When the cut moves (more data), the moments are
//!   summed again over the new range.
//! - Map: once the transform is known every keyframe is backprojected with the
//!   viewer's filter and inserted as one scan from its camera centre, in
//!   ascending id order (the batch order); keyframes from before that moment
//!   are inserted then. OctoMap cannot take a scan out again, so when the
//!   transform or a keyframe pose has moved an inserted keyframe by more than
//!   [`SessionOptions::rebuild_tolerance`] the map is rebuilt from the
//!   keyframes in order — in steps, so that no push waits for a whole map:
//!   [`BUILD_STEP`] keyframes per keyframe push and one per tracked frame,
//!   the last complete map served meanwhile (the first map is served as far
//!   as it is built). [`Session::finish`] completes the build and rebuilds
//!   when anything moved at all, so that the final map equals the batch
//!   octree node for node.
//! - GNSS: fixes ([`Session::push_fix`]) instead of reference poses put the
//!   world frame in ENU at the first fix (or a given origin), and the pairing
//!   is the batch GNSS path's: the fixes interpolated linearly at each SLAM
//!   stamp (plus the offset) between two fixes at most `max_gap` apart,
//!   decided once a fix at or after that time has arrived, each pair weighing
//!   `1 / σ̄²` while every fix has a covariance. A session takes poses or
//!   fixes, not both.
//! - No second sensor: with [`SessionOptions::camera_height`] and no
//!   reference, `T_world_slam` comes from the ground plane of the keyframes
//!   so far and the height as soon as a plane is supported (the stage is
//!   then stable), fitted again as the keyframes grow by a quarter and at
//!   the end, where it equals `convert --camera-height` of the same log.
//! - Not yet online: the IMU-only path (IMU samples are kept, not used) and
//!   a lever arm (it needs the orientations the session does not fit with).

use std::collections::BTreeMap;
use std::time::Instant;

use nalgebra::{UnitQuaternion, Vector3};

use crate::align::covariance::{covariance, Covariance};
use crate::align::trajectories::TrajectoryAlignOptions;
use crate::align::{solve_running, AlignOptions, Moments};
use crate::cloud::{backproject_counted, PointFilter};
use crate::error::{Error, Result};
use crate::geo::{EnuFrame, Geodetic, GnssFix, Origin};
use crate::geometry::Sim3;
use crate::keyframe::Keyframe;
use crate::map::{Grid2d, MapParams, OccupancyMap};
use crate::trajectory::{Association, GapOfStream};

use super::gnss::GnssOptions;
use super::prior::HeightSpec;
use super::startup::{cut_of_pairs, LiveCut};

/// Seconds of stable stage the detection must see before it is reported.
pub const STABLE_HOLD_S: f64 = 5.0;

/// Standard errors within which the medians of `ln p_k` over the last three
/// spans must agree for the level to count as settled.
pub const SETTLED_Z: f64 = 2.0;

/// [`SessionOptions::stable_hold`] spans of converging (a steady move of the
/// level) that must have been seen before a steady level counts as the
/// stable stage (20 s with the default hold).
pub const MIN_CONVERGING_HOLDS: f64 = 4.0;

/// Without a convergence seen, a steady level counts as stable after this
/// many [`SessionOptions::stable_hold`] spans of steadiness (a run without a
/// start-up).
pub const LONG_SETTLED_HOLDS: f64 = 6.0;

/// Fewest factors in each span of the settling test.
pub const SETTLED_MIN_FACTORS: usize = 30;

/// Seconds of tracked frames between two stage detections (each one runs
/// over every matched frame so far).
pub const DETECT_EVERY_S: f64 = 1.0;

/// What a session is told.
#[derive(Clone, Debug, PartialEq)]
pub struct SessionOptions {
    /// Association (`max_diff`, `offset`, `association`) and fit (`scale`,
    /// `method`) options; the start-up cut is always the live one
    /// ([`super::startup`]); robust fits, a time-offset search, orientations,
    /// a pair budget and fits other than Sim(3) / SE(3) are refused.
    pub align: TrajectoryAlignOptions,
    /// Which pixels become points.
    pub filter: PointFilter,
    /// The occupancy octree.
    pub map: MapParams,
    /// Seconds of stable stage seen before the stable stage is reported.
    pub stable_hold: f64,
    /// Metres an inserted keyframe's camera (or a point at the map's max range,
    /// 10 m without one) may move before the map is rebuilt.
    pub rebuild_tolerance: f64,
    /// How GNSS fixes become the reference (origin first or given, weights,
    /// `max_gap`); the mean origin and a lever arm are refused online.
    pub gnss: GnssOptions,
    /// The cameras' height over the ground (metres at every pose, or at the
    /// first), for a session with no reference: `T_world_slam` from the
    /// ground plane of the keyframes so far as soon as one is supported
    /// (a heights file is the batch convert's).
    pub camera_height: Option<HeightSpec>,
}

impl Default for SessionOptions {
    fn default() -> Self {
        let map = MapParams {
            max_range: Some(10.0),
            ..MapParams::new(crate::defaults::DEMO_OCTREE_RESOLUTION)
        };
        SessionOptions {
            align: TrajectoryAlignOptions::default(),
            filter: PointFilter::default(),
            rebuild_tolerance: 0.5 * map.resolution,
            map,
            stable_hold: STABLE_HOLD_S,
            gnss: GnssOptions::default(),
            camera_height: None,
        }
    }
}

impl SessionOptions {
    /// Checks the options (see the field docs for what is refused online).
    pub fn check(&self) -> Result<()> {
        self.align.check()?;
        self.filter.validate()?;
        self.map.check()?;
        let a = &self.align;
        let refuse = |what: &str| {
            Err(Error::invalid(
                what,
                "not supported by the online session (it fits a plain Sim(3) / SE(3) by Horn \
                 from running moments); use the batch convert",
            ))
        };
        if a.robust.is_some() {
            return refuse("robust");
        }
        if a.estimate_offset.is_some() {
            return refuse("estimate_offset");
        }
        if a.use_orientations || a.body_from_cam.is_some() {
            return refuse("use_orientations");
        }
        if a.n_to_align.is_some() {
            return refuse("n_to_align");
        }
        if a.dof != crate::align::dof::Dof::default() || a.anchor != Default::default() {
            return refuse("dof");
        }
        if a.association != Association::Evo {
            return refuse("association");
        }
        self.gnss.check()?;
        if self.gnss.origin == Origin::Mean {
            return Err(Error::invalid(
                "origin",
                "the mean of the fixes is known only once the log has ended: give the first fix \
                 or a position as the origin of an online session",
            ));
        }
        if self.gnss.lever_arm.is_some() {
            return refuse("lever_arm");
        }
        match &self.camera_height {
            Some(HeightSpec::File(_)) => {
                return Err(Error::invalid(
                    "camera_height",
                    "a file of heights is read by the batch convert: give the online session \
                     one height (every pose, or first:M)",
                ))
            }
            Some(HeightSpec::Constant(v) | HeightSpec::First(v))
                if !(v.is_finite() && *v > 0.0) =>
            {
                return Err(Error::invalid(
                    "camera_height",
                    format!("must be a positive number of metres, got {v}"),
                ))
            }
            _ => {}
        }
        for (what, v) in [
            ("stable_hold", self.stable_hold),
            ("rebuild_tolerance", self.rebuild_tolerance),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::invalid(what, format!("{v} is not a number >= 0")));
            }
        }
        Ok(())
    }
}

/// The start-up stage of the SLAM as seen so far.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Stage {
    /// Too few tracked frames matched with the reference to tell.
    Waiting,
    /// The unsynchronised start: the scale wanders and jumps.
    Start,
    /// The scale moves towards its final level.
    Converging,
    /// The scale has settled: `T_world_slam` is fitted.
    Stable,
}

impl Stage {
    /// The stage's name (`waiting`, `start`, `converging`, `stable`).
    pub fn name(self) -> &'static str {
        match self {
            Stage::Waiting => "waiting",
            Stage::Start => "start",
            Stage::Converging => "converging",
            Stage::Stable => "stable",
        }
    }
}

/// What [`Session::state`] says.
#[derive(Clone, Debug, PartialEq)]
pub struct SessionState {
    /// The stage.
    pub stage: Stage,
    /// Why (one line).
    pub reason: String,
    /// Latest SLAM stamp seen (tracked frame or keyframe), seconds.
    pub time: f64,
    /// Log time (latest SLAM stamp) at which the stable stage was first
    /// reported.
    pub stable_reported_at: Option<f64>,
    /// Where the current detection puts the stable stage's start (SLAM stamp).
    pub stable_time: Option<f64>,
    /// Where the current detection puts the converging stretch's start.
    pub converging_time: Option<f64>,
    /// Tracked frames pushed, and those matched with a reference pose.
    pub frames: usize,
    /// Tracked frames matched with a reference pose.
    pub frames_matched: usize,
    /// Keyframes (latest version per id).
    pub keyframes: usize,
    /// Keyframes matched with a reference pose.
    pub keyframes_matched: usize,
    /// Keyframe pairs in the fit.
    pub pairs_fitted: usize,
    /// Keyframes inserted into the map.
    pub keyframes_inserted: usize,
    /// Points inserted into the map.
    pub points: usize,
    /// Times the map was rebuilt because inserted keyframes moved.
    pub rebuilds: usize,
    /// GNSS fixes taken.
    pub fixes: usize,
    /// GNSS fixes dropped (status: no fix).
    pub fixes_dropped: usize,
    /// The ENU frame's origin (the world frame of a session fed fixes).
    pub enu_origin: Option<Geodetic>,
}

/// `T_world_slam` as the session has it.
#[derive(Clone, Debug)]
pub struct SessionTransform {
    /// `T_world_slam`.
    pub transform: Sim3,
    /// Its covariance from the fitted pairs (`None` with too few pairs for a
    /// degree of freedom).
    pub covariance: Option<Covariance>,
    /// rms residual of the fitted pairs, metres.
    pub rmse: f64,
    /// Keyframe pairs fitted.
    pub pairs: usize,
    /// SLAM stamp of the first fitted pair's stage start (the live cut).
    pub stable_time: f64,
}

/// Why [`Session::transform`] has no transform yet.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NotReady {
    /// One line.
    pub reason: String,
}

impl std::fmt::Display for NotReady {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.reason)
    }
}

/// How long the last map update took, by part (seconds).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct UpdateTiming {
    /// Stage detection and fit.
    pub fit_s: f64,
    /// Backprojection of the keyframes inserted.
    pub backproject_s: f64,
    /// Octree insertion (or rebuild).
    pub insert_s: f64,
    /// Keyframes inserted by the update (all of them on a rebuild).
    pub inserted: usize,
    /// Whether the update rebuilt the map.
    pub rebuilt: bool,
}

impl UpdateTiming {
    /// Seconds of the update in all: fit, backprojection and insertion.
    pub fn total_s(&self) -> f64 {
        self.fit_s + self.backproject_s + self.insert_s
    }

    /// This update followed by `next` (a deferred refit's), as one.
    pub fn then(self, next: UpdateTiming) -> UpdateTiming {
        UpdateTiming {
            fit_s: self.fit_s + next.fit_s,
            backproject_s: self.backproject_s + next.backproject_s,
            insert_s: self.insert_s + next.insert_s,
            inserted: self.inserted + next.inserted,
            rebuilt: self.rebuilt || next.rebuilt,
        }
    }
}

/// A tracked frame waiting for its reference pose: time, SLAM position.
type Pending = (f64, Vector3<f64>);

/// A keyframe as the session keeps it.
#[derive(Clone, Debug)]
struct Kf {
    keyframe: Keyframe,
    /// Order of first arrival (the batch's keyframe order, which the
    /// viewer's `cutFirstNKf` counts in).
    arrival: usize,
    /// The reference position it is paired with.
    reference: Option<Vector3<f64>>,
    /// The pair's weight (1, or `1 / σ̄²` of interpolated fixes).
    weight: f64,
    /// The SLAM position that is in the moments (when it is fitted).
    in_fit: Option<Vector3<f64>>,
}

/// What the session's reference is.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Reference {
    /// Nothing pushed yet.
    None,
    /// Reference poses (`push_reference`), paired by the nearest stamp.
    Poses,
    /// GNSS fixes in ENU at this frame, interpolated at the SLAM stamps.
    Fixes(EnuFrame),
}

/// An inserted keyframe: the `T_world_cam` it was inserted with.
#[derive(Clone, Copy, Debug)]
struct Inserted {
    t_world_cam: Sim3,
}

/// An occupancy map and the keyframes in it.
#[derive(Clone, Debug, Default)]
struct MapState {
    map: Option<OccupancyMap>,
    inserted: BTreeMap<i32, Inserted>,
    points: usize,
}

/// Keyframes a keyframe push inserts into a map being built in steps
/// ([`Session`]'s map doc); a tracked frame's push inserts one.
pub const BUILD_STEP: usize = 2;

/// The online conversion (see the module doc).
pub struct Session {
    opts: SessionOptions,
    /// Poses or fixes, once the first one came.
    reference: Reference,
    ref_times: Vec<f64>,
    /// The gap the reference so far is interpolated over by default.
    ref_gap: GapOfStream,
    ref_pos: Vec<Vector3<f64>>,
    ref_rot: Vec<Option<UnitQuaternion<f64>>>,
    /// Per fix, its mean variance `1 / (3 / trace Σ)` (the batch weight's
    /// inverse), while every fix has a covariance and weights are asked for.
    ref_var: Vec<f64>,
    weighted: bool,
    fixes_dropped: usize,
    imu: usize,
    // Tracked frames: matched pairs in time order.
    frames: usize,
    pending_frames: Vec<Pending>,
    live_times: Vec<f64>,
    live_slam: Vec<Vector3<f64>>,
    live_ref: Vec<Vector3<f64>>,
    last_detect: f64,
    // Keyframes by id, and those waiting for a reference pose.
    kfs: BTreeMap<i32, Kf>,
    pending_kfs: Vec<i32>,
    latest: f64,
    cut: Option<LiveCut>,
    stable_reported_at: Option<f64>,
    stage: Stage,
    reason: String,
    converging_s: f64,
    settled_s: f64,
    finished: bool,
    // The fit: moments over the fitted keyframes (by id), from `fit_from`.
    moments: Option<Moments>,
    fit_from: f64,
    transform: Option<Sim3>,
    // The map served, and the one being built in steps to replace it.
    served: MapState,
    building: Option<MapState>,
    rebuilds: usize,
    last_update: UpdateTiming,
    /// With a camera height and no reference: each keyframe's points in the
    /// SLAM frame (every k-th), with the pose they were carried by.
    ground_points: BTreeMap<i32, (Sim3, Vec<Vector3<f64>>)>,
    /// Keyframes came or moved since the ground plane was last fitted.
    ground_dirty: bool,
    /// Keyframes at the last ground fit that gave the transform.
    ground_fitted_at: usize,
    /// Ground refits are left to [`Session::catch_up`] ([`Session::defer_refits`]).
    defer_refits: bool,
    /// A ground refit is due and was left to [`Session::catch_up`].
    refit_due: bool,
}

/// Most points of one keyframe the session's ground plane weighs.
const GROUND_POINTS_PER_KEYFRAME: usize = 4000;

/// Most points of a ground refit before the end (every k-th beyond): the
/// plane of a long run is as well supported by 100 000 floor and wall
/// points as by all of them, and the refit's time (133 ms for the 490 000
/// of a 123-keyframe run) is a keyframe's latency.
const ONLINE_GROUND_POINTS: usize = 100_000;

fn finite3(what: &str, v: &Vector3<f64>) -> Result<()> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(Error::NonFinite {
            what: what.into(),
            index: 0,
        })
    }
}

impl Session {
    /// A new session; the options are checked.
    pub fn new(opts: SessionOptions) -> Result<Session> {
        opts.check()?;
        Ok(Session {
            opts,
            reference: Reference::None,
            ref_var: Vec::new(),
            weighted: true,
            fixes_dropped: 0,
            ref_times: Vec::new(),
            ref_gap: GapOfStream::default(),
            ref_pos: Vec::new(),
            ref_rot: Vec::new(),
            imu: 0,
            frames: 0,
            pending_frames: Vec::new(),
            live_times: Vec::new(),
            live_slam: Vec::new(),
            live_ref: Vec::new(),
            last_detect: f64::NEG_INFINITY,
            kfs: BTreeMap::new(),
            pending_kfs: Vec::new(),
            latest: f64::NEG_INFINITY,
            cut: None,
            stable_reported_at: None,
            stage: Stage::Waiting,
            converging_s: 0.0,
            settled_s: 0.0,
            finished: false,
            reason: "no tracked frame matched with a reference pose yet".into(),
            moments: None,
            fit_from: f64::INFINITY,
            transform: None,
            served: MapState::default(),
            building: None,
            rebuilds: 0,
            last_update: UpdateTiming::default(),
            ground_points: BTreeMap::new(),
            ground_dirty: false,
            ground_fitted_at: 0,
            defer_refits: false,
            refit_due: false,
        })
    }

    /// The options.
    pub fn options(&self) -> &SessionOptions {
        &self.opts
    }

    /// A reference pose `T_world_body` at `time` (seconds; positions in
    /// metres). Poses must come in increasing time.
    pub fn push_reference(
        &mut self,
        time: f64,
        position: Vector3<f64>,
        orientation: Option<UnitQuaternion<f64>>,
    ) -> Result<()> {
        finite3("reference position", &position)?;
        if !time.is_finite() {
            return Err(Error::invalid("time", format!("{time} is not finite")));
        }
        if matches!(self.reference, Reference::Fixes(_)) {
            return Err(Error::invalid(
                "push_reference",
                "this session's reference is GNSS fixes (push_fix): one session takes \
                 reference poses or fixes, not both",
            ));
        }
        self.reference = Reference::Poses;
        if let Some(&last) = self.ref_times.last() {
            if time <= last {
                return Err(Error::invalid(
                    "time",
                    format!(
                        "reference pose at {time} s is not after the previous one ({last} s): \
                         the session takes reference poses in time order"
                    ),
                ));
            }
        }
        self.ref_times.push(time);
        self.ref_gap.push(time);
        self.ref_pos.push(position);
        self.ref_rot.push(orientation);
        self.match_pending(false);
        Ok(())
    }

    /// An IMU sample (kept, not used online yet: the session's world frame
    /// comes from the reference poses).
    pub fn push_imu(&mut self, time: f64, gyro: Vector3<f64>, accel: Vector3<f64>) -> Result<()> {
        finite3("gyro", &gyro)?;
        finite3("accel", &accel)?;
        if !time.is_finite() {
            return Err(Error::invalid("time", format!("{time} is not finite")));
        }
        self.imu += 1;
        Ok(())
    }

    /// A GNSS fix (seconds; WGS84 degrees, metres above the ellipsoid; ENU
    /// covariance in m² when known). The first fix puts the world frame: ENU
    /// at it, or at [`GnssOptions::origin`] when one is given. A fix without
    /// a fix (status) is dropped and counted, as the batch reader does. Fixes
    /// must come in increasing time; a session fed reference poses refuses
    /// them.
    pub fn push_fix(&mut self, fix: &GnssFix) -> Result<()> {
        if !fix.time.is_finite() {
            return Err(Error::invalid(
                "time",
                format!("{} is not finite", fix.time),
            ));
        }
        let g = Geodetic::try_new(fix.lat, fix.lon, fix.alt)?;
        if let Some(c) = &fix.covariance {
            if !c.iter().all(|v| v.is_finite()) {
                return Err(Error::NonFinite {
                    what: "fix covariance".into(),
                    index: 0,
                });
            }
        }
        if self.reference == Reference::Poses {
            return Err(Error::invalid(
                "push_fix",
                "this session's reference is reference poses (push_reference): one session \
                 takes reference poses or fixes, not both",
            ));
        }
        if !fix.status.is_fix() {
            self.fixes_dropped += 1;
            return Ok(());
        }
        if let Some(&last) = self.ref_times.last() {
            if fix.time <= last {
                return Err(Error::invalid(
                    "time",
                    format!(
                        "fix at {} s is not after the previous one ({last} s): the session \
                         takes fixes in time order",
                        fix.time
                    ),
                ));
            }
        }
        let frame = match self.reference {
            Reference::Fixes(f) => f,
            _ => {
                let origin = match self.opts.gnss.origin {
                    Origin::Given(o) => o,
                    // `Mean` is refused by the options' check.
                    Origin::First | Origin::Mean => g,
                };
                let f = EnuFrame::new(origin)?;
                self.reference = Reference::Fixes(f);
                f
            }
        };
        // The batch weight is 3 / trace(Σ) per fix, used only when every fix
        // has one; its inverse is what is interpolated.
        match (&fix.covariance, self.weighted && self.opts.gnss.weights) {
            (Some(c), true) => self.ref_var.push(1.0 / (3.0 / c.trace())),
            (_, true) => {
                // From here on all pairs weigh the same, those fitted already too.
                self.weighted = false;
                self.ref_var.clear();
                self.resum();
            }
            (_, false) => {}
        }
        self.ref_times.push(fix.time);
        self.ref_gap.push(fix.time);
        self.ref_pos.push(frame.geodetic_to_enu(&g));
        self.ref_rot.push(None);
        self.match_pending(false);
        Ok(())
    }

    /// A tracked frame: the SLAM's `T_slam_cam` at `time` as published live
    /// (LSD-SLAM's live frames), the start-up stages' evidence.
    pub fn push_frame(&mut self, time: f64, pose: &Sim3) -> Result<()> {
        finite3("frame position", &pose.translation)?;
        if !time.is_finite() {
            return Err(Error::invalid("time", format!("{time} is not finite")));
        }
        self.frames += 1;
        self.pending_frames.push((time, pose.translation));
        self.latest = self.latest.max(time);
        self.match_pending(false);
        if time - self.last_detect >= DETECT_EVERY_S {
            // The stage only: the fit and the map move with keyframes.
            self.detect(false);
        }
        // A map being built takes one more keyframe (an update of its own).
        if self.building.is_some() && self.transform.is_some() {
            self.last_update = UpdateTiming::default();
            self.step_build(1)?;
        }
        Ok(())
    }

    /// A keyframe (its pose `T_slam_cam` as published now); a keyframe of an id
    /// already seen replaces it (a re-published, refined keyframe). Updates the
    /// stages, the fit and the map.
    pub fn push_keyframe(&mut self, keyframe: Keyframe) -> Result<UpdateTiming> {
        finite3("keyframe position", &keyframe.pose.translation)?;
        let id = keyframe.id;
        self.latest = self.latest.max(keyframe.timestamp);
        match self.kfs.get_mut(&id) {
            Some(k) => {
                let (old_time, reference) = (k.keyframe.timestamp, k.reference);
                k.keyframe = keyframe;
                if k.keyframe.timestamp != old_time || reference.is_none() {
                    // Paired anew at its (new) time.
                    self.unfit(id);
                    if let Some(k) = self.kfs.get_mut(&id) {
                        k.reference = None;
                    }
                    if !self.pending_kfs.contains(&id) {
                        self.pending_kfs.push(id);
                    }
                } else {
                    self.refit_moved(id);
                }
            }
            None => {
                let arrival = self.kfs.len();
                self.kfs.insert(
                    id,
                    Kf {
                        keyframe,
                        arrival,
                        reference: None,
                        weight: 1.0,
                        in_fit: None,
                    },
                );
                self.pending_kfs.push(id);
            }
        }
        self.ground_dirty = true;
        self.match_pending(false);
        self.update()?;
        Ok(self.last_update)
    }

    /// A graph update: new poses `T_slam_cam` of keyframes by id (ids not seen
    /// yet are ignored, as the batch reader does). Moved keyframes are taken
    /// out of the fit and put back, and re-inserted into the map when they
    /// moved beyond the tolerance.
    pub fn push_graph_update(&mut self, poses: &[(i32, Sim3)]) -> Result<UpdateTiming> {
        for (id, pose) in poses {
            finite3("graph pose", &pose.translation)?;
            if let Some(k) = self.kfs.get_mut(id) {
                k.keyframe.pose = *pose;
                self.ground_dirty = true;
                self.refit_moved(*id);
            }
        }
        self.update()?;
        Ok(self.last_update)
    }

    /// Everything has been pushed: pairs every item still waiting (no later
    /// reference pose will come), cuts by the batch rule on all the data (the
    /// stable stage then holds even where it was not reported online:
    /// `stable_reported_at` stays `None`), fits, and rebuilds
    /// the map when anything inserted moved at all, so that it equals the
    /// batch conversion's octree of the same data.
    pub fn finish(&mut self) -> Result<UpdateTiming> {
        self.finished = true;
        self.match_pending(true);
        self.update()?;
        if self.transform.is_some() {
            // The build in progress completed; then, where anything inserted
            // moved at all, built again, so that the map is the batch's.
            self.step_build(usize::MAX)?;
            if self.moved(&self.served, 0.0) {
                self.building = Some(MapState::default());
                self.step_build(usize::MAX)?;
            }
        }
        Ok(self.last_update)
    }

    /// The stage and what the session holds.
    pub fn state(&self) -> SessionState {
        SessionState {
            stage: self.stage,
            reason: self.reason.clone(),
            time: self.latest,
            stable_reported_at: self.stable_reported_at,
            stable_time: self.cut.as_ref().map(|c| c.stable_time),
            converging_time: self.cut.as_ref().map(|c| c.converging_time),
            frames: self.frames,
            frames_matched: self.live_times.len(),
            keyframes: self.kfs.len(),
            keyframes_matched: self.kfs.values().filter(|k| k.reference.is_some()).count(),
            pairs_fitted: self.moments.as_ref().map_or(0, |m| m.n),
            keyframes_inserted: self.shown().inserted.len(),
            points: self.shown().points,
            rebuilds: self.rebuilds,
            fixes: match self.reference {
                Reference::Fixes(_) => self.ref_times.len(),
                _ => 0,
            },
            fixes_dropped: self.fixes_dropped,
            enu_origin: match self.reference {
                Reference::Fixes(f) => Some(f.origin()),
                _ => None,
            },
        }
    }

    /// `T_world_slam` with its covariance once the stable stage is reached;
    /// before, why not.
    pub fn transform(&self) -> std::result::Result<SessionTransform, NotReady> {
        let Some(t) = self.transform else {
            return Err(NotReady {
                reason: self.reason.clone(),
            });
        };
        let (src, dst, w) = self.fitted_pairs();
        let weights = self.weighs().then_some(w.as_slice());
        let rmse = (src
            .iter()
            .zip(&dst)
            .map(|(a, b)| (b - t.transform_point(a)).norm_squared())
            .sum::<f64>()
            / src.len().max(1) as f64)
            .sqrt();
        Ok(SessionTransform {
            transform: t,
            covariance: covariance(&t, &src, &dst, weights, self.opts.align.scale).ok(),
            rmse,
            pairs: src.len(),
            stable_time: self.fit_from,
        })
    }

    /// The occupancy map (world frame), once the transform is known.
    pub fn map(&self) -> Option<&OccupancyMap> {
        self.shown().map.as_ref()
    }

    /// The map served: the one built last, or while the first is still being
    /// built, that one as far as it goes.
    fn shown(&self) -> &MapState {
        match (&self.served.map, &self.building) {
            (None, Some(b)) => b,
            _ => &self.served,
        }
    }

    /// The 2-D grid of the map ([`OccupancyMap::grid`]); an error before there
    /// is a map.
    pub fn grid(&self, z_min: f64, z_max: f64, resolution: Option<f64>) -> Result<Grid2d> {
        match &self.shown().map {
            Some(m) => m.grid(z_min, z_max, resolution),
            None => Err(Error::invalid(
                "grid",
                format!("no map yet: {}", self.reason),
            )),
        }
    }

    /// The reference so far in the world frame: the poses pushed, or the
    /// fixes as ENU positions (no orientation), at most `most` of them
    /// evenly spread ([`crate::trajectory::even_indices`]); None before the
    /// first.
    pub fn reference_path(&self, most: usize) -> Result<Option<crate::trajectory::Trajectory>> {
        if self.ref_times.is_empty() {
            return Ok(None);
        }
        let idx = crate::trajectory::even_indices(self.ref_times.len(), most);
        let rot: Option<Vec<UnitQuaternion<f64>>> = idx.iter().map(|&i| self.ref_rot[i]).collect();
        crate::trajectory::Trajectory::try_new(
            idx.iter().map(|&i| self.ref_times[i]).collect(),
            idx.iter().map(|&i| self.ref_pos[i]).collect(),
            rot,
        )
        .map(Some)
    }

    /// The keyframes (latest version per id, ascending id), poses as last
    /// pushed.
    pub fn keyframes(&self) -> impl Iterator<Item = &Keyframe> {
        self.kfs.values().map(|k| &k.keyframe)
    }

    /// The timing of the last update.
    pub fn last_update(&self) -> UpdateTiming {
        self.last_update
    }

    /// With `on`, a push whose update calls for a ground refit (a camera
    /// height, no reference: the keyframes grew by a quarter since the
    /// last fit) leaves it for [`Session::catch_up`]: the update carries the
    /// new keyframe by the transform it has, so that a live viewer gets its
    /// points without waiting for the refit (tens of milliseconds at a few
    /// hundred keyframes), and the refit follows at once. The first fit and
    /// the end's are never deferred. Off by default.
    pub fn defer_refits(&mut self, on: bool) {
        self.defer_refits = on;
    }

    /// Whether a deferred refit waits for [`Session::catch_up`].
    pub fn has_deferred(&self) -> bool {
        self.refit_due
    }

    /// Does the refit a push left for later ([`Session::defer_refits`]) and
    /// the map update it calls for: the session is then where it would be
    /// had nothing been deferred. Returns that update's timing (zeros when
    /// nothing was due).
    pub fn catch_up(&mut self) -> Result<UpdateTiming> {
        if !self.refit_due {
            return Ok(UpdateTiming::default());
        }
        let defer = std::mem::replace(&mut self.defer_refits, false);
        let r = self.update();
        self.defer_refits = defer;
        r?;
        Ok(self.last_update)
    }

    /// IMU samples pushed.
    pub fn imu_samples(&self) -> usize {
        self.imu
    }

    // ------------------------------------------------------------ pairing

    /// The reference position paired with SLAM stamp `t` and the pair's
    /// weight; `None` when it cannot be decided yet (unless `all`), `Some(None)`
    /// when there is none. Poses: the nearest within `max_diff` after the
    /// offset, by the `evo` rule ([`crate::trajectory::associate`]), decided
    /// once a pose later than `t + max_diff` has come. Fixes: interpolated at
    /// `t + offset` between two fixes at most `max_gap` apart (the rule of
    /// [`crate::trajectory::Trajectory::interpolate_where_covered`]), decided
    /// once a fix at or after that time has come.
    fn reference_at(&self, t: f64, all: bool) -> Option<Option<(Vector3<f64>, f64)>> {
        let (max_diff, offset) = (self.opts.align.max_diff, self.opts.align.offset);
        let r = &self.ref_times;
        let t = t + offset;
        let last = *r.last()?;
        if matches!(self.reference, Reference::Fixes(_)) {
            // Before the first fix or inside a gap: none (fixes come in order).
            // The gap from the fixes so far, unless one is given.
            let gap = self.fix_gap();
            let Some((i, k, a)) = self.bracket_at(t, gap, all)? else {
                return Some(None);
            };
            let p = self.ref_pos[i].lerp(&self.ref_pos[k], a);
            let w = if self.weighs() {
                let v = Vector3::new(self.ref_var[i], 0.0, 0.0)
                    .lerp(&Vector3::new(self.ref_var[k], 0.0, 0.0), a);
                1.0 / v.x
            } else {
                1.0
            };
            return Some(Some((p, w)));
        }
        if !all && last <= t + max_diff {
            return None;
        }
        if t < r[0] - max_diff || t > last + max_diff {
            return Some(None);
        }
        let k = r.partition_point(|&x| x <= t).min(r.len() - 1);
        let diff_ub = r[k] - t;
        let diff_lb = if k > 0 { t - r[k - 1] } else { f64::INFINITY };
        let at = if diff_ub <= max_diff && diff_ub < diff_lb {
            Some(k)
        } else if diff_lb <= max_diff && diff_lb <= diff_ub {
            Some(k - 1)
        } else {
            None
        };
        Some(at.map(|k| (self.ref_pos[k], 1.0)))
    }

    /// Where the reference samples bracket `t` (offset applied already): the
    /// two samples at most `max_gap` apart and the fraction between them
    /// ([`crate::trajectory::bracket`]). `None` while the reference has not
    /// reached `t` (unless `all`), `Some(None)` when there are none.
    fn bracket_at(&self, t: f64, max_gap: f64, all: bool) -> Option<Option<(usize, usize, f64)>> {
        let r = &self.ref_times;
        if t > *r.last()? {
            return if all { Some(None) } else { None };
        }
        Some(crate::trajectory::bracket(r, t, max_gap).ok())
    }

    /// The gap between fixes bridged: the one given, else the fixes' so far
    /// ([`GnssOptions::max_gap_for`]'s rule).
    fn fix_gap(&self) -> f64 {
        self.opts.gnss.max_gap.unwrap_or_else(|| self.ref_gap.gap())
    }

    /// The reference position at a tracked frame's stamp `t`, as the batch
    /// cut takes it ([`super::startup::live_pairs`], [`super::gnss::live_cut`]):
    /// interpolated at `t + offset` between two reference samples at most
    /// [`crate::trajectory::gap_of`] the reference so far apart (fixes: the
    /// keyframes' gap, which is the same unless one is given) ([`Session::bracket_at`]).
    fn live_reference_at(&self, t: f64, all: bool) -> Option<Option<Vector3<f64>>> {
        let gap = match self.reference {
            Reference::Fixes(_) => self.fix_gap(),
            _ => self.ref_gap.gap(),
        };
        let b = self.bracket_at(t + self.opts.align.offset, gap, all)?;
        Some(b.map(|(i, k, a)| self.ref_pos[i].lerp(&self.ref_pos[k], a)))
    }

    fn match_pending(&mut self, all: bool) {
        if self.ref_times.is_empty() {
            return;
        }
        // Tracked frames.
        let mut keep = Vec::new();
        let mut matched = Vec::new();
        for (time, slam) in std::mem::take(&mut self.pending_frames) {
            match self.live_reference_at(time, all) {
                None => keep.push((time, slam)),
                Some(Some(r)) => matched.push((time, slam, r)),
                Some(None) => {}
            }
        }
        self.pending_frames = keep;
        for (time, slam, refp) in matched {
            // In time order (frames may arrive out of order only within the wait).
            let at = self.live_times.partition_point(|&x| x <= time);
            self.live_times.insert(at, time);
            self.live_slam.insert(at, slam);
            self.live_ref.insert(at, refp);
        }
        // Keyframes.
        let mut keep = Vec::new();
        for id in std::mem::take(&mut self.pending_kfs) {
            let Some(t) = self.kfs.get(&id).map(|k| k.keyframe.timestamp) else {
                continue;
            };
            match self.reference_at(t, all) {
                None => keep.push(id),
                Some(r) => {
                    if let Some(k) = self.kfs.get_mut(&id) {
                        k.reference = r.map(|(p, _)| p);
                        k.weight = r.map_or(1.0, |(_, w)| w);
                    }
                    self.fit_in(id);
                }
            }
        }
        self.pending_kfs = keep;
    }

    // ------------------------------------------------------------ fit

    /// The fitted pairs (SLAM, reference) and their weights.
    fn fitted_pairs(&self) -> (Vec<Vector3<f64>>, Vec<Vector3<f64>>, Vec<f64>) {
        let mut out = (Vec::new(), Vec::new(), Vec::new());
        for k in self.kfs.values() {
            if let (Some(a), Some(b)) = (k.in_fit, k.reference) {
                out.0.push(a);
                out.1.push(b);
                out.2.push(k.weight);
            }
        }
        out
    }

    /// The moments summed again over the keyframes from the fit's start (the
    /// weights changed).
    fn resum(&mut self) {
        for k in self.kfs.values_mut() {
            k.in_fit = None;
            k.weight = 1.0;
        }
        if self.moments.is_none() {
            return;
        }
        self.moments = None;
        let from = self.fit_from;
        self.fit_from = f64::INFINITY;
        self.move_cut(from);
    }

    /// Whether the pairs weigh `1 / σ̄²` (fixes, every one with a covariance,
    /// weights asked for).
    fn weighs(&self) -> bool {
        matches!(self.reference, Reference::Fixes(_)) && self.weighted && self.opts.gnss.weights
    }

    /// Puts keyframe `id` into the moments when it belongs to the fit.
    fn fit_in(&mut self, id: i32) {
        let Some(m) = self.moments.as_mut() else {
            return;
        };
        let Some(k) = self.kfs.get_mut(&id) else {
            return;
        };
        if k.in_fit.is_some() || k.keyframe.timestamp < self.fit_from {
            return;
        }
        if let Some(r) = k.reference {
            m.push_weighted(&k.keyframe.pose.translation, &r, k.weight);
            k.in_fit = Some(k.keyframe.pose.translation);
        }
    }

    /// Takes keyframe `id` out of the moments.
    fn unfit(&mut self, id: i32) {
        let (Some(m), Some(k)) = (self.moments.as_mut(), self.kfs.get_mut(&id)) else {
            return;
        };
        if let (Some(a), Some(b)) = (k.in_fit.take(), k.reference) {
            m.pull_weighted(&a, &b, k.weight);
        }
    }

    /// A fitted keyframe whose pose changed: out with the old, in with the new.
    fn refit_moved(&mut self, id: i32) {
        let moved = self
            .kfs
            .get(&id)
            .is_some_and(|k| k.in_fit.is_some_and(|a| a != k.keyframe.pose.translation));
        if moved {
            self.unfit(id);
            self.fit_in(id);
        }
    }

    /// Moves the start of the fit to `from`: the keyframe pairs between the
    /// old and the new start are taken out of or put into the moments (the
    /// first time, the moments start at the first pair).
    fn move_cut(&mut self, from: f64) {
        let old = self.fit_from;
        self.fit_from = from;
        if self.moments.is_none() {
            let first = self
                .kfs
                .values()
                .filter(|k| k.reference.is_some() && k.keyframe.timestamp >= from)
                .min_by(|a, b| a.keyframe.timestamp.total_cmp(&b.keyframe.timestamp));
            let Some(k) = first else {
                return;
            };
            self.moments = Some(Moments::running(
                k.keyframe.pose.translation,
                k.reference.unwrap_or_default(),
            ));
        }
        let (lo, hi) = if from < old { (from, old) } else { (old, from) };
        let ids: Vec<i32> = self
            .kfs
            .values()
            .filter(|k| k.keyframe.timestamp >= lo && k.keyframe.timestamp < hi)
            .map(|k| k.keyframe.id)
            .collect();
        for id in ids {
            if from < old {
                self.fit_in(id);
            } else {
                self.unfit(id);
            }
        }
    }

    /// Stage detection on the matched frames so far; the fit; the map.
    fn update(&mut self) -> Result<()> {
        let t0 = Instant::now();
        self.last_update = UpdateTiming::default();
        if self.reference == Reference::None && self.opts.camera_height.is_some() {
            self.update_ground()?;
            self.last_update.fit_s = t0.elapsed().as_secs_f64();
            if self.transform.is_some() {
                self.update_map()?;
            }
            return Ok(());
        }
        self.detect(true);
        if self.stage == Stage::Stable {
            let from = self.cut.as_ref().map_or(f64::INFINITY, |c| c.stable_time);
            if self.moments.is_none() || from != self.fit_from {
                self.move_cut(from);
            }
            let opts = AlignOptions {
                scale: self.opts.align.scale,
                method: self.opts.align.method,
                ..AlignOptions::default()
            };
            self.transform = match &self.moments {
                Some(m) => match solve_running(m, &opts) {
                    Ok((t, _)) => Some(t),
                    Err(e) => {
                        self.reason = format!("stable, but no fit yet: {e}");
                        None
                    }
                },
                None => {
                    self.reason =
                        "stable, but no keyframe paired with a reference pose since its start yet"
                            .into();
                    None
                }
            };
        }
        self.last_update.fit_s = t0.elapsed().as_secs_f64();
        if self.transform.is_some() {
            self.update_map()?;
        }
        Ok(())
    }

    /// With a camera height and no reference: `T_world_slam` from the ground
    /// plane of the keyframes so far and the height, once a plane is
    /// supported (the stage is then stable), fitted again as the keyframes
    /// grow by a quarter and at the end (then equal to the batch convert's
    /// of the same keyframes); until then, or when a later keyframe makes
    /// the plane refused, the reason (a transform found before is kept).
    fn update_ground(&mut self) -> Result<()> {
        let Some(height) = self.opts.camera_height.clone() else {
            return Ok(());
        };
        // Once a plane gave the transform, it is fitted again when the
        // keyframes have grown by a quarter (and at the end): a new transform
        // moves every inserted keyframe, and the map is built again.
        let grown = 4 * self.kfs.len() >= 5 * self.ground_fitted_at;
        if !self.ground_dirty || !(self.finished || self.transform.is_none() || grown) {
            return Ok(());
        }
        self.refit_due = self.defer_refits && !self.finished && self.transform.is_some();
        if self.refit_due {
            return Ok(());
        }
        self.ground_dirty = false;
        let mut order: Vec<&Kf> = self.kfs.values().collect();
        order.sort_by(|a, b| a.keyframe.timestamp.total_cmp(&b.keyframe.timestamp));
        if order.is_empty() {
            self.reason = "no keyframe yet: the ground plane needs the map".into();
            return Ok(());
        }
        // Each keyframe's points carried by its pose now (again when it moved).
        for k in &order {
            let kf = &k.keyframe;
            if self
                .ground_points
                .get(&kf.id)
                .is_some_and(|(pose, _)| *pose == kf.pose)
            {
                continue;
            }
            let (c, _) = crate::cloud::backproject_batch_counted(
                std::slice::from_ref(kf),
                k.arrival,
                &self.opts.filter,
                |_| Sim3::identity(),
                false,
            )?;
            let pts = c
                .points_every(c.len().div_ceil(GROUND_POINTS_PER_KEYFRAME))
                .collect();
            self.ground_points.insert(kf.id, (kf.pose, pts));
        }
        let total: usize = order
            .iter()
            .filter_map(|k| self.ground_points.get(&k.keyframe.id))
            .map(|(_, p)| p.len())
            .sum();
        // While the run goes on, every k-th point (at most
        // ONLINE_GROUND_POINTS: a refit holds up the keyframe that asks for
        // it); at the end all of them, as the batch fit.
        let every = match self.finished {
            true => 1,
            false => total.div_ceil(ONLINE_GROUND_POINTS).max(1),
        };
        let points: Vec<Vector3<f64>> = order
            .iter()
            .filter_map(|k| self.ground_points.get(&k.keyframe.id))
            .flat_map(|(_, p)| p.iter().copied())
            .step_by(every)
            .collect();
        let cams = crate::trajectory::Trajectory::try_new(
            order.iter().map(|k| k.keyframe.timestamp).collect(),
            order.iter().map(|k| k.keyframe.pose.translation).collect(),
            Some(order.iter().map(|k| k.keyframe.pose.rotation).collect()),
        )?;
        let first = cams.timestamps[0];
        let given = match height {
            HeightSpec::First(v) => crate::align::ground::CameraHeight::First(v),
            HeightSpec::Constant(v) => crate::align::ground::CameraHeight::Constant(v),
            // Refused by the options' check.
            HeightSpec::File(_) => return Ok(()),
        };
        let fitted = crate::align::ground::fit_ground_plane(
            &points,
            &cams,
            &crate::align::ground::GroundOptions::default(),
        )
        .and_then(|plane| {
            crate::align::ground::metric_from_height(&plane, &cams, &given)
                .map(|m| (plane.inliers, plane.n_points, m.t_world_slam))
        });
        match fitted {
            Ok((inliers, n, t)) => {
                self.transform = Some(t);
                self.ground_fitted_at = order.len();
                self.fit_from = first;
                self.stage = Stage::Stable;
                if self.stable_reported_at.is_none() {
                    self.stable_reported_at = Some(self.latest);
                }
                self.reason = format!(
                    "scale and up from the ground plane ({inliers} of {n} points of {} \
                     keyframes) and the camera height",
                    order.len()
                );
            }
            Err(e) => {
                self.reason = format!("no ground plane yet: {e}");
            }
        }
        Ok(())
    }

    /// The stage on the data so far; once stable and with `cut`, where the
    /// stable stage starts (the batch rule over every matched frame so far).
    fn detect(&mut self, cut: bool) {
        let dt = if self.last_detect.is_finite() {
            (self.latest - self.last_detect).max(0.0)
        } else {
            0.0
        };
        self.last_detect = self.latest;
        let n = self.live_times.len();
        if n < crate::align::stages::MIN_FACTORS + 1 {
            self.reason = format!(
                "{n} tracked frames matched with a reference pose: too few to tell the stage"
            );
            return;
        }
        if self.finished && self.stage != Stage::Stable {
            // The whole log is in: the batch rule decides (not reported online).
            self.stage = Stage::Stable;
        }
        if self.stage != Stage::Stable {
            match self.settled() {
                Ok(()) => {
                    self.settled_s += dt;
                    // The paper's order: a level that settles after converging;
                    // without a convergence seen, a level steady for long.
                    let after_converging =
                        self.converging_s >= MIN_CONVERGING_HOLDS * self.opts.stable_hold;
                    let long = self.settled_s >= LONG_SETTLED_HOLDS * self.opts.stable_hold;
                    if !(after_converging || long) {
                        self.stage = Stage::Start;
                        self.reason = format!(
                            "start: the level is steady, but no convergence was seen yet \
                             ({:.1} s converging of {:.1} s; steady {:.1} s of {:.1} s)",
                            self.converging_s,
                            MIN_CONVERGING_HOLDS * self.opts.stable_hold,
                            self.settled_s,
                            LONG_SETTLED_HOLDS * self.opts.stable_hold
                        );
                        return;
                    }
                    self.stage = Stage::Stable;
                    self.stable_reported_at = Some(self.latest);
                }
                Err((stage, why)) => {
                    self.settled_s = 0.0;
                    if stage == Stage::Converging {
                        self.converging_s += dt;
                    }
                    self.stage = stage;
                    self.reason = format!("{}: {why}", stage.name());
                    return;
                }
            }
        }
        if !cut {
            return;
        }
        // Stable: where the stage starts, by the batch rule on the data so far.
        match cut_of_pairs(&self.live_times, &self.live_slam, &self.live_ref) {
            Ok(cut) => {
                self.reason = format!(
                    "stable (reported at {:.3} s): {}",
                    self.stable_reported_at.unwrap_or(self.latest),
                    cut.describe()
                );
                self.cut = Some(cut);
            }
            Err(e) => self.reason = format!("stable, but the stage start is not found: {e}"),
        }
    }

    /// Whether `ln p_k` of the matched frames has settled: its medians over
    /// the last three spans of [`SessionOptions::stable_hold`] seconds agree
    /// within [`SETTLED_Z`] standard errors (the spread from the pooled MAD).
    /// Otherwise the stage it is in (a level far from the last span's: the
    /// start; a steady trend: converging) and why.
    fn settled(&self) -> std::result::Result<(), (Stage, String)> {
        self.settled_with(self.opts.stable_hold)
    }

    /// The settling test's medians and standard error with spans of `hold`
    /// seconds, for tracing (one line).
    #[doc(hidden)]
    pub fn debug_levels(&self, hold: f64) -> String {
        if self.live_times.len() < 30 {
            return String::new();
        }
        match self.settled_with(hold) {
            Ok(()) => "settled".into(),
            Err((s, why)) => format!("{} {why}", s.name()),
        }
    }

    fn settled_with(&self, hold: f64) -> std::result::Result<(), (Stage, String)> {
        let hold = hold.max(1e-9);
        let n = self.live_times.len();
        let now = self.live_times[n - 1];
        let x: Vec<f64> = (1..n)
            .map(|k| {
                let ds = (self.live_slam[k] - self.live_slam[k - 1]).norm_squared();
                let dr = (self.live_ref[k] - self.live_ref[k - 1]).norm_squared();
                (dr / ds).ln()
            })
            .collect();
        // Factor k belongs to the time of pair k + 1.
        let span = |lo: f64, hi: f64| -> Vec<f64> {
            let a = self.live_times.partition_point(|&t| t <= lo).max(1);
            let b = self.live_times.partition_point(|&t| t <= hi);
            x[a - 1..b.saturating_sub(1).max(a - 1)]
                .iter()
                .copied()
                .filter(|v| v.is_finite())
                .collect()
        };
        let spans = [
            span(now - 3.0 * hold, now - 2.0 * hold),
            span(now - 2.0 * hold, now - hold),
            span(now - hold, now),
        ];
        let few = spans.iter().map(Vec::len).min().unwrap_or(0);
        if now - self.live_times[0] < 3.0 * hold || few < SETTLED_MIN_FACTORS {
            return Err((
                Stage::Start,
                format!(
                    "{:.1} s of matched tracked frames: the level is judged over 3 × {hold} s",
                    now - self.live_times[0]
                ),
            ));
        }
        let med = |v: &[f64]| {
            let mut v = v.to_vec();
            v.sort_by(f64::total_cmp);
            let m = v.len() / 2;
            if v.len() % 2 == 1 {
                v[m]
            } else {
                0.5 * (v[m - 1] + v[m])
            }
        };
        let m: Vec<f64> = spans.iter().map(|v| med(v)).collect();
        let dev: Vec<f64> = spans
            .iter()
            .zip(&m)
            .flat_map(|(v, c)| v.iter().map(move |x| (x - c).abs()))
            .collect();
        let sigma = 1.4826 * med(&dev);
        let se: Vec<f64> = spans
            .iter()
            .map(|v| 1.2533 * sigma / (v.len() as f64).sqrt())
            .collect();
        let z = |i: usize, j: usize| (m[i] - m[j]).abs() / (se[i] * se[i] + se[j] * se[j]).sqrt();
        let (z01, z12, z02) = (z(0, 1), z(1, 2), z(0, 2));
        if z01 <= SETTLED_Z && z12 <= SETTLED_Z && z02 <= SETTLED_Z {
            return Ok(());
        }
        // A steady move in one direction over the three spans: converging.
        let monotone = (m[0] < m[1] && m[1] < m[2]) || (m[0] > m[1] && m[1] > m[2]);
        let stage = if monotone && z12 <= 4.0 * SETTLED_Z {
            Stage::Converging
        } else {
            Stage::Start
        };
        Err((
            stage,
            format!(
                "median ln p over the last 3 × {hold} s: {:.3}, {:.3}, {:.3} (standard errors \
                 {:.3}); not within {SETTLED_Z} standard errors of each other",
                m[0], m[1], m[2], se[2]
            ),
        ))
    }

    // ------------------------------------------------------------ map

    fn t_world_cam(&self, kf: &Keyframe) -> Option<Sim3> {
        self.transform.map(|t| t * kf.pose)
    }

    /// Whether some keyframe inserted into `m` has a `T_world_cam` that moved
    /// by more than `tol` (metres at its camera and at the map's max range,
    /// 10 m without one); `tol = 0`: moved at all.
    fn moved(&self, m: &MapState, tol: f64) -> bool {
        let range = self.opts.map.max_range.unwrap_or(10.0);
        m.inserted.iter().any(|(id, ins)| {
            let Some(now) = self.kfs.get(id).and_then(|k| self.t_world_cam(&k.keyframe)) else {
                return true;
            };
            if tol == 0.0 {
                return now != ins.t_world_cam;
            }
            // A point `range` metres in front of the camera.
            let far = Vector3::new(0.0, 0.0, range / now.scale);
            let d_centre = (now.translation - ins.t_world_cam.translation).norm();
            let d_far = (now.transform_point(&far) - ins.t_world_cam.transform_point(&far)).norm();
            !(d_centre <= tol && d_far <= tol)
        })
    }

    /// Whether a keyframe not in `m` has an id below one that is (inserting
    /// it would change the batch order).
    fn out_of_order(&self, m: &MapState) -> bool {
        let first_new = self.kfs.keys().find(|id| !m.inserted.contains_key(id));
        matches!((first_new, m.inserted.keys().next_back()), (Some(a), Some(b)) if a < b)
    }

    /// Inserts keyframe `id` into `m` with the current transform.
    fn insert_one(&mut self, id: i32, m: &mut MapState) -> Result<()> {
        let Some((kf, arrival)) = self.kfs.get(&id).map(|k| (&k.keyframe, k.arrival)) else {
            return Ok(());
        };
        let Some(t) = self.transform else {
            return Ok(());
        };
        let tb = Instant::now();
        // The viewer's cut counts keyframes in arrival order, not in this slice of one.
        let filter = PointFilter {
            cut_first_keyframes: None,
            ..self.opts.filter
        };
        let (cloud, _) = if self.opts.filter.cuts(arrival) {
            Default::default()
        } else {
            backproject_counted(std::slice::from_ref(kf), &filter, Some(&t))?
        };
        self.last_update.backproject_s += tb.elapsed().as_secs_f64();
        let ti = Instant::now();
        let c = t.transform_point(&kf.pose.translation);
        let origin = [c.x as f32, c.y as f32, c.z as f32];
        let t_world_cam = t * kf.pose;
        let map = match &mut m.map {
            Some(map) => map,
            None => m.map.insert(OccupancyMap::try_new(self.opts.map)?),
        };
        if !cloud.points.is_empty() {
            map.insert_scan(&cloud.points, origin)?;
            m.points += cloud.len();
        }
        m.inserted.insert(id, Inserted { t_world_cam });
        self.last_update.insert_s += ti.elapsed().as_secs_f64();
        self.last_update.inserted += 1;
        Ok(())
    }

    /// Inserts up to `n` keyframes (ascending id) into the map being built;
    /// once every keyframe is in, it replaces the served map.
    fn step_build(&mut self, n: usize) -> Result<()> {
        if self.transform.is_none() {
            return Ok(());
        }
        let Some(mut b) = self.building.take() else {
            return Ok(());
        };
        let todo: Vec<i32> = self
            .kfs
            .keys()
            .copied()
            .filter(|id| !b.inserted.contains_key(id))
            .take(n)
            .collect();
        for id in todo {
            crate::interrupt::check()?;
            self.insert_one(id, &mut b)?;
        }
        if b.inserted.len() == self.kfs.len() {
            b.map.get_or_insert(OccupancyMap::try_new(self.opts.map)?);
            self.served = b;
            self.rebuilds += 1;
            self.last_update.rebuilt = true;
        } else {
            self.building = Some(b);
        }
        Ok(())
    }

    /// Keeps the map up to date: new keyframes into the served map; a map
    /// built anew in steps of [`BUILD_STEP`] keyframes per push (the served
    /// one kept until it is complete) when there is none yet, when an
    /// inserted keyframe moved beyond the tolerance, or when a keyframe came
    /// out of id order; a build whose keyframes moved starts again.
    fn update_map(&mut self) -> Result<()> {
        let tol = self.opts.rebuild_tolerance;
        let restart = match &self.building {
            Some(b) => self.out_of_order(b) || self.moved(b, tol),
            None => {
                self.served.map.is_none()
                    || self.out_of_order(&self.served)
                    || self.moved(&self.served, tol)
            }
        };
        if restart {
            self.building = Some(MapState::default());
        }
        if self.building.is_some() {
            return self.step_build(BUILD_STEP);
        }
        let new: Vec<i32> = self
            .kfs
            .keys()
            .copied()
            .filter(|id| !self.served.inserted.contains_key(id))
            .collect();
        let mut m = std::mem::take(&mut self.served);
        let r = new
            .into_iter()
            .try_for_each(|id| self.insert_one(id, &mut m));
        self.served = m;
        r
    }
}

impl std::fmt::Debug for Session {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Session")
            .field("stage", &self.stage)
            .field("keyframes", &self.kfs.len())
            .field("frames", &self.frames)
            .field("reference", &self.ref_times.len())
            .finish_non_exhaustive()
    }
}

/// What [`LogFeed::push`] did with a message.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Pushed {
    /// A keyframe went in: its id, the decode time (seconds) and the update.
    Keyframe {
        /// Keyframe id.
        id: i32,
        /// Decoding the message into a keyframe, seconds.
        decode_s: f64,
        /// The update it caused.
        timing: UpdateTiming,
    },
    /// A tracked frame, a graph update, a reference pose, a GNSS fix or an IMU sample.
    Other,
    /// A message the session does not use (another type, a second pose topic,
    /// a reference pose of a repeated stamp).
    Ignored,
}

/// A [`Session`] fed raw log messages (topic, type, encoding, bytes) in log
/// order, as `follow` reads them: LSD-SLAM keyframes and live frames
/// (`keyframeMsg`, told apart by `isKeyframe`), graph messages, the first
/// pose topic seen as the reference (a repeated stamp keeps its first pose,
/// as the batch reader does) — or the first GNSS topic (`NavSatFix`,
/// `LocationFix`), whichever comes first — IMU samples.
#[derive(Debug)]
pub struct LogFeed {
    /// The session.
    pub session: Session,
    reference_topic: Option<String>,
    last_reference: f64,
}

/// Whether `topic` is the feed's reference topic: the first one offered
/// becomes it.
fn is_reference(reference: &mut Option<String>, topic: &str) -> bool {
    reference.get_or_insert_with(|| topic.to_string()) == topic
}

impl LogFeed {
    /// A feed into a new session.
    pub fn new(opts: SessionOptions) -> Result<LogFeed> {
        Ok(LogFeed {
            session: Session::new(opts)?,
            reference_topic: None,
            last_reference: f64::NEG_INFINITY,
        })
    }

    /// The reference topic in use, once one was seen.
    pub fn reference_topic(&self) -> Option<&str> {
        self.reference_topic.as_deref()
    }

    /// Decodes one message and pushes it. Errors name the topic.
    pub fn push(
        &mut self,
        topic: &str,
        kind: Option<crate::io::messages::decode::MessageKind>,
        encoding: &str,
        data: &[u8],
    ) -> Result<Pushed> {
        use crate::io::messages::decode::{self, MessageKind};
        let fail = |what: String| Error::invalid("message", format!("topic {topic}: {what}"));
        match kind {
            Some(MessageKind::Keyframe) => {
                let t0 = Instant::now();
                let m = decode::keyframe_ros1(data).map_err(|e| fail(e.to_string()))?;
                let pose = Sim3::from_lsd_slam(&m.cam_to_world)
                    .map_err(|e| fail(format!("camToWorld: {e}")))?;
                if !m.is_keyframe {
                    self.session.push_frame(m.time, &pose)?;
                    return Ok(Pushed::Other);
                }
                let (idepth, var, color) = decode::split_pointcloud(m.pointcloud);
                let camera = crate::geometry::PinholeCamera::try_new(
                    m.fx, m.fy, m.cx, m.cy, m.width, m.height,
                )
                .map_err(|e| fail(format!("camera: {e}")))?;
                let kf =
                    Keyframe::try_new(m.id, m.time, pose, camera, idepth, Some(var), Some(color))
                        .map_err(|e| fail(format!("keyframe {}: {e}", m.id)))?;
                let decode_s = t0.elapsed().as_secs_f64();
                let timing = self.session.push_keyframe(kf)?;
                Ok(Pushed::Keyframe {
                    id: m.id,
                    decode_s,
                    timing,
                })
            }
            Some(MessageKind::KeyframeGraph) => {
                let frames = decode::graph_ros1(data).map_err(|e| fail(e.to_string()))?;
                let poses = frames
                    .iter()
                    .map(|(id, c2w)| {
                        Sim3::from_lsd_slam(c2w)
                            .map(|p| (*id, p))
                            .map_err(|e| fail(format!("keyframe {id}: camToWorld: {e}")))
                    })
                    .collect::<Result<Vec<_>>>()?;
                self.session.push_graph_update(&poses)?;
                Ok(Pushed::Other)
            }
            Some(MessageKind::Imu) => {
                let s = decode::imu(encoding, data).map_err(|e| fail(e.to_string()))?;
                self.session
                    .push_imu(s.time, Vector3::from(s.gyro), Vector3::from(s.accel))?;
                Ok(Pushed::Other)
            }
            Some(k @ (MessageKind::NavSatFix | MessageKind::LocationFix)) => {
                if !is_reference(&mut self.reference_topic, topic) {
                    return Ok(Pushed::Ignored);
                }
                let fix = crate::io::messages::gnss::gnss_fix(k, encoding, data)
                    .map_err(|e| fail(e.to_string()))?;
                if fix.status.is_fix() && fix.time <= self.last_reference {
                    return Ok(Pushed::Ignored);
                }
                if fix.status.is_fix() {
                    self.last_reference = fix.time;
                }
                self.session.push_fix(&fix)?;
                Ok(Pushed::Other)
            }
            Some(k) if k.is_pose() && k != MessageKind::Tf => {
                if !is_reference(&mut self.reference_topic, topic) {
                    return Ok(Pushed::Ignored);
                }
                let (t, p, [x, y, z, w]) =
                    decode::pose_sample(k, encoding, data).map_err(|e| fail(e.to_string()))?;
                if t <= self.last_reference {
                    return Ok(Pushed::Ignored);
                }
                self.last_reference = t;
                let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
                self.session.push_reference(t, Vector3::from(p), Some(q))?;
                Ok(Pushed::Other)
            }
            _ => Ok(Pushed::Ignored),
        }
    }
}
