//! Message decoders: LSD-SLAM keyframes and graphs (ROS 1), reference poses
//! (`geometry_msgs/PoseStamped`, `PoseWithCovarianceStamped`, `TransformStamped`,
//! `nav_msgs/Odometry`, `tf2_msgs/TFMessage` in ROS 1 and ROS 2 CDR; `foxglove.PoseInFrame` and
//! `foxglove.PosesInFrame` in protobuf and JSON) and `sensor_msgs/Imu`.
//!
//! Decoders return a [`WireError`] saying what was wrong and where in the
//! message; the log assembly (`io::log`) adds the file, topic and
//! message index. The same decoders serve MCAP files and ROS bags.

use super::wire::{pb_fields, Cdr, PbValue, Ros1, RosReader, WireError, WireResult};

/// Size of one LSD-SLAM `InputPointDense` (f32 idepth, f32 idepth_var, u8 color[4]).
pub const POINT_BYTES: usize = 12;

/// What a channel carries, found from its schema name (ROS 1 `pkg/Type`,
/// ROS 2 `pkg/msg/Type`, Foxglove `foxglove.Type`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum MessageKind {
    /// `lsd_slam_viewer/keyframeMsg`.
    Keyframe,
    /// `lsd_slam_viewer/keyframeGraphMsg`.
    KeyframeGraph,
    /// `geometry_msgs/PoseStamped`.
    PoseStamped,
    /// `geometry_msgs/PoseWithCovarianceStamped`.
    PoseWithCovarianceStamped,
    /// `nav_msgs/Odometry`.
    Odometry,
    /// `geometry_msgs/TransformStamped` (`T_frame_child`, e.g. a motion-capture body).
    TransformStamped,
    /// `foxglove.PoseInFrame`.
    PoseInFrame,
    /// `foxglove.PosesInFrame` (the last pose of each message is taken).
    PosesInFrame,
    /// `tf2_msgs/TFMessage` (one parent/child pair is taken).
    Tf,
    /// `sensor_msgs/Imu`.
    Imu,
    /// `sensor_msgs/NavSatFix` (decoded by `io::messages::gnss`).
    NavSatFix,
    /// `foxglove.LocationFix` (decoded by `io::messages::gnss`).
    LocationFix,
}

impl MessageKind {
    /// The kind of a schema name, or `None` for a schema slam2world does not use.
    pub fn from_schema(name: &str) -> Option<Self> {
        let n = name.replace("/msg/", "/");
        Some(match n.as_str() {
            "lsd_slam_viewer/keyframeMsg" => MessageKind::Keyframe,
            "lsd_slam_viewer/keyframeGraphMsg" => MessageKind::KeyframeGraph,
            "geometry_msgs/PoseStamped" => MessageKind::PoseStamped,
            "geometry_msgs/PoseWithCovarianceStamped" => MessageKind::PoseWithCovarianceStamped,
            "nav_msgs/Odometry" => MessageKind::Odometry,
            "geometry_msgs/TransformStamped" => MessageKind::TransformStamped,
            "foxglove.PoseInFrame" => MessageKind::PoseInFrame,
            "foxglove.PosesInFrame" => MessageKind::PosesInFrame,
            "tf2_msgs/TFMessage" => MessageKind::Tf,
            "sensor_msgs/Imu" => MessageKind::Imu,
            "sensor_msgs/NavSatFix" => MessageKind::NavSatFix,
            "foxglove.LocationFix" => MessageKind::LocationFix,
            _ => return None,
        })
    }

    /// True for the kinds that give reference poses.
    pub fn is_pose(self) -> bool {
        matches!(
            self,
            MessageKind::PoseStamped
                | MessageKind::PoseWithCovarianceStamped
                | MessageKind::Odometry
                | MessageKind::TransformStamped
                | MessageKind::PoseInFrame
                | MessageKind::PosesInFrame
                | MessageKind::Tf
        )
    }

