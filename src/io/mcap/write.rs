//! MCAP writing: the world output that Foxglove (or RViz 2) shows, and the
//! SLAM-side log a LSD-SLAM user records (used by the simulation to produce
//! test logs). Files are written to a temporary name beside the destination
//! and renamed when complete.

use std::collections::BTreeMap;
use std::io::{BufWriter, Seek, Write};
use std::path::Path;

use super::piecewise::{Channel, PiecewiseWriter};
use super::schemas;
use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::imu::ImuSamples;
use crate::io::atomic::OutputSet;
use crate::io::messages::wire::PbWriter;
use crate::io::spill::{CloudRef, TrajectoryRef};
use crate::keyframe::Keyframe;
use crate::trajectory::Trajectory;

/// Which message set the world output uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WorldFlavor {
    /// `foxglove.PointCloud`, `foxglove.PosesInFrame`, `foxglove.FrameTransform` (protobuf).
    #[default]
    Foxglove,
    /// `sensor_msgs/msg/PointCloud2` and `tf2_msgs/msg/TFMessage` (ROS 2 CDR), for RViz 2.
    Ros2,
}

/// What goes into `world.mcap`. Everything is in the world frame (metres)
/// except `t_world_slam`, which maps the SLAM frame into it.
#[derive(Clone, Debug)]
pub struct WorldScene<'a> {
    /// The points (world frame, metres) and their RGB colours (or none:
    /// written white), in memory or on disk. A cloud of more than
    /// [`CLOUD_MESSAGE_POINTS`] points is written as consecutive messages of
    /// that many points (the last one fewer), all at the one stamp.
    pub cloud: CloudRef<'a>,
    /// `T_world_slam`; the transform messages carry its rotation and translation
    /// (a transform message has no scale; the points are already scaled).
    pub t_world_slam: Sim3,
    /// The SLAM trajectory mapped into the world frame.
    pub slam_trajectory: Option<&'a Trajectory>,
    /// The reference trajectory (world frame), in memory or on disk.
    pub reference: Option<TrajectoryRef<'a>>,
    /// Stamp of the cloud and transform messages, seconds.
    pub stamp: f64,
    /// Frame name of the world (`world` by default in the CLI).
    pub world_frame: &'a str,
    /// Frame name of the SLAM map (`slam`).
    pub slam_frame: &'a str,
    /// More frames under the world, each one more `/tf` message after
    /// `world → slam` (`follow`'s `camera`, the latest keyframe, and `body`,
    /// the latest reference pose); their scale is not written.
    pub frames: &'a [(&'a str, Sim3)],
}

/// The most points one cloud message of `world.mcap` holds (64 MiB of
/// Foxglove points): a larger cloud is split into several, so that a viewer,
/// which loads a message whole, never needs more than that at once. The
/// writer itself holds none of them whole: each goes from the cloud (in
/// memory or on disk) into the file a piece at a time
/// ([`super::piecewise::PiecewiseWriter`]).
pub const CLOUD_MESSAGE_POINTS: usize = 1 << 22;

/// Topic names of the world output.
pub mod topics {
    /// The world point cloud.
    pub const CLOUD: &str = "/world/cloud";
    /// The SLAM trajectory in the world frame.
    pub const SLAM_TRAJECTORY: &str = "/world/slam_trajectory";
    /// The reference trajectory.
    pub const REFERENCE: &str = "/world/reference";
    /// `world → slam` transform.
    pub const TF: &str = "/tf";
    /// The online session's state (`follow`: its `report.json` as a JSON
    /// message, stage, transform, fit and timing).
    pub const STATE: &str = "/slam2world/state";
    /// The occupied voxels of the occupancy map (`foxglove.SceneUpdate` cubes,
    /// or a `PointCloud2` of leaf centres in the ROS 2 flavour).
    pub const OCTOMAP: &str = "/slam2world/octomap";
}

/// Entity id of the occupancy map in its `foxglove.SceneUpdate`.
pub const OCTOMAP_ENTITY_ID: &str = "octomap";

fn mcap_err(path: &Path, what: &str, e: impl std::fmt::Display) -> Error {
    Error::Mcap {
        path: path.to_path_buf(),
        reason: format!("{what}: {e}"),
    }
}

/// An error of the `mcap` writer: its I/O errors (disk full, file size
/// limit) are file errors naming the output, the rest format errors.
fn write_err(path: &Path, what: &str, e: mcap::McapError) -> Error {
    match e {
        mcap::McapError::Io(io) => Error::io(path, io),
        other => mcap_err(path, what, other),
    }
}

fn nanos(path: &Path, what: &str, t: f64) -> Result<u64> {
    if !(0.0..=1.8e10).contains(&t) {
        return Err(mcap_err(
            path,
            what,
            format!(
                "time {} s cannot be an MCAP log time (0 ≤ t < 1.8e10 s)",
                crate::error::num(t)
            ),
        ));
    }
    Ok((t * 1e9).round() as u64)
}

/// Writes an MCAP as one output of `set` (a temporary file beside `path`,
/// renamed when the set is committed).
fn write_atomic(
    set: &mut OutputSet,
    path: &Path,
    options: mcap::WriteOptions,
    body: impl FnOnce(&mut mcap::Writer<BufWriter<&std::fs::File>>) -> Result<()>,
) -> Result<()> {
    set.write(path, |file| {
        let mut w = options
            .create(BufWriter::new(file))
            .map_err(|e| write_err(path, "create", e))?;
        body(&mut w)?;
        w.finish().map_err(|e| write_err(path, "finish", e))?;
        let mut inner = w.into_inner();
        inner.flush().map_err(|e| Error::io(path, e))
    })
}

struct Chan {
    id: u16,
    seq: u32,
}

fn add_channel(
    w: &mut mcap::Writer<BufWriter<&std::fs::File>>,
    path: &Path,
    topic: &str,
    schema: (&str, &str, &[u8]),
    message_encoding: &str,
) -> Result<Chan> {
    let sid = w
        .add_schema(schema.0, schema.1, schema.2)
        .map_err(|e| write_err(path, topic, e))?;
    let id = w
        .add_channel(sid, topic, message_encoding, &BTreeMap::new())
        .map_err(|e| write_err(path, topic, e))?;
    Ok(Chan { id, seq: 0 })
}

fn put(
    w: &mut mcap::Writer<BufWriter<&std::fs::File>>,
    path: &Path,
    ch: &mut Chan,
    t: u64,
    data: &[u8],
) -> Result<()> {
    let header = mcap::records::MessageHeader {
        channel_id: ch.id,
        sequence: ch.seq,
        log_time: t,
        publish_time: t,
    };
    ch.seq = ch.seq.wrapping_add(1);
    crate::interrupt::check()?;
    w.write_to_known_channel(&header, data)
        .map_err(|e| write_err(path, "write message", e))
}

