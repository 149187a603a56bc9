//! [`SessionWorld`]: the metric world of a running [`Session`] as
//! `world.mcap` holds it — what `follow` writes after every keyframe and
//! what `Session.serve` puts on a Foxglove WebSocket — and the
//! [`FollowReport`] of a session, its state channel.

use std::path::Path;
use std::sync::{Arc, Mutex};

use crate::cloud::PointFilter;
use crate::error::Result;
use crate::geometry::Sim3;
use crate::io::atomic::OutputSet;
use crate::io::mcap::grid_msgs::{grid_channels, GridChannel};
use crate::io::mcap::write::{topics, world_mcap_bytes, write_world_mcap_extra_into, ExtraChannel};
use crate::io::mcap::{WorldFlavor, WorldScene};
use crate::io::spill::{CloudRef, TrajectoryRef};
use crate::live::LiveCloud;
use crate::map::{Grid2d, GridParams, VoxelState};
use crate::pipeline::outputs::WORLD_MCAP;
use crate::pipeline::report::{FollowReport, TransformReport};
use crate::pipeline::session::{Session, UpdateTiming};
use crate::trajectory::Trajectory;

/// The world of a session, written again after each of its updates: the
/// world cloud bounded for a viewer ([`LiveCloud`]: each keyframe
/// backprojected once, again only when the graph moves it), the keyframe
/// path and the reference path in the world frame (each at most
/// [`crate::defaults::LIVE_PATH_POSES`] poses), `world → slam`,
/// `world → camera` (the latest keyframe), `world → body` (the latest
/// reference pose), the occupied voxels, the 2-D grid when asked for, and
/// the session's state as JSON on `/slam2world/state` (a [`FollowReport`]).
pub struct SessionWorld {
    cloud: LiveCloud,
    grid: Option<GridParams>,
    flavor: WorldFlavor,
    buffers: Buffers,
}

/// The memory of the worlds sent lately ([`LiveWorld::bytes`]), each
/// reused once only this pool holds it (a server let go of it): a world of
/// megabytes written into fresh memory at every update pays a page fault
/// per 4 KiB page.
#[derive(Clone, Default)]
struct Buffers(Arc<Mutex<Vec<Arc<Vec<u8>>>>>);

/// Worlds [`Buffers`] keeps: the one a server sends, the one it replaces,
/// one more.
const KEPT_WORLDS: usize = 3;

impl Buffers {
    /// An empty buffer, with the memory of a world nobody else holds when
    /// there is one.
    fn take(&self) -> Vec<u8> {
        let mut held = self.0.lock().unwrap_or_else(|e| e.into_inner());
        // Only this pool can hand out a world it holds: one it alone holds
        // stays so.
        if let Some(i) = held.iter().position(|b| Arc::strong_count(b) == 1) {
            if let Ok(mut v) = Arc::try_unwrap(held.swap_remove(i)) {
                v.clear();
                return v;
            }
        }
        Vec::new()
    }

    /// Keeps `world` for reuse; the oldest beyond [`KEPT_WORLDS`] is let go.
    fn keep(&self, world: &Arc<Vec<u8>>) {
        let mut held = self.0.lock().unwrap_or_else(|e| e.into_inner());
        held.push(world.clone());
        if held.len() > KEPT_WORLDS {
            held.remove(0);
        }
    }
}

/// The world of a session as it stands ([`SessionWorld::build`]): what
/// `world.mcap` holds, ready to be sent ([`LiveWorld::bytes`]) and written
/// ([`LiveWorld::write_into`]).
pub struct LiveWorld<'a> {
    points: &'a [f32],
    colors: Option<&'a [u8]>,
    t_world_slam: Sim3,
    slam: Trajectory,
    reference: Option<Trajectory>,
    frames: Vec<(&'static str, Sim3)>,
    stamp: f64,
    leaves: Vec<([f64; 3], f64)>,
    grid: Option<(Grid2d, f64)>,
    grid_channels: Vec<GridChannel>,
    state: Vec<u8>,
    flavor: WorldFlavor,
    buffers: Buffers,
}

impl SessionWorld {
    /// The world of a session whose points pass `filter` (the session's
    /// own), with at most `max_points` cloud points
    /// ([`crate::defaults::LIVE_MAX_POINTS`] by default; at most
    /// [`crate::defaults::LIVE_KEYFRAME_POINTS`] of one keyframe), the 2-D
    /// grid `grid` when given, in the schemas of `flavor`.
    pub fn new(
        filter: PointFilter,
        max_points: usize,
        grid: Option<GridParams>,
        flavor: WorldFlavor,
    ) -> Self {
        SessionWorld {
            cloud: LiveCloud::new(
                filter,
                crate::defaults::LIVE_KEYFRAME_POINTS.min(max_points),
                max_points,
            ),
            grid,
            flavor,
            buffers: Buffers::default(),
        }
    }