    /// Message encodings this kind is decoded from.
    pub fn encodings(self) -> &'static [&'static str] {
        match self {
            MessageKind::Keyframe | MessageKind::KeyframeGraph => &["ros1"],
            MessageKind::PoseInFrame | MessageKind::PosesInFrame | MessageKind::LocationFix => {
                &["protobuf", "json"]
            }
            _ => &["ros1", "cdr"],
        }
    }

    /// How slam2world uses the kind (for `inspect`).
    pub fn usage(self) -> &'static str {
        match self {
            MessageKind::Keyframe => "SLAM keyframes (pose, camera, inverse depth)",
            MessageKind::KeyframeGraph => "SLAM keyframe pose updates",
            MessageKind::Imu => "raw IMU samples",
            MessageKind::NavSatFix | MessageKind::LocationFix => {
                "GNSS fixes (latitude, longitude, altitude)"
            }
            MessageKind::Tf => "reference poses (one parent/child pair)",
            _ => "reference poses",
        }
    }
}

/// A stamped pose: `T_frame_child` at `time`.
#[derive(Clone, Debug, PartialEq)]
pub struct StampedPose {
    /// Header stamp, seconds.
    pub time: f64,
    /// The frame the pose is expressed in (the parent).
    pub frame_id: String,
    /// The child frame (TF and Odometry; empty otherwise).
    pub child_frame_id: String,
    /// Translation, metres.
    pub position: [f64; 3],
    /// Rotation `(x, y, z, w)` as in the message (not normalised).
    pub orientation: [f64; 4],
}

/// A decoded `keyframeMsg`; `pointcloud` borrows the message bytes.
#[derive(Clone, Debug)]
pub struct KeyframeMsg<'a> {
    /// Keyframe id.
    pub id: i32,
    /// The message's own time, seconds.
    pub time: f64,
    /// False for live frames (pose only, empty point cloud).
    pub is_keyframe: bool,
    /// `[qx, qy, qz, qw, tx, ty, tz]`, the quaternion scaled by the Sim(3) scale.
    pub cam_to_world: [f64; 7],
    /// Intrinsics, pixels.
    pub fx: f64,
    /// Intrinsics, pixels.
    pub fy: f64,
    /// Intrinsics, pixels.
    pub cx: f64,
    /// Intrinsics, pixels.
    pub cy: f64,
    /// Image size, pixels.
    pub width: u32,
    /// Image size, pixels.
    pub height: u32,
    /// `width·height` × 12 bytes of `InputPointDense`, or empty.
    pub pointcloud: &'a [u8],
}

/// Decodes a ROS 1 `lsd_slam_viewer/keyframeMsg` (layout in DESIGN.md). A
/// keyframe whose point cloud is neither empty nor `width·height·12` bytes is an error.
pub fn keyframe_ros1(data: &[u8]) -> WireResult<KeyframeMsg<'_>> {
    let mut r = Ros1::new(data);
    let id = r.i32()?;
    let time = r.f64()?;
    let is_keyframe = r.u8()? != 0;
    let mut cam_to_world = [0.0; 7];
    for v in &mut cam_to_world {
        *v = r.f32()? as f64;
    }
    let fx = r.f32()? as f64;
    let fy = r.f32()? as f64;
    let cx = r.f32()? as f64;
    let cy = r.f32()? as f64;
    let height = r.u32()?;
    let width = r.u32()?;
    let pc_offset = r.pos();
    let pointcloud = r.byte_array()?;
    // u32·u32·12 can exceed u64: count in u128.
    let expected = width as u128 * height as u128 * POINT_BYTES as u128;
    if !pointcloud.is_empty() && pointcloud.len() as u128 != expected {
        return Err(WireError::malformed(
            pc_offset,
            format!(
                "keyframe {id}: point cloud of {} bytes, expected width·height·12 = {width}·{height}·12 = {expected}",
                pointcloud.len()
            ),
        ));
    }
    if is_keyframe && pointcloud.is_empty() {
        return Err(WireError::malformed(
            pc_offset,
            format!("keyframe {id}: isKeyframe is set but the point cloud is empty"),
        ));
    }
    Ok(KeyframeMsg {
        id,
        time,
        is_keyframe,
        cam_to_world,
        fx,
        fy,
        cx,
        cy,
        width,
        height,
        pointcloud,
    })
}