fn pb_time(t: f64) -> PbWriter {
    let mut m = PbWriter::new();
    let sec = t.floor();
    m.int(1, sec as i64);
    m.int(2, ((t - sec) * 1e9).round().min(999_999_999.0) as i64);
    m
}

fn pb_vec3(v: [f64; 3]) -> PbWriter {
    let mut m = PbWriter::new();
    for (i, x) in v.iter().enumerate() {
        m.double(i as u32 + 1, *x);
    }
    m
}

fn pb_quat(q: [f64; 4]) -> PbWriter {
    let mut m = PbWriter::new();
    for (i, x) in q.iter().enumerate() {
        m.double(i as u32 + 1, *x);
    }
    m
}

fn pb_pose(p: [f64; 3], q: [f64; 4]) -> PbWriter {
    let mut m = PbWriter::new();
    m.message(1, &pb_vec3(p));
    m.message(2, &pb_quat(q));
    m
}

/// Foxglove `PackedElementField.NumericType` ids (not ROS PointField's).
const FOXGLOVE_UINT8: i64 = 1;
const FOXGLOVE_FLOAT32: i64 = 7;

/// Appends points and colours as `x, y, z: f32` + `r, g, b, a: u8` (16 bytes
/// a point, white without colours).
fn pack_foxglove(data: &mut Vec<u8>, points: &[f32], colors: Option<&[u8]>) {
    pack16(data, points, colors, |c| [c[0], c[1], c[2], 255], [255; 4]);
}

/// Appends points and colours as `x, y, z: f32` + PCL's packed float `rgb`
/// (the bytes b, g, r, 0 of a little-endian u32; white without colours).
fn pack_pcl(data: &mut Vec<u8>, points: &[f32], colors: Option<&[u8]>) {
    pack16(
        data,
        points,
        colors,
        |c| [c[2], c[1], c[0], 0],
        [255, 255, 255, 0],
    );
}

/// Appends 16 bytes a point: `x, y, z` as little-endian `f32`, then the
/// four bytes `color` makes of its colour (`white` without colours).
#[inline(always)]
fn pack16(
    data: &mut Vec<u8>,
    points: &[f32],
    colors: Option<&[u8]>,
    color: impl Fn(&[u8]) -> [u8; 4],
    white: [u8; 4],
) {
    let n = points.len() / 3;
    let start = data.len();
    data.resize(start + 16 * n, 0);
    let out = data[start..]
        .chunks_exact_mut(16)
        .zip(points.chunks_exact(3));
    let xyz = |o: &mut [u8], p: &[f32]| {
        o[0..4].copy_from_slice(&p[0].to_le_bytes());
        o[4..8].copy_from_slice(&p[1].to_le_bytes());
        o[8..12].copy_from_slice(&p[2].to_le_bytes());
    };
    match colors {
        Some(c) => {
            for ((o, p), c) in out.zip(c.chunks_exact(3)) {
                xyz(o, p);
                o[12..16].copy_from_slice(&color(c));
            }
        }
        None => {
            for (o, p) in out {
                xyz(o, p);
                o[12..16].copy_from_slice(&white);
            }
        }
    }
}

/// Fills a cloud message's point data in place: `pieces(f)` hands `f` the
/// message's points, a piece at a time.
/// One piece of a cloud message's points: coordinates and colours.
type Piece<'f> = &'f mut dyn FnMut(&[f32], Option<&[u8]>);
type Pieces<'p> = &'p mut dyn FnMut(Piece<'_>) -> Result<()>;

/// The `foxglove.PointCloud` message of `points` (world frame, stride 16).
pub fn foxglove_point_cloud(
    stamp: f64,
    frame: &str,
    points: &[f32],
    colors: Option<&[u8]>,
) -> Vec<u8> {
    let msg = CloudMessage::foxglove(stamp, frame, points.len() / 3);
    msg.in_memory(points, colors)
}

/// A cloud message of `n` points in its parts: the bytes before the points,
/// their packing (16 bytes a point), the bytes after; written a piece of the
/// cloud at a time ([`CloudMessage::write`]) or whole in memory.
struct CloudMessage {
    head: Vec<u8>,
    n: usize,
    pack: fn(&mut Vec<u8>, &[f32], Option<&[u8]>),
    tail: Vec<u8>,
}

impl CloudMessage {
    /// `foxglove.PointCloud`: the points are the last field, `data`.
    fn foxglove(stamp: f64, frame: &str, n: usize) -> Self {
        let mut m = PbWriter::new();
        m.message(1, &pb_time(stamp));
        m.bytes(2, frame.as_bytes());
        m.message(3, &pb_pose([0.0; 3], [0.0, 0.0, 0.0, 1.0]));
        m.fixed32(4, 16);
        for (name, offset, ty) in [
            ("x", 0u32, FOXGLOVE_FLOAT32),
            ("y", 4, FOXGLOVE_FLOAT32),
            ("z", 8, FOXGLOVE_FLOAT32),
            ("red", 12, FOXGLOVE_UINT8),
            ("green", 13, FOXGLOVE_UINT8),
            ("blue", 14, FOXGLOVE_UINT8),
            ("alpha", 15, FOXGLOVE_UINT8),
        ] {
            let mut f = PbWriter::new();
            f.bytes(1, name.as_bytes());
            f.fixed32(2, offset);
            f.int(3, ty);
            m.message(5, &f);
        }
        m.bytes_head(6, 16 * n);
        CloudMessage {
            head: m.buf,
            n,
            pack: pack_foxglove,
            tail: Vec::new(),
        }
    }

    /// `sensor_msgs/PointCloud2` (CDR): `is_dense` after the points.
    fn ros2(stamp: f64, frame: &str, n: usize) -> Self {
        let mut w = CdrWriter::new();
        w.header(stamp, frame);
        w.u32(1); // height
        w.u32(n as u32); // width
        w.u32(4);
        for (name, offset) in [("x", 0u32), ("y", 4), ("z", 8), ("rgb", 12)] {
            w.string(name);
            w.u32(offset);
            w.u8(7); // PointField.FLOAT32
            w.u32(1);
        }
        w.u8(0); // is_bigendian
        w.u32(16);
        w.u32(16 * n as u32);
        w.u32(16 * n as u32);
        CloudMessage {
            head: w.buf,
            n,
            pack: pack_pcl,
            tail: vec![1], // is_dense
        }
    }

    /// The message's length in bytes.
    fn len(&self) -> usize {
        self.head.len() + 16 * self.n + self.tail.len()
    }

    /// Writes the message to `out`, its points packed a piece at a time as
    /// `pieces` gives them; an error when they are not the `n` points
    /// declared (a cloud that changed while it was written).
    fn write(&self, out: &mut dyn Write, pieces: Pieces<'_>, path: &Path) -> Result<()> {
        let io = |e| Error::io(path, e);
        out.write_all(&self.head).map_err(io)?;
        let mut buf = Vec::new();
        let mut got = 0;
        let mut failed = None;
        pieces(&mut |p, c| {
            if failed.is_some() {
                return;
            }
            buf.clear();
            (self.pack)(&mut buf, p, c);
            got += buf.len();
            if let Err(e) = out.write_all(&buf) {
                failed = Some(e);
            }
        })?;
        if let Some(e) = failed {
            return Err(io(e));
        }
        check_filled(16 * self.n, got)?;
        out.write_all(&self.tail).map_err(io)
    }

    /// The whole message of `points` in memory.
    fn in_memory(&self, points: &[f32], colors: Option<&[u8]>) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.len());
        out.extend_from_slice(&self.head);
        (self.pack)(&mut out, points, colors);
        out.extend_from_slice(&self.tail);
        out
    }
}