    /// The world of `session` as it stands, with `state` (the report's
    /// JSON bytes) on the state channel; `None` before the transform (there
    /// is no world yet).
    pub fn build(&mut self, session: &Session, state: Vec<u8>) -> Result<Option<LiveWorld<'_>>> {
        let (Some(map), Ok(t)) = (session.map(), session.transform()) else {
            return Ok(None);
        };
        let grid = match &self.grid {
            Some(p) => {
                let g = map.grid_of(p)?;
                (!g.is_empty()).then_some((g, p.occupied_threshold))
            }
            None => None,
        };
        let stamp = session.state().time.max(0.0);
        let grid_channels = match &grid {
            Some((g, _)) => grid_channels(g, stamp, "world", self.flavor)?,
            None => Vec::new(),
        };
        let (points, colors) = self.cloud.update(session.keyframes(), &t.transform)?;
        let reference = session.reference_path(crate::defaults::LIVE_PATH_POSES)?;
        let frames = latest_frames(&t.transform, session, reference.as_ref());
        let slam = thin(keyframe_path(session)?)?.transformed(&t.transform);
        Ok(Some(LiveWorld {
            points,
            colors,
            t_world_slam: t.transform,
            slam,
            reference,
            frames,
            stamp,
            leaves: map.leaves(VoxelState::Occupied),
            grid,
            grid_channels,
            state,
            flavor: self.flavor,
            buffers: self.buffers.clone(),
        }))
    }
}

impl LiveWorld<'_> {
    fn scene(&self) -> WorldScene<'_> {
        WorldScene {
            cloud: CloudRef::Memory(self.points, self.colors),
            t_world_slam: self.t_world_slam,
            slam_trajectory: Some(&self.slam),
            reference: self.reference.as_ref().map(TrajectoryRef::Memory),
            stamp: self.stamp,
            world_frame: "world",
            slam_frame: "slam",
            frames: &self.frames,
        }
    }

    fn extra(&self) -> Vec<ExtraChannel<'_>> {
        let mut extra: Vec<ExtraChannel<'_>> = self
            .grid_channels
            .iter()
            .map(GridChannel::as_extra)
            .collect();
        extra.push(ExtraChannel {
            topic: topics::STATE,
            schema: ("slam2world.FollowReport", "jsonschema", state_schema()),
            message_encoding: "json",
            data: &self.state,
        });
        extra
    }

    /// `world.mcap` in memory, its chunks stored (what goes to a live
    /// server, and the file while the run goes on), in the memory of a
    /// world sent before that nobody holds any more.
    pub fn bytes(&self) -> Result<Arc<Vec<u8>>> {
        let bytes = Arc::new(world_mcap_bytes(
            Path::new(WORLD_MCAP),
            &self.scene(),
            Some(&self.leaves),
            &self.extra(),
            self.flavor,
            self.buffers.take(),
        )?);
        self.buffers.keep(&bytes);
        Ok(bytes)
    }

    /// Writes `world.mcap` to `path`, one output of `set` (published when
    /// the set is committed), its chunks zstd-compressed with `compress`,
    /// else stored (what a world written again at every update wants: zstd
    /// took a third of a full-size `follow`).
    pub fn write_into(&self, set: &mut OutputSet, path: &Path, compress: bool) -> Result<()> {
        write_world_mcap_extra_into(
            set,
            path,
            &self.scene(),
            Some(&self.leaves),
            &self.extra(),
            self.flavor,
            compress,
        )
    }

    /// The 2-D grid and its occupied threshold, when one was asked for and
    /// the map has voxels in its band (nav2's files are made from it).
    pub fn grid(&self) -> Option<&(Grid2d, f64)> {
        self.grid.as_ref()
    }
}