/// Splits an LSD-SLAM point cloud into inverse depth, its variance and RGB
/// (the fourth colour byte is dropped).
///
/// One pass over the message bytes (a decompressed chunk, or the memory map)
/// straight into the three arrays, which are allocated zeroed (fresh pages from
/// the system for a large image) and filled in place, without a bounds check
/// or a length update per point.
pub fn split_pointcloud(pc: &[u8]) -> (Vec<f32>, Vec<f32>, Vec<u8>) {
    let n = pc.len() / POINT_BYTES;
    let mut out = (
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(3 * n),
    );
    split_pointcloud_into(pc, &mut out);
    out
}

/// [`split_pointcloud`] appending to `out` (inverse depth, variance, RGB):
/// a cloud read a piece at a time is split as it comes.
pub fn split_pointcloud_into(pc: &[u8], (idepth, var, color): &mut (Vec<f32>, Vec<f32>, Vec<u8>)) {
    let n = pc.len() / POINT_BYTES;
    idepth.reserve(n);
    var.reserve(n);
    color.reserve(3 * n);
    // Written once, without a zero fill first (megabytes a keyframe).
    for (((p, d), v), c) in pc
        .chunks_exact(POINT_BYTES)
        .zip(idepth.spare_capacity_mut())
        .zip(var.spare_capacity_mut())
        .zip(color.spare_capacity_mut().chunks_exact_mut(3))
    {
        d.write(f32::from_le_bytes([p[0], p[1], p[2], p[3]]));
        v.write(f32::from_le_bytes([p[4], p[5], p[6], p[7]]));
        for (c, &b) in c.iter_mut().zip(&p[8..11]) {
            c.write(b);
        }
    }
    // SAFETY: the loop ran over the `n` points (each vector had room for
    // them), and wrote the `n` elements of `idepth` and `var` and the `3n`
    // of `color` after their lengths.
    unsafe {
        idepth.set_len(idepth.len() + n);
        var.set_len(var.len() + n);
        color.set_len(color.len() + 3 * n);
    }
}

/// Decodes a ROS 1 `lsd_slam_viewer/keyframeGraphMsg`: `(id, camToWorld)` per frame.
pub fn graph_ros1(data: &[u8]) -> WireResult<Vec<(i32, [f64; 7])>> {
    let mut r = Ros1::new(data);
    let num_frames = r.u32()? as usize;
    let at = r.pos();
    let frames = r.byte_array()?;
    if frames.len() != num_frames.saturating_mul(32) {
        return Err(WireError::malformed(
            at,
            format!(
                "graph: frameData of {} bytes, expected numFrames·32 = {num_frames}·32",
                frames.len()
            ),
        ));
    }
    let mut out = Vec::with_capacity(num_frames);
    for f in frames.chunks_exact(32) {
        let mut fr = Ros1::new(f);
        let id = fr.i32()?;
        let mut c = [0.0; 7];
        for v in &mut c {
            *v = fr.f32()? as f64;
        }
        out.push((id, c));
    }
    Ok(out)
}

/// One IMU sample: time (s), angular rate (rad/s), specific force (m/s²).
#[derive(Clone, Debug, PartialEq)]
pub struct ImuMsg {
    /// Header stamp, seconds.
    pub time: f64,
    /// Angular velocity, rad/s.
    pub gyro: [f64; 3],
    /// Linear acceleration, m/s².
    pub accel: [f64; 3],
}