/// A cloud message whose point data came out at another length than it
/// declared (a cloud that changed while it was written).
fn check_filled(declared: usize, got: usize) -> Result<()> {
    if declared == got {
        return Ok(());
    }
    Err(Error::invalid(
        "cloud",
        format!("a cloud message declared {declared} bytes of points and got {got}"),
    ))
}

/// `foxglove.PosesInFrame` of a trajectory, written a pose at a time (a
/// reference of hours at 200 Hz is a message of hundreds of MB, never whole
/// in memory). Every pose field is the same number of bytes (fixed-width
/// doubles), so the length is known before the message is written.
struct PosesMessage<'t> {
    head: Vec<u8>,
    traj: TrajectoryRef<'t>,
}

impl<'t> PosesMessage<'t> {
    fn new(stamp: f64, frame: &str, traj: TrajectoryRef<'t>) -> Self {
        let mut m = PbWriter::new();
        m.message(1, &pb_time(stamp));
        m.bytes(2, frame.as_bytes());
        PosesMessage { head: m.buf, traj }
    }

    /// Field 3 (a pose) of `p` and `q` (xyzw) into `m`, cleared first.
    fn pose_field(m: &mut PbWriter, p: [f64; 3], q: [f64; 4]) {
        m.buf.clear();
        m.message(3, &pb_pose(p, q));
    }

    fn len(&self) -> u64 {
        let mut m = PbWriter::new();
        Self::pose_field(&mut m, [0.0; 3], [0.0; 4]);
        (self.head.len() + self.traj.len() * m.buf.len()) as u64
    }

    /// The message into `out` (`path` names the file in an error), the
    /// trajectory read a piece at a time.
    fn write(&self, out: &mut dyn Write, path: &Path) -> Result<()> {
        let io = |e| Error::io(path, e);
        out.write_all(&self.head).map_err(io)?;
        let mut m = PbWriter::new();
        self.traj
            .for_each_piece(1 << 14, |_, _, positions, orientations| {
                for (i, p) in positions.iter().enumerate() {
                    let q = match orientations {
                        Some(o) => {
                            let c = o[i].coords;
                            [c[0], c[1], c[2], c[3]]
                        }
                        None => [0.0, 0.0, 0.0, 1.0],
                    };
                    Self::pose_field(&mut m, [p.x, p.y, p.z], q);
                    out.write_all(&m.buf).map_err(io)?;
                }
                Ok(())
            })
    }
}

fn foxglove_frame_transform(stamp: f64, parent: &str, child: &str, t: &Sim3) -> Vec<u8> {
    let mut m = PbWriter::new();
    m.message(1, &pb_time(stamp));
    m.bytes(2, parent.as_bytes());
    m.bytes(3, child.as_bytes());
    m.message(
        4,
        &pb_vec3([t.translation.x, t.translation.y, t.translation.z]),
    );
    m.message(5, &pb_quat(t.quaternion_xyzw()));
    m.buf
}

/// A little-endian CDR writer (XCDR1): alignment relative to the end of the header.
struct CdrWriter {
    buf: Vec<u8>,
}

impl CdrWriter {
    fn new() -> Self {
        CdrWriter {
            buf: vec![0, 1, 0, 0],
        }
    }
    fn align(&mut self, n: usize) {
        while (self.buf.len() - 4) % n != 0 {
            self.buf.push(0);
        }
    }
    fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }
    fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }
    fn header(&mut self, t: f64, frame: &str) {
        let sec = t.floor();
        self.i32(sec as i32);
        self.u32(((t - sec) * 1e9).round().min(999_999_999.0) as u32);
        self.string(frame);
    }
}

fn ros2_point_cloud(stamp: f64, frame: &str, points: &[f32], colors: Option<&[u8]>) -> Vec<u8> {
    CloudMessage::ros2(stamp, frame, points.len() / 3).in_memory(points, colors)
}

fn ros2_tf(stamp: f64, parent: &str, child: &str, t: &Sim3) -> Vec<u8> {
    let mut w = CdrWriter::new();
    w.u32(1);
    w.header(stamp, parent);
    w.string(child);
    for v in [t.translation.x, t.translation.y, t.translation.z] {
        w.f64(v);
    }
    for v in t.quaternion_xyzw() {
        w.f64(v);
    }
    w.buf
}

/// Colour of a voxel at height `z` (metres) in `[z_min, z_max]`: a rainbow from
/// blue (low) through green to red (high), as OctoMap's viewers colour by
/// height. Returns `(r, g, b)` in `[0, 1]`; a flat range gives the middle colour.
pub fn height_color(z: f64, z_min: f64, z_max: f64) -> [f64; 3] {
    let span = z_max - z_min;
    let t = if span > 0.0 && span.is_finite() {
        ((z - z_min) / span).clamp(0.0, 1.0)
    } else {
        0.5
    };
    // Hue from 240° (blue) down to 0° (red), full saturation and value.
    let h = (1.0 - t) * 4.0;
    let x = 1.0 - (h % 2.0 - 1.0).abs();
    match h {
        h if h < 1.0 => [1.0, x, 0.0],
        h if h < 2.0 => [x, 1.0, 0.0],
        h if h < 3.0 => [0.0, 1.0, x],
        _ => [0.0, x, 1.0],
    }
}

fn height_range(leaves: &[([f64; 3], f64)]) -> (f64, f64) {
    leaves
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (c, _)| {
            (lo.min(c[2]), hi.max(c[2]))
        })
}