impl FollowReport {
    /// Brings the report up to `session` after keyframe `id` (-1: the end).
    pub fn update(
        &mut self,
        session: &Session,
        id: i32,
        decode_s: f64,
        t: &UpdateTiming,
        latency: f64,
    ) {
        let s = session.state();
        self.stage = s.stage.name().into();
        self.reason = s.reason.clone();
        self.time = s.time;
        self.last_keyframe = id;
        self.keyframes = s.keyframes;
        self.frames = s.frames;
        self.points = s.points;
        self.rebuilds = s.rebuilds;
        self.stable_time = s.stable_time;
        self.stable_reported_at = s.stable_reported_at;
        self.enu_origin = s.enu_origin.map(|g| [g.lat, g.lon, g.alt]);
        self.fixes = s.fixes;
        self.fixes_dropped = s.fixes_dropped;
        match session.transform() {
            Ok(tr) => {
                self.t_world_slam = Some(TransformReport::from(&tr.transform));
                self.fit_rmse = Some(tr.rmse);
                self.pairs_fitted = tr.pairs;
            }
            Err(_) => {
                self.t_world_slam = None;
                self.fit_rmse = None;
                self.pairs_fitted = 0;
            }
        }
        self.decode_s = decode_s;
        self.fit_s = t.fit_s;
        self.backproject_s = t.backproject_s;
        self.insert_s = t.insert_s;
        self.latency_s = latency;
    }
}

/// The frames under the world besides `slam`: `camera`, the latest keyframe
/// (`T_world_slam · T_slam_cam`), and `body`, the latest reference pose
/// when it has an orientation (a 3-D panel can follow either).
fn latest_frames(
    t_world_slam: &Sim3,
    session: &Session,
    reference: Option<&Trajectory>,
) -> Vec<(&'static str, Sim3)> {
    let mut frames = Vec::new();
    if let Some(kf) = session
        .keyframes()
        .max_by(|a, b| a.timestamp.total_cmp(&b.timestamp))
    {
        frames.push(("camera", *t_world_slam * kf.pose));
    }
    if let Some(r) = reference {
        if let (Some(p), Some(q)) = (
            r.positions.last(),
            r.orientations.as_ref().and_then(|o| o.last()),
        ) {
            frames.push((
                "body",
                Sim3 {
                    rotation: *q,
                    translation: *p,
                    scale: 1.0,
                },
            ));
        }
    }
    frames
}

/// The JSON Schema of the state channel's messages (`report.json`'s).
fn state_schema() -> &'static [u8] {
    static SCHEMA: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    SCHEMA.get_or_init(|| {
        serde_json::to_vec(&schemars::schema_for!(FollowReport)).unwrap_or_default()
    })
}

/// The session's keyframe poses (SLAM frame), in time order.
fn keyframe_path(session: &Session) -> Result<Trajectory> {
    let mut kfs: Vec<&crate::keyframe::Keyframe> = session.keyframes().collect();
    kfs.sort_by(|a, b| a.timestamp.total_cmp(&b.timestamp));
    Trajectory::try_new(
        kfs.iter().map(|k| k.timestamp).collect(),
        kfs.iter().map(|k| k.pose.translation).collect(),
        Some(kfs.iter().map(|k| k.pose.rotation).collect()),
    )
}

/// `t` with at most [`crate::defaults::LIVE_PATH_POSES`] poses, evenly
/// spread (the first and the last kept): a path drawn in a viewer needs no
/// more.
fn thin(t: Trajectory) -> Result<Trajectory> {
    let idx = crate::trajectory::even_indices(t.len(), crate::defaults::LIVE_PATH_POSES);
    if idx.len() == t.len() {
        return Ok(t);
    }
    Trajectory::try_new(
        idx.iter().map(|&i| t.timestamps[i]).collect(),
        idx.iter().map(|&i| t.positions[i]).collect(),
        t.orientations
            .as_ref()
            .map(|o| idx.iter().map(|&i| o[i]).collect()),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn thin_keeps_the_ends_and_the_bound() {
        let n = 3 * crate::defaults::LIVE_PATH_POSES + 7;
        let t = Trajectory::try_new(
            (0..n).map(|i| i as f64).collect(),
            (0..n).map(|i| Vector3::new(i as f64, 0.0, 0.0)).collect(),
            None,
        )
        .unwrap();
        let s = thin(t).unwrap();
        assert_eq!(s.len(), crate::defaults::LIVE_PATH_POSES);
        assert_eq!(s.timestamps[0], 0.0);
        assert_eq!(*s.timestamps.last().unwrap(), (n - 1) as f64);
        assert!(s.timestamps.windows(2).all(|w| w[1] > w[0]));
        let short = Trajectory::try_new(vec![0.0, 1.0], vec![Vector3::zeros(); 2], None).unwrap();
        assert_eq!(thin(short).unwrap().len(), 2);
    }
}