/// Decodes `sensor_msgs/Imu` (`ros1` or `cdr`).
pub fn imu(encoding: &str, data: &[u8]) -> WireResult<ImuMsg> {
    match encoding {
        "ros1" => {
            let mut r = Ros1::new(data);
            let (time, _) = r.header()?;
            let mut skip = [0.0; 4 + 9];
            for v in &mut skip {
                *v = r.f64()?;
            }
            let gyro = [r.f64()?, r.f64()?, r.f64()?];
            for _ in 0..9 {
                r.f64()?;
            }
            let accel = [r.f64()?, r.f64()?, r.f64()?];
            Ok(ImuMsg { time, gyro, accel })
        }
        "cdr" => {
            let mut r = Cdr::new(data)?;
            let (time, _) = r.header()?;
            for _ in 0..4 + 9 {
                r.f64()?;
            }
            let gyro = [r.f64()?, r.f64()?, r.f64()?];
            for _ in 0..9 {
                r.f64()?;
            }
            let accel = [r.f64()?, r.f64()?, r.f64()?];
            Ok(ImuMsg { time, gyro, accel })
        }
        other => Err(WireError::schema(format!(
            "sensor_msgs/Imu in encoding {other:?} is not supported"
        ))),
    }
}

/// `(time, position, orientation xyzw)` of a single-pose message.
pub type PoseSample = (f64, [f64; 3], [f64; 4]);

fn ros_sample<'a, R: RosReader<'a>>(kind: MessageKind, r: &mut R) -> WireResult<PoseSample> {
    let time = r.header_stamp()?;
    // Odometry and TransformStamped have the child frame before the pose.
    if matches!(kind, MessageKind::Odometry | MessageKind::TransformStamped) {
        r.skip_string()?;
    }
    let (p, q) = pose_fields(r)?;
    Ok((time, p, q))
}

/// Decodes the one pose of a message of any pose kind but TF, without
/// allocating (the fast path of reference reading).
pub fn pose_sample(kind: MessageKind, encoding: &str, data: &[u8]) -> WireResult<PoseSample> {
    match (kind, encoding) {
        (
            MessageKind::PoseStamped
            | MessageKind::PoseWithCovarianceStamped
            | MessageKind::Odometry
            | MessageKind::TransformStamped,
            "ros1",
        ) => ros_sample(kind, &mut Ros1::new(data)),
        (
            MessageKind::PoseStamped
            | MessageKind::PoseWithCovarianceStamped
            | MessageKind::Odometry
            | MessageKind::TransformStamped,
            "cdr",
        ) => ros_sample(kind, &mut Cdr::new(data)?),
        _ => {
            let v = poses(kind, encoding, data)?;
            match v.last() {
                Some(s) => Ok((s.time, s.position, s.orientation)),
                None => Err(WireError::schema("message without a pose")),
            }
        }
    }
}

fn pose_fields<'a, R: RosReader<'a>>(r: &mut R) -> WireResult<([f64; 3], [f64; 4])> {
    let [x, y, z, qx, qy, qz, qw] = r.f64s::<7>()?;
    Ok(([x, y, z], [qx, qy, qz, qw]))
}

fn ros_pose<'a, R: RosReader<'a>>(kind: MessageKind, r: &mut R) -> WireResult<Vec<StampedPose>> {
    match kind {
        MessageKind::PoseStamped | MessageKind::PoseWithCovarianceStamped => {
            let (time, frame_id) = r.header()?;
            let (position, orientation) = pose_fields(r)?;
            Ok(vec![StampedPose {
                time,
                frame_id,
                child_frame_id: String::new(),
                position,
                orientation,
            }])
        }
        // `TransformStamped`: header, child_frame_id, translation, rotation —
        // the layout of Odometry's first fields and of one TF entry.
        MessageKind::Odometry | MessageKind::TransformStamped => {
            let (time, frame_id) = r.header()?;
            let child_frame_id = r.string()?;
            let (position, orientation) = pose_fields(r)?;
            Ok(vec![StampedPose {
                time,
                frame_id,
                child_frame_id,
                position,
                orientation,
            }])
        }
        MessageKind::Tf => {
            let n = r.seq_len()?;
            let mut out = Vec::with_capacity(n.min(1024));
            for _ in 0..n {
                let (time, frame_id) = r.header()?;
                let child_frame_id = r.string()?;
                let (position, orientation) = pose_fields(r)?;
                out.push(StampedPose {
                    time,
                    frame_id,
                    child_frame_id,
                    position,
                    orientation,
                });
            }
            Ok(out)
        }
        other => Err(WireError::schema(format!(
            "{other:?} is not a ROS pose message"
        ))),
    }
}