/// The `foxglove.SceneUpdate` of occupied voxels: one entity
/// ([`OCTOMAP_ENTITY_ID`], frame `frame`) holding one `CubePrimitive` per leaf
/// `(centre, edge length)` (metres, in `frame`), axis-aligned, opaque,
/// coloured by height ([`height_color`] over the leaves' height range).
pub fn foxglove_scene_update_cubes(stamp: f64, frame: &str, leaves: &[([f64; 3], f64)]) -> Vec<u8> {
    let (z_min, z_max) = height_range(leaves);
    let mut entity = PbWriter::new();
    entity.message(1, &pb_time(stamp));
    entity.bytes(2, frame.as_bytes());
    entity.bytes(3, OCTOMAP_ENTITY_ID.as_bytes());
    entity.buf.reserve(140 * leaves.len());
    let mut cube = PbWriter::new();
    for (c, size) in leaves {
        cube.buf.clear();
        cube.message(1, &pb_pose(*c, [0.0, 0.0, 0.0, 1.0]));
        cube.message(2, &pb_vec3([*size; 3]));
        let rgb = height_color(c[2], z_min, z_max);
        cube.message(3, &pb_quat([rgb[0], rgb[1], rgb[2], 1.0]));
        entity.message(8, &cube);
    }
    let mut m = PbWriter::new();
    m.message(2, &entity);
    m.buf
}

/// Leaf centres as `f32` points and their height colours as RGB bytes.
fn leaf_centers_colored(leaves: &[([f64; 3], f64)]) -> (Vec<f32>, Vec<u8>) {
    let (z_min, z_max) = height_range(leaves);
    let mut pts = Vec::with_capacity(3 * leaves.len());
    let mut cols = Vec::with_capacity(3 * leaves.len());
    for (c, _) in leaves {
        pts.extend(c.iter().map(|&v| v as f32));
        cols.extend(
            height_color(c[2], z_min, z_max)
                .iter()
                .map(|&v| (v * 255.0).round() as u8),
        );
    }
    (pts, cols)
}

/// [`write_world_mcap`] plus, with `octomap = Some(leaves)`, the occupied
/// voxels of an occupancy map on [`topics::OCTOMAP`]: leaves as
/// `(centre, edge length)` in the world frame (metres). Foxglove flavour: one
/// `foxglove.SceneUpdate` of cube primitives; ROS 2 flavour: a
/// `sensor_msgs/msg/PointCloud2` of the leaf centres (coloured by height).
pub fn write_world_mcap_with_octomap(
    path: impl AsRef<Path>,
    scene: &WorldScene<'_>,
    octomap: Option<&[([f64; 3], f64)]>,
    flavor: WorldFlavor,
) -> Result<()> {
    let mut set = OutputSet::new();
    write_world_mcap_into(&mut set, path.as_ref(), scene, octomap, flavor)?;
    set.commit().map(|_| ())
}

/// [`write_world_mcap_with_octomap`] as one output of `set` (published when
/// the set is committed).
pub fn write_world_mcap_into(
    set: &mut OutputSet,
    path: &Path,
    scene: &WorldScene<'_>,
    octomap: Option<&[([f64; 3], f64)]>,
    flavor: WorldFlavor,
) -> Result<()> {
    write_world_mcap_extra_into(set, path, scene, octomap, &[], flavor, true)
}

/// One more channel of `world.mcap` with its one message, stamped with the
/// scene's stamp (the 2-D grid: `grid_msgs::grid_channels`).
#[derive(Clone, Copy, Debug)]
pub struct ExtraChannel<'a> {
    /// Topic.
    pub topic: &'a str,
    /// Schema record: `(name, encoding, data)`.
    pub schema: (&'a str, &'a str, &'a [u8]),
    /// Message encoding of the channel (`protobuf`, `cdr`).
    pub message_encoding: &'a str,
    /// The encoded message.
    pub data: &'a [u8],
}