fn pb_vec(buf: &[u8], n: usize) -> WireResult<[f64; 4]> {
    let mut v = [0.0; 4];
    for f in pb_fields(buf) {
        let (num, val) = f?;
        if (1..=n as u32).contains(&num) {
            v[num as usize - 1] = val.as_f64()?;
        }
    }
    if n == 4 && v == [0.0; 4] {
        // proto3 omits zero fields; an empty quaternion is read as the identity.
        v[3] = 1.0;
    }
    Ok(v)
}

fn pb_pose(buf: &[u8]) -> WireResult<([f64; 3], [f64; 4])> {
    let mut p = [0.0; 3];
    let mut q = [0.0, 0.0, 0.0, 1.0];
    for f in pb_fields(buf) {
        match f? {
            (1, v) => {
                let a = pb_vec(v.as_bytes()?, 3)?;
                p = [a[0], a[1], a[2]];
            }
            (2, v) => q = pb_vec(v.as_bytes()?, 4)?,
            _ => {}
        }
    }
    Ok((p, q))
}

/// A `google.protobuf.Timestamp` (seconds 1, nanos 2), as seconds.
pub(crate) fn pb_time(buf: &[u8]) -> WireResult<f64> {
    let mut sec = 0i64;
    let mut nsec = 0i64;
    for f in pb_fields(buf) {
        match f? {
            (1, v) => sec = v.as_u64()? as i64,
            (2, v) => nsec = v.as_u64()? as i32 as i64,
            _ => {}
        }
    }
    Ok(sec as f64 + nsec as f64 * 1e-9)
}

fn foxglove_protobuf(kind: MessageKind, data: &[u8]) -> WireResult<Vec<StampedPose>> {
    let mut time = 0.0;
    let mut frame_id = String::new();
    let mut poses = Vec::new();
    for f in pb_fields(data) {
        match f? {
            (1, v) => time = pb_time(v.as_bytes()?)?,
            (2, v) => frame_id = String::from_utf8_lossy(v.as_bytes()?).into_owned(),
            (3, PbValue::Bytes(b)) => poses.push(pb_pose(b)?),
            (3, other) => {
                return Err(WireError::schema(format!(
                    "pose field is not a message: {other:?}"
                )))
            }
            _ => {}
        }
    }
    let pose = match (kind, poses.last()) {
        (_, Some(p)) => *p,
        (MessageKind::PoseInFrame, None) => ([0.0; 3], [0.0, 0.0, 0.0, 1.0]),
        (_, None) => return Err(WireError::schema("PosesInFrame message without poses")),
    };
    Ok(vec![StampedPose {
        time,
        frame_id,
        child_frame_id: String::new(),
        position: pose.0,
        orientation: pose.1,
    }])
}

fn json_num(v: &serde_json::Value, what: &str) -> WireResult<f64> {
    v.as_f64().ok_or_else(|| {
        WireError::schema(format!("JSON field {what}: expected a number, found {v}"))
    })
}

fn json_pose(v: &serde_json::Value) -> WireResult<([f64; 3], [f64; 4])> {
    let p = &v["position"];
    let q = &v["orientation"];
    Ok((
        [
            json_num(&p["x"], "position.x")?,
            json_num(&p["y"], "position.y")?,
            json_num(&p["z"], "position.z")?,
        ],
        [
            json_num(&q["x"], "orientation.x")?,
            json_num(&q["y"], "orientation.y")?,
            json_num(&q["z"], "orientation.z")?,
            json_num(&q["w"], "orientation.w")?,
        ],
    ))
}

fn foxglove_json(kind: MessageKind, data: &[u8]) -> WireResult<Vec<StampedPose>> {
    let v: serde_json::Value = serde_json::from_slice(data)
        .map_err(|e| WireError::schema(format!("invalid JSON: {e}")))?;
    let t = &v["timestamp"];
    let time =
        json_num(&t["sec"], "timestamp.sec")? + json_num(&t["nsec"], "timestamp.nsec")? * 1e-9;
    let frame_id = v["frame_id"].as_str().unwrap_or_default().to_string();
    let pose = match kind {
        MessageKind::PoseInFrame => json_pose(&v["pose"])?,
        _ => match v["poses"].as_array().and_then(|a| a.last()) {
            Some(p) => json_pose(p)?,
            None => return Err(WireError::schema("PosesInFrame message without poses")),
        },
    };
    Ok(vec![StampedPose {
        time,
        frame_id,
        child_frame_id: String::new(),
        position: pose.0,
        orientation: pose.1,
    }])
}

/// Decodes the poses of one message of a pose kind in the given encoding.
pub fn poses(kind: MessageKind, encoding: &str, data: &[u8]) -> WireResult<Vec<StampedPose>> {
    match (kind, encoding) {
        (MessageKind::PoseInFrame | MessageKind::PosesInFrame, "protobuf") => {
            foxglove_protobuf(kind, data)
        }
        (MessageKind::PoseInFrame | MessageKind::PosesInFrame, "json") => foxglove_json(kind, data),
        (MessageKind::PoseInFrame | MessageKind::PosesInFrame, _) => {
            Err(WireError::schema(format!(
                "{kind:?} in message encoding {encoding:?} is not supported (protobuf or json)"
            )))
        }
        (_, "ros1") => ros_pose(kind, &mut Ros1::new(data)),
        (_, "cdr") => ros_pose(kind, &mut Cdr::new(data)?),
        _ => Err(WireError::schema(format!(
            "{kind:?} in message encoding {encoding:?} is not supported (ros1 or cdr)"
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schema_names_map_to_kinds() {
        assert_eq!(
            MessageKind::from_schema("geometry_msgs/msg/PoseStamped"),
            Some(MessageKind::PoseStamped)
        );
        assert_eq!(
            MessageKind::from_schema("foxglove.PoseInFrame"),
            Some(MessageKind::PoseInFrame)
        );
        assert_eq!(MessageKind::from_schema("std_msgs/String"), None);
    }

    #[test]
    fn keyframe_with_wrong_pointcloud_size_is_refused() {
        let mut m = Vec::new();
        m.extend_from_slice(&3i32.to_le_bytes());
        m.extend_from_slice(&1.5f64.to_le_bytes());
        m.push(1);
        for v in [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0] {
            m.extend_from_slice(&v.to_le_bytes());
        }
        m.extend_from_slice(&2u32.to_le_bytes()); // height
        m.extend_from_slice(&2u32.to_le_bytes()); // width
        m.extend_from_slice(&13u32.to_le_bytes());
        m.extend_from_slice(&[0u8; 13]);
        let e = keyframe_ros1(&m).unwrap_err();
        // The length field of the point cloud sits at byte 65 of the message.
        let WireError::Malformed { offset: 65, what } = &e else {
            panic!("{e:?}")
        };
        assert!(what.contains("13 bytes") && what.contains("48"), "{e}");
    }

    #[test]
    fn json_pose_in_frame() {
        let j = br#"{"timestamp":{"sec":2,"nsec":500000000},"frame_id":"w",
            "pose":{"position":{"x":1,"y":2,"z":3},"orientation":{"x":0,"y":0,"z":0,"w":1}}}"#;
        let p = poses(MessageKind::PoseInFrame, "json", j).unwrap();
        assert_eq!(p[0].time, 2.5);
        assert_eq!(p[0].position, [1.0, 2.0, 3.0]);
        assert!(poses(MessageKind::PoseInFrame, "json", b"{").is_err());
    }
}