/// [`write_world_mcap_into`] with `extra` channels after the scene's own;
/// `compress: false` stores the chunks uncompressed (a live world written
/// again at every update: zstd would cost more than the write, and the
/// server reading it again would pay to decompress).
pub fn write_world_mcap_extra_into(
    set: &mut OutputSet,
    path: &Path,
    scene: &WorldScene<'_>,
    octomap: Option<&[([f64; 3], f64)]>,
    extra: &[ExtraChannel<'_>],
    flavor: WorldFlavor,
    compress: bool,
) -> Result<()> {
    if let Some(leaves) = octomap {
        if let Some(i) = leaves
            .iter()
            .position(|(c, s)| !(c.iter().all(|v| v.is_finite()) && s.is_finite() && *s > 0.0))
        {
            return Err(Error::invalid(
                "octomap",
                format!("leaf {i} has a non-finite centre or a non-positive size"),
            ));
        }
    }
    write_world_impl(set, path, scene, octomap, extra, flavor, compress)
}

/// Writes the world output: the cloud, the trajectories and `world → slam`.
pub fn write_world_mcap(
    path: impl AsRef<Path>,
    scene: &WorldScene<'_>,
    flavor: WorldFlavor,
) -> Result<()> {
    let mut set = OutputSet::new();
    write_world_impl(&mut set, path.as_ref(), scene, None, &[], flavor, true)?;
    set.commit().map(|_| ())
}

/// Points per piece read from a cloud on disk into a cloud message (about
/// 1 MiB packed).
const MESSAGE_PIECE: usize = 1 << 16;

/// Calls `f` with each cloud message's point count and a filler of its
/// points: messages of at most [`CLOUD_MESSAGE_POINTS`], one empty message
/// for an empty cloud; a cloud on disk is read a piece at a time straight
/// into the message.
fn cloud_messages(
    cloud: CloudRef<'_>,
    per_message: usize,
    mut f: impl FnMut(usize, Pieces<'_>) -> Result<()>,
) -> Result<()> {
    let n = cloud.len();
    let per_message = per_message.max(1);
    let mut start = 0;
    loop {
        let len = per_message.min(n - start);
        let mut pieces = |g: Piece<'_>| {
            cloud.for_each_piece_in(start, len, MESSAGE_PIECE, |p, c| {
                g(p, c);
                Ok(())
            })
        };
        f(len, &mut pieces)?;
        start += len;
        if start >= n {
            return Ok(());
        }
    }
}

fn write_world_impl(
    set: &mut OutputSet,
    path: &Path,
    scene: &WorldScene<'_>,
    octomap: Option<&[([f64; 3], f64)]>,
    extra: &[ExtraChannel<'_>],
    flavor: WorldFlavor,
    compress: bool,
) -> Result<()> {
    set.write(path, |file| {
        let w = write_world_to(
            BufWriter::new(file),
            path,
            scene,
            octomap,
            extra,
            flavor,
            compress,
        )?;
        w.into_inner()
            .map_err(|e| Error::io(path, e.into_error()))
            .map(|_| ())
    })
}

/// The `world.mcap` of [`write_world_mcap_extra_into`] in memory, its
/// chunks stored uncompressed (what a live world sends as it is written: a
/// file of it is these bytes), written into `buf` (cleared first: its
/// memory is reused). `name` stands for the file in errors.
pub fn world_mcap_bytes(
    name: &Path,
    scene: &WorldScene<'_>,
    octomap: Option<&[([f64; 3], f64)]>,
    extra: &[ExtraChannel<'_>],
    flavor: WorldFlavor,
    mut buf: Vec<u8>,
) -> Result<Vec<u8>> {
    buf.clear();
    // The cloud's bytes and a little more: one allocation at most.
    let cloud_bytes = 16 * scene.cloud.len() + octomap.map_or(0, |l| 64 * l.len());
    buf.reserve(cloud_bytes + (1 << 20));
    let w = write_world_to(
        std::io::Cursor::new(buf),
        name,
        scene,
        octomap,
        extra,
        flavor,
        false,
    )?;
    Ok(w.into_inner())
}

/// Writes the world into `out` (the file at `path`, named in errors):
/// the scene's channels, the occupied voxels, then `extra`.
fn write_world_to<W: Write + Seek>(
    out: W,
    path: &Path,
    scene: &WorldScene<'_>,
    octomap: Option<&[([f64; 3], f64)]>,
    extra: &[ExtraChannel<'_>],
    flavor: WorldFlavor,
    compress: bool,
) -> Result<W> {
    if let CloudRef::Memory(points, colors) = scene.cloud {
        crate::io::ply::check_shapes(points, colors)?;
    }
    let t = nanos(path, "stamp", scene.stamp)?;
    let profile = match flavor {
        WorldFlavor::Foxglove => "",
        WorldFlavor::Ros2 => "ros2",
    };
    // The cloud's messages go a piece at a time from the cloud into the
    // file (PiecewiseWriter): none is ever whole in memory.
    let w = PiecewiseWriter::new(
        out,
        path,
        profile,
        concat!("slam2world ", env!("CARGO_PKG_VERSION")),
    )?;
    let mut w = if compress { w } else { w.uncompressed() };
    let put = |w: &mut PiecewiseWriter<_>, ch: &mut Channel, data: &[u8]| {
        crate::interrupt::check()?;
        w.message(ch, t, data)
    };
    let clouds = |w: &mut PiecewiseWriter<_>, ch: &mut Channel, ros2: bool| {
        cloud_messages(scene.cloud, CLOUD_MESSAGE_POINTS, |n, pieces| {
            crate::interrupt::check()?;
            let msg = if ros2 {
                CloudMessage::ros2(scene.stamp, scene.world_frame, n)
            } else {
                CloudMessage::foxglove(scene.stamp, scene.world_frame, n)
            };
            w.message_with(ch, t, msg.len() as u64, |out| msg.write(out, pieces, path))
        })
    };
    match flavor {
        WorldFlavor::Foxglove => {
            let mut cloud =
                w.add_channel(topics::CLOUD, schemas::FOXGLOVE_POINT_CLOUD, "protobuf")?;
            let mut tf =
                w.add_channel(topics::TF, schemas::FOXGLOVE_FRAME_TRANSFORM, "protobuf")?;
            let msg = foxglove_frame_transform(
                scene.stamp,
                scene.world_frame,
                scene.slam_frame,
                &scene.t_world_slam,
            );
            put(&mut w, &mut tf, &msg)?;
            for (child, pose) in scene.frames {
                let msg = foxglove_frame_transform(scene.stamp, scene.world_frame, child, pose);
                put(&mut w, &mut tf, &msg)?;
            }
            clouds(&mut w, &mut cloud, false)?;
            for (topic, traj) in [
                (
                    topics::SLAM_TRAJECTORY,
                    scene.slam_trajectory.map(TrajectoryRef::Memory),
                ),
                (topics::REFERENCE, scene.reference),
            ] {
                if let Some(traj) = traj {
                    let mut ch =
                        w.add_channel(topic, schemas::FOXGLOVE_POSES_IN_FRAME, "protobuf")?;
                    let msg = PosesMessage::new(scene.stamp, scene.world_frame, traj);
                    crate::interrupt::check()?;
                    w.message_with(&mut ch, t, msg.len(), |out| msg.write(out, path))?;
                }
            }
            if let Some(leaves) = octomap {
                let mut ch =
                    w.add_channel(topics::OCTOMAP, schemas::FOXGLOVE_SCENE_UPDATE, "protobuf")?;
                let msg = foxglove_scene_update_cubes(scene.stamp, scene.world_frame, leaves);
                put(&mut w, &mut ch, &msg)?;
            }
        }
        WorldFlavor::Ros2 => {
            let mut tf = w.add_channel(topics::TF, schemas::ROS2_TF_MESSAGE, "cdr")?;
            let mut cloud = w.add_channel(topics::CLOUD, schemas::ROS2_POINT_CLOUD2, "cdr")?;
            let msg = ros2_tf(
                scene.stamp,
                scene.world_frame,
                scene.slam_frame,
                &scene.t_world_slam,
            );
            put(&mut w, &mut tf, &msg)?;
            for (child, pose) in scene.frames {
                let msg = ros2_tf(scene.stamp, scene.world_frame, child, pose);
                put(&mut w, &mut tf, &msg)?;
            }
            clouds(&mut w, &mut cloud, true)?;
            if let Some(leaves) = octomap {
                let mut ch = w.add_channel(topics::OCTOMAP, schemas::ROS2_POINT_CLOUD2, "cdr")?;
                let (pts, cols) = leaf_centers_colored(leaves);
                let msg = ros2_point_cloud(scene.stamp, scene.world_frame, &pts, Some(&cols));
                put(&mut w, &mut ch, &msg)?;
            }
        }
    }
    for x in extra {
        let mut ch = w.add_channel(x.topic, x.schema, x.message_encoding)?;
        put(&mut w, &mut ch, x.data)?;
    }
    let mut out = w.finish()?;
    out.flush().map_err(|e| Error::io(path, e))?;
    Ok(out)
}

/// Topics and options of [`write_slam_log`].
#[derive(Clone, Debug)]
pub struct SlamLogOptions {
    /// Keyframe topic (`lsd_slam_viewer/keyframeMsg`).
    pub keyframe_topic: String,
    /// Graph topic (`lsd_slam_viewer/keyframeGraphMsg`); one graph message with
    /// every keyframe's final pose is written after the last keyframe.
    pub graph_topic: Option<String>,
    /// Reference pose topic (`geometry_msgs/PoseStamped`).
    pub pose_topic: String,
    /// IMU topic (`sensor_msgs/Imu`).
    pub imu_topic: String,
    /// Frame id of the reference poses.
    pub pose_frame: String,
    /// Frame id of the IMU samples.
    pub imu_frame: String,
    /// Chunk compression.
    pub compression: Option<mcap::Compression>,
}

impl Default for SlamLogOptions {
    fn default() -> Self {
        SlamLogOptions {
            keyframe_topic: "/lsd_slam/keyframes".into(),
            graph_topic: Some("/lsd_slam/graph".into()),
            pose_topic: "/ground_truth/pose".into(),
            imu_topic: "/imu0".into(),
            pose_frame: "world".into(),
            imu_frame: "imu".into(),
            compression: Some(mcap::Compression::Zstd),
        }
    }
}

/// The ROS 1 `keyframeMsg` of a keyframe (colour 4th byte 255; variance 0 when absent).
pub fn keyframe_msg_ros1(kf: &Keyframe) -> Vec<u8> {
    keyframe_msg_ros1_at(kf, &kf.pose)
}

/// The ROS 1 `keyframeMsg` of a live frame as LSD-SLAM publishes it:
/// `isKeyframe = false`, the tracked `camToWorld`, the camera, no point cloud.
pub fn live_frame_msg_ros1(
    id: i32,
    time: f64,
    pose: &Sim3,
    camera: &crate::geometry::PinholeCamera,
) -> Vec<u8> {
    let mut m = Vec::with_capacity(69);
    m.extend_from_slice(&id.to_le_bytes());
    m.extend_from_slice(&time.to_le_bytes());
    m.push(0);
    for v in pose.to_lsd_slam() {
        m.extend_from_slice(&(v as f32).to_le_bytes());
    }
    for v in [camera.fx, camera.fy, camera.cx, camera.cy] {
        m.extend_from_slice(&(v as f32).to_le_bytes());
    }
    m.extend_from_slice(&camera.height.to_le_bytes());
    m.extend_from_slice(&camera.width.to_le_bytes());
    m.extend_from_slice(&0u32.to_le_bytes());
    m
}

/// [`keyframe_msg_ros1`] with `pose` in place of the keyframe's own (a
/// keyframe as first published, before the map refined it).
pub fn keyframe_msg_ros1_at(kf: &Keyframe, pose: &Sim3) -> Vec<u8> {
    let n = kf.len();
    let mut m = Vec::with_capacity(69 + 12 * n);
    m.extend_from_slice(&kf.id.to_le_bytes());
    m.extend_from_slice(&kf.timestamp.to_le_bytes());
    m.push(1);
    for v in pose.to_lsd_slam() {
        m.extend_from_slice(&(v as f32).to_le_bytes());
    }
    let c = &kf.camera;
    for v in [c.fx, c.fy, c.cx, c.cy] {
        m.extend_from_slice(&(v as f32).to_le_bytes());
    }
    m.extend_from_slice(&c.height.to_le_bytes());
    m.extend_from_slice(&c.width.to_le_bytes());
    m.extend_from_slice(&((12 * n) as u32).to_le_bytes());
    for i in 0..n {
        m.extend_from_slice(&kf.idepth[i].to_le_bytes());
        let var = kf.idepth_var.as_ref().map_or(0.0, |v| v[i]);
        m.extend_from_slice(&var.to_le_bytes());
        match &kf.color {
            Some(col) => m.extend_from_slice(&[col[3 * i], col[3 * i + 1], col[3 * i + 2], 255]),
            None => m.extend_from_slice(&[128, 128, 128, 255]),
        }
    }
    m
}

/// The ROS 1 `keyframeGraphMsg` listing `(id, camToWorld)` of each keyframe (no constraints).
pub fn graph_msg_ros1(keyframes: &[Keyframe]) -> Vec<u8> {
    let poses: Vec<(i32, Sim3)> = keyframes.iter().map(|k| (k.id, k.pose)).collect();
    graph_msg_ros1_poses(&poses)
}

/// The ROS 1 `keyframeGraphMsg` listing `(id, camToWorld)` pairs (no constraints).
pub fn graph_msg_ros1_poses(poses: &[(i32, Sim3)]) -> Vec<u8> {
    let mut frames = Vec::with_capacity(32 * poses.len());
    for (id, pose) in poses {
        frames.extend_from_slice(&id.to_le_bytes());
        for v in pose.to_lsd_slam() {
            frames.extend_from_slice(&(v as f32).to_le_bytes());
        }
    }
    let mut m = Vec::with_capacity(16 + frames.len());
    m.extend_from_slice(&(poses.len() as u32).to_le_bytes());
    m.extend_from_slice(&(frames.len() as u32).to_le_bytes());
    m.extend_from_slice(&frames);
    m.extend_from_slice(&0u32.to_le_bytes());
    m.extend_from_slice(&0u32.to_le_bytes());
    m
}

fn ros1_header(m: &mut Vec<u8>, seq: u32, t: f64, frame: &str) {
    let sec = t.floor();
    m.extend_from_slice(&seq.to_le_bytes());
    m.extend_from_slice(&(sec as u32).to_le_bytes());
    m.extend_from_slice(&(((t - sec) * 1e9).round().min(999_999_999.0) as u32).to_le_bytes());
    m.extend_from_slice(&(frame.len() as u32).to_le_bytes());
    m.extend_from_slice(frame.as_bytes());
}

/// The ROS 1 `geometry_msgs/PoseStamped` of a pose (`q` is `(x, y, z, w)`).
pub fn pose_stamped_ros1(seq: u32, t: f64, frame: &str, p: [f64; 3], q: [f64; 4]) -> Vec<u8> {
    let mut m = Vec::with_capacity(80 + frame.len());
    ros1_header(&mut m, seq, t, frame);
    for v in p.iter().chain(q.iter()) {
        m.extend_from_slice(&v.to_le_bytes());
    }
    m
}

/// The ROS 1 `sensor_msgs/Imu` of a sample (orientation unknown: covariance[0] = -1).
pub fn imu_ros1(seq: u32, t: f64, frame: &str, gyro: [f64; 3], accel: [f64; 3]) -> Vec<u8> {
    let mut m = Vec::with_capacity(340 + frame.len());
    ros1_header(&mut m, seq, t, frame);
    let mut put = |v: f64| m.extend_from_slice(&v.to_le_bytes());
    for v in [0.0, 0.0, 0.0, 1.0] {
        put(v);
    }
    put(-1.0);
    (0..8).for_each(|_| put(0.0));
    gyro.iter().for_each(|v| put(*v));
    (0..9).for_each(|_| put(0.0));
    accel.iter().for_each(|v| put(*v));
    (0..9).for_each(|_| put(0.0));
    m
}

/// Writes the log a LSD-SLAM user records: keyframes (ros1 `keyframeMsg`), one
/// final graph message, reference poses (`PoseStamped`, `T_world_body`) and IMU
/// samples, plus `metadata` as a Metadata record named `slam2world`. Log times
/// are the messages' own stamps. Deterministic: the same input gives a
/// byte-identical file (no wall-clock time; channels are not repeated in the
/// summary, whose order the `mcap` writer does not fix).
pub fn write_slam_log(
    path: impl AsRef<Path>,
    keyframes: &[Keyframe],
    reference: Option<&Trajectory>,
    imu: Option<&ImuSamples>,
    metadata: &[(String, String)],
    options: &SlamLogOptions,
) -> Result<()> {
    let mut set = OutputSet::new();
    write_slam_log_into(
        &mut set,
        path.as_ref(),
        keyframes,
        reference,
        imu,
        metadata,
        options,
    )?;
    set.commit().map(|_| ())
}

/// What LSD-SLAM publishes while it runs, beside the keyframes' final
/// state: the live frames, each keyframe as first published, re-published
/// keyframes and periodic graph messages ([`write_slam_log_live_into`]).
#[derive(Clone, Debug)]
pub struct LiveLog<'a> {
    /// Topic of the live frames (`keyframeMsg`, `isKeyframe = false`).
    pub topic: &'a str,
    /// Tracked `T_slam_cam` of every frame, written as live frames (id = row).
    pub frames: &'a Trajectory,
    /// Camera of the live frames.
    pub camera: crate::geometry::PinholeCamera,
    /// Each keyframe's pose when it was first published (one per keyframe, in
    /// order); the keyframe's own pose is its refined, final one.
    pub first_poses: &'a [Sim3],
    /// Also re-publish each keyframe, with its final pose and depth, when the
    /// next one is published (as LSD-SLAM does once a keyframe is finished);
    /// doubles the keyframe bytes.
    pub republish: bool,
    /// Seconds between graph messages (each with the keyframes published so
    /// far, at their final poses); the last graph message follows the last
    /// keyframe as without live data. `None`: that one only.
    pub graph_period: Option<f64>,
}

/// [`write_slam_log`] as one output of `set` (published when the set is committed).
pub fn write_slam_log_into(
    set: &mut OutputSet,
    path: &Path,
    keyframes: &[Keyframe],
    reference: Option<&Trajectory>,
    imu: Option<&ImuSamples>,
    metadata: &[(String, String)],
    options: &SlamLogOptions,
) -> Result<()> {
    write_slam_log_live_into(
        set, path, keyframes, None, reference, imu, metadata, options,
    )
}

/// [`write_slam_log_into`] with what the SLAM published live (`live`): the
/// keyframe messages carry the first-published poses, the refined poses
/// follow in graph messages (and re-published keyframes), and the live frames
/// are on their own topic.
#[allow(clippy::too_many_arguments)]
pub fn write_slam_log_live_into(
    set: &mut OutputSet,
    path: &Path,
    keyframes: &[Keyframe],
    live: Option<&LiveLog<'_>>,
    reference: Option<&Trajectory>,
    imu: Option<&ImuSamples>,
    metadata: &[(String, String)],
    options: &SlamLogOptions,
) -> Result<()> {
    // (log time, order within the same time, channel slot, payload)
    let mut msgs: Vec<(u64, usize, usize, Vec<u8>)> = Vec::new();
    if let Some(l) = live {
        if l.first_poses.len() != keyframes.len() {
            return Err(Error::ShapeMismatch {
                what: "first_poses".into(),
                expected: format!("{}, one per keyframe", keyframes.len()),
                got: format!("{}", l.first_poses.len()),
            });
        }
    }
    for (i, kf) in keyframes.iter().enumerate() {
        let t = nanos(path, &format!("keyframe {}", kf.id), kf.timestamp)?;
        let msg = match live {
            Some(l) => keyframe_msg_ros1_at(kf, &l.first_poses[i]),
            None => keyframe_msg_ros1(kf),
        };
        msgs.push((t, i, 0, msg));
        if let (Some(l), Some(next)) = (live, keyframes.get(i + 1)) {
            if l.republish {
                let t = nanos(path, &format!("keyframe {}", next.id), next.timestamp)?;
                msgs.push((t, i, 0, keyframe_msg_ros1(kf)));
            }
        }
    }
    if let Some(l) = live {
        let f = l.frames;
        for i in 0..f.len() {
            let t = nanos(path, "live frame", f.timestamps[i])?;
            let q = f
                .orientations
                .as_ref()
                .map_or_else(nalgebra::UnitQuaternion::identity, |o| o[i]);
            let pose = Sim3::try_new(q, f.positions[i], 1.0)?;
            msgs.push((
                t,
                i,
                4,
                live_frame_msg_ros1(i as i32, f.timestamps[i], &pose, &l.camera),
            ));
        }
        if let (Some(period), Some(_), Some(first), Some(last)) = (
            l.graph_period,
            &options.graph_topic,
            keyframes.first().map(|k| k.timestamp),
            keyframes.iter().map(|k| k.timestamp).reduce(f64::max),
        ) {
            if !(period.is_finite() && period > 0.0) {
                return Err(Error::invalid(
                    "graph_period",
                    format!("{period} is not a positive number of seconds"),
                ));
            }
            let mut k = 1usize;
            while first + k as f64 * period < last {
                let at = first + k as f64 * period;
                let seen: Vec<(i32, Sim3)> = keyframes
                    .iter()
                    .filter(|kf| kf.timestamp <= at)
                    .map(|kf| (kf.id, kf.pose))
                    .collect();
                let t = nanos(path, "graph", at)?;
                msgs.push((t, k, 1, graph_msg_ros1_poses(&seen)));
                k += 1;
            }
        }
    }
    if let (Some(_), Some(last)) = (
        &options.graph_topic,
        keyframes.iter().map(|k| k.timestamp).reduce(f64::max),
    ) {
        let t = nanos(path, "graph", last)?;
        msgs.push((t, usize::MAX, 1, graph_msg_ros1(keyframes)));
    }
    if let Some(r) = reference {
        for i in 0..r.len() {
            let t = nanos(path, "reference pose", r.timestamps[i])?;
            let p = r.positions[i];
            let q = match &r.orientations {
                Some(o) => {
                    let c = o[i].coords;
                    [c[0], c[1], c[2], c[3]]
                }
                None => [0.0, 0.0, 0.0, 1.0],
            };
            let data = pose_stamped_ros1(
                i as u32,
                r.timestamps[i],
                &options.pose_frame,
                [p.x, p.y, p.z],
                q,
            );
            msgs.push((t, i, 2, data));
        }
    }
    if let Some(s) = imu {
        for i in 0..s.len() {
            let t = nanos(path, "imu sample", s.timestamps[i])?;
            let g = s.gyro[i];
            let a = s.accel[i];
            let data = imu_ros1(
                i as u32,
                s.timestamps[i],
                &options.imu_frame,
                [g.x, g.y, g.z],
                [a.x, a.y, a.z],
            );
            msgs.push((t, i, 3, data));
        }
    }
    msgs.sort_by_key(|m| (m.0, m.2, m.1));
    let wopts = mcap::WriteOptions::new()
        .compression(options.compression)
        .profile("ros1")
        .library(concat!("slam2world ", env!("CARGO_PKG_VERSION")))
        .repeat_channels(false)
        .repeat_schemas(false)
        .emit_chunk_indexes(false)
        .emit_message_indexes(false);
    write_atomic(set, path, wopts, |w| {
        let mut chans = [
            Some(add_channel(
                w,
                path,
                &options.keyframe_topic,
                schemas::ROS1_KEYFRAME,
                "ros1",
            )?),
            match &options.graph_topic {
                Some(g) => Some(add_channel(
                    w,
                    path,
                    g,
                    schemas::ROS1_KEYFRAME_GRAPH,
                    "ros1",
                )?),
                None => None,
            },
            match reference {
                Some(_) => Some(add_channel(
                    w,
                    path,
                    &options.pose_topic,
                    schemas::ROS1_POSE_STAMPED,
                    "ros1",
                )?),
                None => None,
            },
            match imu {
                Some(_) => Some(add_channel(
                    w,
                    path,
                    &options.imu_topic,
                    schemas::ROS1_IMU,
                    "ros1",
                )?),
                None => None,
            },
            match live {
                Some(l) => Some(add_channel(
                    w,
                    path,
                    l.topic,
                    schemas::ROS1_KEYFRAME,
                    "ros1",
                )?),
                None => None,
            },
        ];
        for (t, _, slot, data) in &msgs {
            if let Some(Some(ch)) = chans.get_mut(*slot) {
                put(w, path, ch, *t, data)?;
            }
        }
        if !metadata.is_empty() {
            let md = mcap::records::Metadata {
                name: "slam2world".into(),
                metadata: metadata.iter().cloned().collect(),
            };
            w.write_metadata(&md)
                .map_err(|e| write_err(path, "metadata", e))?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cloud_is_split_into_messages_alike_in_memory_and_on_disk() {
        let n: usize = 1000;
        let pts: Vec<f32> = (0..3 * n).map(|v| v as f32 * 0.25).collect();
        let cols: Vec<u8> = (0..3 * n).map(|v| (v % 251) as u8).collect();
        let mut file = crate::io::spill::CloudFile::new(true).unwrap();
        file.push(&pts, Some(&cols)).unwrap();
        let path = Path::new("world.mcap");
        // Each message written a piece at a time, as world.mcap's are.
        let split = |cloud: CloudRef<'_>, per: usize| {
            let mut out = Vec::new();
            cloud_messages(cloud, per, |n, pieces| {
                let (fox, ros) = (
                    CloudMessage::foxglove(1.0, "world", n),
                    CloudMessage::ros2(1.0, "world", n),
                );
                let (mut a, mut b) = (Vec::new(), Vec::new());
                fox.write(&mut a, &mut *pieces, path)?;
                ros.write(&mut b, pieces, path)?;
                assert_eq!((a.len(), b.len()), (fox.len(), ros.len()));
                out.push((a, b));
                Ok(())
            })
            .unwrap();
            out
        };
        for per in [1000, 333, 5000] {
            let mem = split(CloudRef::Memory(&pts, Some(&cols)), per);
            assert_eq!(mem.len(), n.div_ceil(per));
            assert_eq!(mem, split(CloudRef::File(&file), per));
            let mut at = 0;
            for (fox, ros) in &mem {
                let k = per.min(n - at);
                let (p, c) = (&pts[3 * at..3 * (at + k)], &cols[3 * at..3 * (at + k)]);
                // As the one-slice writers make it.
                assert_eq!(fox, &foxglove_point_cloud(1.0, "world", p, Some(c)));
                assert_eq!(ros, &ros2_point_cloud(1.0, "world", p, Some(c)));
                // Field 6 (data) holds the points, x y z r g b 255 each,
                // and is the message's last field.
                let fields: Vec<_> = pb_fields(fox)
                    .collect::<std::result::Result<_, _>>()
                    .unwrap();
                let data = fields.iter().find(|(f, _)| *f == 6).unwrap();
                let mut expect = Vec::new();
                for i in 0..k {
                    for v in &p[3 * i..3 * i + 3] {
                        expect.extend_from_slice(&v.to_le_bytes());
                    }
                    expect.extend_from_slice(&[c[3 * i], c[3 * i + 1], c[3 * i + 2], 255]);
                }
                assert!(matches!(&data.1, PbValue::Bytes(b) if *b == &expect[..]));
                assert!(fox.ends_with(&expect));
                // PointCloud2: the points, then is_dense.
                assert_eq!(ros.last(), Some(&1));
                at += k;
            }
        }
        assert_eq!(split(CloudRef::Memory(&[], None), 10).len(), 1);
        // A cloud that gives fewer points than the message declared.
        let mut short = |f: Piece<'_>| {
            f(&pts[..30], None);
            Ok(())
        };
        let e = CloudMessage::foxglove(1.0, "world", 11)
            .write(&mut Vec::new(), &mut short, path)
            .unwrap_err();
        assert!(e.to_string().contains("declared 176 bytes"), "{e}");
    }
    use crate::io::messages::wire::{pb_fields, PbValue};

    #[test]
    fn height_colors_run_from_blue_to_red() {
        assert_eq!(height_color(0.0, 0.0, 2.0), [0.0, 0.0, 1.0]);
        assert_eq!(height_color(2.0, 0.0, 2.0), [1.0, 0.0, 0.0]);
        assert_eq!(height_color(1.0, 0.0, 2.0), [0.0, 1.0, 0.0]);
        assert_eq!(height_color(5.0, 0.0, 2.0), [1.0, 0.0, 0.0]);
        assert_eq!(height_color(1.0, 1.0, 1.0), [0.0, 1.0, 0.0]);
    }

    #[test]
    fn scene_update_has_one_entity_with_a_cube_per_leaf() {
        let leaves = [([0.5, 0.5, 0.5], 1.0), ([2.0, 0.0, 4.0], 0.25)];
        let msg = foxglove_scene_update_cubes(1.5, "world", &leaves);
        let top: Vec<_> = pb_fields(&msg).map(|f| f.unwrap()).collect();
        assert_eq!(top.len(), 1);
        assert_eq!(top[0].0, 2);
        let entity = top[0].1.as_bytes().unwrap();
        let mut cubes = 0;
        for f in pb_fields(entity) {
            let (n, v) = f.unwrap();
            match n {
                2 => assert_eq!(v.as_bytes().unwrap(), b"world"),
                3 => assert_eq!(v.as_bytes().unwrap(), OCTOMAP_ENTITY_ID.as_bytes()),
                8 => cubes += 1,
                _ => {}
            }
        }
        assert_eq!(cubes, 2);
    }
}
