"""MCAP logs: logs written by the Python mcap packages decode; our output reads back."""

from __future__ import annotations

import gc
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import data_path
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from mcap.reader import make_reader
from mcap.writer import Writer as McapWriter
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory
from mcap_protobuf.writer import Writer as ProtobufWriter
from mcap_ros1._vendor.genpy.dynamic import generate_dynamic
from mcap_ros1.writer import Writer as Ros1Writer
from mcap_ros2.writer import Writer as Ros2Writer

import slam2world as s2w

REPO = Path(__file__).resolve().parents[2]
SCHEMAS = REPO / "src" / "io" / "mcap" / "schemas"

KEYFRAME_MSG = """int32 id
float64 time
bool isKeyframe
float32[7] camToWorld
float32 fx
float32 fy
float32 cx
float32 cy
uint32 height
uint32 width
uint8[] pointcloud
"""

GRAPH_MSG = """uint32 numFrames
uint8[] frameData
uint32 numConstraints
uint8[] constraintsData
"""

POSE_STAMPED = """Header header
Pose pose
================================================================================
MSG: std_msgs/Header
uint32 seq
time stamp
string frame_id
================================================================================
MSG: geometry_msgs/Pose
Point position
Quaternion orientation
================================================================================
MSG: geometry_msgs/Point
float64 x
float64 y
float64 z
================================================================================
MSG: geometry_msgs/Quaternion
float64 x
float64 y
float64 z
float64 w
"""

IMU = """Header header
geometry_msgs/Quaternion orientation
float64[9] orientation_covariance
geometry_msgs/Vector3 angular_velocity
float64[9] angular_velocity_covariance
geometry_msgs/Vector3 linear_acceleration
float64[9] linear_acceleration_covariance
================================================================================
MSG: std_msgs/Header
uint32 seq
time stamp
string frame_id
================================================================================
MSG: geometry_msgs/Quaternion
float64 x
float64 y
float64 z
float64 w
================================================================================
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z
"""

W, H = 6, 4


def _cls(name: str, text: str) -> Any:
    return generate_dynamic(name, text)[name]


def _pointcloud(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray, bytes]:
    idepth = rng.uniform(0.2, 2.0, (H, W)).astype(np.float32)
    var = rng.uniform(0.0, 1e-3, (H, W)).astype(np.float32)
    color = rng.integers(0, 256, (H, W, 4), dtype=np.uint8)
    rec = np.zeros((H, W), dtype=[("d", "<f4"), ("v", "<f4"), ("c", "u1", (4,))])
    rec["d"], rec["v"], rec["c"] = idepth, var, color
    return idepth, var, color, rec.tobytes()


def _c2w(rng: np.random.Generator, scale: float) -> list[float]:
    q = rng.normal(size=4)
    q = q / np.linalg.norm(q) * scale
    return [float(v) for v in q] + [float(v) for v in rng.normal(size=3)]


def _write_lsd_log(path: Path) -> dict[str, Any]:
    """An LSD-SLAM session: keyframes 0, 1, 2, keyframe 1 re-published, a live frame,
    a graph update of 0 and 1, ground truth and IMU; log times = receive times."""
    rng = np.random.default_rng(3)
    Kf = _cls("lsd_slam_viewer/keyframeMsg", KEYFRAME_MSG)
    Graph = _cls("lsd_slam_viewer/keyframeGraphMsg", GRAPH_MSG)
    Pose = _cls("geometry_msgs/PoseStamped", POSE_STAMPED)
    Imu = _cls("sensor_msgs/Imu", IMU)
    expected: dict[str, Any] = {"kf": {}}
    with open(path, "wb") as f:
        w = Ros1Writer(f)
        log_t = 1_000_000_000_000
        for i, (kid, t) in enumerate([(0, 100.0), (1, 100.5), (2, 101.0), (1, 100.5)]):
            idepth, var, color, blob = _pointcloud(rng)
            c2w = _c2w(rng, 1.0 + 0.5 * kid)
            msg = Kf(
                id=kid,
                time=t,
                isKeyframe=True,
                camToWorld=c2w,
                fx=5.0,
                fy=5.5,
                cx=2.5,
                cy=1.5,
                height=H,
                width=W,
                pointcloud=blob,
            )
            w.write_message("/lsd_slam/keyframes", msg, log_time=log_t + i * 10**9)
            expected["kf"][kid] = (t, c2w, idepth, var, color)
        for j in range(6):  # live frames: more messages than keyframes, pose only
            live = Kf(id=9 + j, time=101.2 + j, isKeyframe=False, camToWorld=_c2w(rng, 1.0))
            w.write_message("/lsd_slam/liveframes", live, log_time=log_t + (5 + j) * 10**9)
        graph_poses = {0: _c2w(rng, 2.0), 1: _c2w(rng, 3.0)}
        frames = b"".join(
            np.array([k], "<i4").tobytes() + np.array(v, "<f4").tobytes()
            for k, v in graph_poses.items()
        )
        w.write_message(
            "/lsd_slam/graph",
            Graph(numFrames=2, frameData=frames, numConstraints=0, constraintsData=b""),
            log_time=log_t + 6 * 10**9,
        )
        expected["graph"] = graph_poses
        ts = 100.0 + 0.05 * np.arange(30)
        pos = rng.normal(size=(30, 3))
        for i, (t, p) in enumerate(zip(ts, pos)):
            m = Pose()
            m.header.seq = i
            m.header.stamp.secs = int(t)
            m.header.stamp.nsecs = int(round((t - int(t)) * 1e9))
            m.header.frame_id = "world"
            m.pose.position.x, m.pose.position.y, m.pose.position.z = p
            m.pose.orientation.w = 1.0
            w.write_message("/vicon/pose", m, log_time=log_t + i)
        expected["ref"] = (ts, pos)
        its = 100.0 + 0.005 * np.arange(12)
        gyro = rng.normal(size=(12, 3))
        acc = rng.normal(size=(12, 3))
        for i in range(12):
            m = Imu()
            m.header.stamp.secs = int(its[i])
            m.header.stamp.nsecs = int(round((its[i] - int(its[i])) * 1e9))
            m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = gyro[i]
            a = m.linear_acceleration
            a.x, a.y, a.z = acc[i]
            w.write_message("/imu0", m, log_time=log_t + i)
        expected["imu"] = (its, gyro, acc)
        w.finish()
    return expected


def test_lsd_slam_log_written_by_python_decodes(tmp_path: Path) -> None:
    path = tmp_path / "lsd.mcap"
    exp = _write_lsd_log(path)
    log = s2w.read_mcap(path)
    assert log.keyframe_topic == "/lsd_slam/keyframes"
    assert Path(log.path) == path
    assert log.graph_topic == "/lsd_slam/graph"
    assert log.reference_topic == "/vicon/pose"
    assert log.imu_topic == "/imu0"
    assert [k.id for k in log.keyframes] == [0, 1, 2]
    assert log.graph_updates == 2
    for k in log.keyframes:
        t, c2w, idepth, var, color = exp["kf"][k.id]
        assert k.timestamp == t  # the message's own time, not the log time
        np.testing.assert_array_equal(k.idepth, idepth)
        assert k.idepth_var is not None and k.color is not None
        np.testing.assert_array_equal(k.idepth_var, var)
        np.testing.assert_array_equal(k.color, color[..., :3])
        cam = k.camera
        assert (cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height) == (5.0, 5.5, 2.5, 1.5, W, H)
        c2w = exp["graph"].get(k.id, c2w)
        want = s2w.Sim3.from_lsd_slam(np.array(c2w, dtype=np.float32).astype(np.float64))
        np.testing.assert_allclose(k.pose.matrix(), want.matrix(), atol=1e-9)
    # The keyframes share the log's arrays: they outlive the log, and their
    # numpy arrays are copies a caller may write to.
    kept = log.keyframes[1]
    del log
    gc.collect()
    np.testing.assert_array_equal(kept.idepth, exp["kf"][1][2])
    a = kept.idepth
    a[:] = -1.0
    np.testing.assert_array_equal(kept.idepth, exp["kf"][1][2])
    log = s2w.read_mcap(path)
    ref = log.reference
    assert ref is not None
    ts, pos = exp["ref"]
    np.testing.assert_allclose(ref.timestamps, ts, atol=1e-9)
    np.testing.assert_array_equal(ref.positions, pos)
    assert ref.orientations is not None
    np.testing.assert_array_equal(ref.orientations, np.tile([0.0, 0.0, 0.0, 1.0], (len(ts), 1)))
    imu = log.imu
    assert imu is not None
    assert isinstance(imu, s2w.ImuSamples) and len(imu) == len(exp["imu"][0])
    np.testing.assert_allclose(imu.timestamps, exp["imu"][0], atol=1e-9)
    np.testing.assert_array_equal(imu.gyro, exp["imu"][1])
    np.testing.assert_array_equal(imu.accel, exp["imu"][2])


def test_nav2_sim_odometry() -> None:
    path = data_path("mcap_nav2_sim", "nav2_turtlebot.mcap")
    log = s2w.read_mcap(path, pose_topic="/odom")
    ref = log.reference
    assert ref is not None
    assert ref.timestamps.shape == (2639,)
    assert ref.positions.shape == (2639, 3)
    assert np.all(np.diff(ref.timestamps) >= 0)
    assert ref.orientations is not None
    np.testing.assert_allclose(np.linalg.norm(ref.orientations, axis=1), 1.0, atol=1e-9)


ROS2_POSE_STAMPED = """std_msgs/Header header
Pose pose
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
================================================================================
MSG: geometry_msgs/Pose
Point position
Quaternion orientation
================================================================================
MSG: geometry_msgs/Point
float64 x
float64 y
float64 z
================================================================================
MSG: geometry_msgs/Quaternion
float64 x
float64 y
float64 z
float64 w
"""


def test_ros2_pose_stamped_log(tmp_path: Path) -> None:
    path = tmp_path / "ros2.mcap"
    rng = np.random.default_rng(5)
    pos = rng.normal(size=(15, 3))
    q = rng.normal(size=(15, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    with open(path, "wb") as f:
        w = Ros2Writer(f)
        schema = w.register_msgdef("geometry_msgs/msg/PoseStamped", ROS2_POSE_STAMPED)
        for i in range(15):
            msg = {
                "header": {"stamp": {"sec": 50 + i, "nanosec": 250_000_000}, "frame_id": "map"},
                "pose": {
                    "position": dict(zip("xyz", pos[i])),
                    "orientation": dict(zip("xyzw", q[i])),
                },
            }
            w.write_message("/gt", schema, msg, log_time=i, publish_time=i)
        w.finish()
    log = s2w.read_mcap(path)
    ref = log.reference
    assert ref is not None
    np.testing.assert_allclose(ref.timestamps, 50.25 + np.arange(15), atol=1e-9)
    np.testing.assert_array_equal(ref.positions, pos)
    # same rotation (q and -q are one rotation)
    assert ref.orientations is not None
    dots = np.abs(np.sum(ref.orientations * q, axis=1))
    np.testing.assert_allclose(dots, 1.0, atol=1e-12)


def _foxglove_class(name: str) -> Any:
    fds = descriptor_pb2.FileDescriptorSet()
    fds.ParseFromString((SCHEMAS / f"{name}.fds.bin").read_bytes())
    pool = descriptor_pool.DescriptorPool()
    for fd in fds.file:
        pool.Add(fd)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(name))


def test_foxglove_pose_in_frame_protobuf(tmp_path: Path) -> None:
    PoseInFrame = _foxglove_class("foxglove.PoseInFrame")
    path = tmp_path / "pb.mcap"
    with open(path, "wb") as f:
        w = ProtobufWriter(f)
        for i in range(8):
            m = PoseInFrame()
            m.timestamp.seconds = 10 + i
            m.timestamp.nanos = 500_000_000
            m.frame_id = "world"
            m.pose.position.x = float(i)
            m.pose.position.y = -2.0 * i
            m.pose.position.z = 0.25
            m.pose.orientation.z = np.sin(0.1 * i)
            m.pose.orientation.w = np.cos(0.1 * i)
            w.write_message("/pose", m, log_time=i, publish_time=i)
        w.finish()
    ref = s2w.read_mcap(path).reference
    assert ref is not None
    np.testing.assert_allclose(ref.timestamps, 10.5 + np.arange(8), atol=1e-9)
    np.testing.assert_array_equal(ref.positions[:, 0], np.arange(8.0))
    np.testing.assert_array_equal(ref.positions[:, 1], -2.0 * np.arange(8.0))
    assert ref.orientations is not None
    np.testing.assert_allclose(ref.orientations[:, 3], np.cos(0.1 * np.arange(8)), atol=1e-12)


def test_foxglove_pose_in_frame_json(tmp_path: Path) -> None:
    path = tmp_path / "json.mcap"
    with open(path, "wb") as f:
        w = McapWriter(f)
        w.start(profile="", library="test")
        sid = w.register_schema(name="foxglove.PoseInFrame", encoding="jsonschema", data=b"{}")
        cid = w.register_channel(topic="/pose", message_encoding="json", schema_id=sid)
        for i in range(6):
            m = {
                "timestamp": {"sec": 3, "nsec": 100_000_000 * i},
                "frame_id": "world",
                "pose": {
                    "position": {"x": i, "y": 1.5, "z": -i},
                    "orientation": {"x": 0, "y": 0, "z": 0, "w": 1},
                },
            }
            w.add_message(channel_id=cid, log_time=i, publish_time=i, data=json.dumps(m).encode())
        w.finish()
    ref = s2w.read_mcap(path).reference
    assert ref is not None
    np.testing.assert_allclose(ref.timestamps, 3.0 + 0.1 * np.arange(6), atol=1e-9)
    np.testing.assert_array_equal(ref.positions[:, 2], -np.arange(6.0))


def test_world_mcap_reads_back_with_python_mcap(tmp_path: Path) -> None:
    rng = np.random.default_rng(11)
    pts = rng.normal(size=(500, 3)).astype(np.float32)
    cols = rng.integers(0, 256, (500, 3), dtype=np.uint8)
    t = s2w.Sim3.from_quaternion([0.0, 0.0, np.sin(0.2), np.cos(0.2)], [1.0, 2.0, 3.0], 2.0)
    path = tmp_path / "world.mcap"
    s2w.write_world_mcap(path, pts, cols, transform=t, stamp=7.25)
    seen: dict[str, Any] = {}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[ProtobufDecoderFactory()])
        for schema, channel, _, msg in reader.iter_decoded_messages():
            seen[schema.name] = (channel.topic, msg)
    assert set(seen) == {"foxglove.PointCloud", "foxglove.FrameTransform"}
    _, cloud = seen["foxglove.PointCloud"]
    assert cloud.point_stride == 16
    assert cloud.frame_id == "world"
    assert cloud.timestamp.seconds == 7 and cloud.timestamp.nanos == 250_000_000
    fields = {f.name: (f.offset, f.type) for f in cloud.fields}
    assert fields == {
        "x": (0, 7),
        "y": (4, 7),
        "z": (8, 7),
        "red": (12, 1),
        "green": (13, 1),
        "blue": (14, 1),
        "alpha": (15, 1),
    }
    rec = np.frombuffer(cloud.data, dtype=[("p", "<f4", (3,)), ("c", "u1", (4,))])
    assert len(rec) == 500
    np.testing.assert_array_equal(rec["p"], pts)
    np.testing.assert_array_equal(rec["c"][:, :3], cols)
    assert np.all(rec["c"][:, 3] == 255)
    _, tf = seen["foxglove.FrameTransform"]
    assert (tf.parent_frame_id, tf.child_frame_id) == ("world", "slam")
    np.testing.assert_allclose(
        [tf.translation.x, tf.translation.y, tf.translation.z], [1.0, 2.0, 3.0]
    )
    np.testing.assert_allclose(
        [tf.rotation.x, tf.rotation.y, tf.rotation.z, tf.rotation.w], t.quaternion
    )


def test_errors(tmp_path: Path) -> None:
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"not an mcap file at all")
    with pytest.raises(s2w.FormatError, match="magic"):
        s2w.read_mcap(bad)
    with pytest.raises(s2w.FileError):
        s2w.read_mcap(tmp_path / "missing.mcap")
    path = tmp_path / "lsd.mcap"
    _write_lsd_log(path)
    with pytest.raises(s2w.FormatError, match="/nope"):
        s2w.read_mcap(path, pose_topic="/nope")
    with pytest.raises(s2w.InvalidInputError, match="colors"):
        s2w.write_world_mcap(
            tmp_path / "w.mcap", np.zeros((4, 3)), np.zeros((3, 3), dtype=np.uint8)
        )
    assert not (tmp_path / "w.mcap").exists()


def _rot(q: np.ndarray) -> np.ndarray:
    x, y, z, w = q / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


S_TRUE, R_TRUE, T_TRUE = 2.0, _rot(np.array([0.1, -0.3, 0.4, 0.85])), np.array([1.0, -2.0, 0.5])


def _write_aligned_lsd_log(
    path: Path, noise: float = 0.0, outliers: tuple[int, ...] = ()
) -> np.ndarray:
    """An LSD-SLAM log written with mcap-ros1-support (8 keyframes on /lsd_slam/keyframes),
    its reference on /mocap/pose made with T_world_slam = (S_TRUE, R_TRUE, T_TRUE), plus
    Gaussian `noise` (metres, per axis) and 1 m along x at the keyframes in `outliers`.
    Returns the expected world points (every pixel with a depth, keyframe order)."""
    rng = np.random.default_rng(21)
    noise_rng = np.random.default_rng(22)
    s_true, r_true, t_true = S_TRUE, R_TRUE, T_TRUE
    Kf = _cls("lsd_slam_viewer/keyframeMsg", KEYFRAME_MSG)
    Pose = _cls("geometry_msgs/PoseStamped", POSE_STAMPED)
    fx, fy, cx, cy = 5.0, 5.0, 2.5, 1.5
    expected = []
    with open(path, "wb") as f:
        w = Ros1Writer(f)
        for i in range(8):
            a = 0.5 * i
            q = np.array([0.0, np.sin(0.05 * a), 0.0, np.cos(0.05 * a)], dtype=np.float32)
            tr = np.array([np.cos(a), np.sin(a), 0.3 * a], dtype=np.float32)
            idepth = rng.uniform(0.5, 2.0, (H, W)).astype(np.float32)
            idepth[0, 0] = 0.0  # no depth: no point
            rec = np.zeros((H, W), dtype=[("d", "<f4"), ("v", "<f4"), ("c", "u1", (4,))])
            rec["d"] = idepth
            rec["c"] = 200
            c2w = [float(v) for v in q] + [float(v) for v in tr]
            w.write_message(
                "/lsd_slam/keyframes",
                Kf(
                    id=i,
                    time=20.0 + i,
                    isKeyframe=True,
                    camToWorld=c2w,
                    fx=fx,
                    fy=fy,
                    cx=cx,
                    cy=cy,
                    height=H,
                    width=W,
                    pointcloud=rec.tobytes(),
                ),
                log_time=i,
            )
            # reference: the camera position in the world
            p_world = s_true * r_true @ tr.astype(np.float64) + t_true
            p_world = p_world + noise * noise_rng.normal(size=3)
            if i in outliers:
                p_world = p_world + np.array([1.0, 0.0, 0.0])
            m = Pose()
            m.header.stamp.secs = 20 + i
            m.header.frame_id = "world"
            m.pose.position.x, m.pose.position.y, m.pose.position.z = p_world
            m.pose.orientation.w = 1.0
            w.write_message("/mocap/pose", m, log_time=i)
            ys, xs = np.nonzero(idepth > 0)
            d = 1.0 / idepth[ys, xs].astype(np.float64)
            p_cam = np.stack([(xs - cx) / fx * d, (ys - cy) / fy * d, d], axis=1)
            r_kf = _rot(q.astype(np.float64))
            s_kf = float(np.linalg.norm(q.astype(np.float64)))
            p_slam = s_kf * p_cam @ r_kf.T + tr.astype(np.float64)
            expected.append(s_true * p_slam @ r_true.T + t_true)
        w.finish()
    return np.concatenate(expected)


def test_convert_writes_a_world_the_python_reader_decodes(tmp_path: Path) -> None:
    """An LSD-SLAM log written with mcap-ros1-support, its reference made with a known
    T_world_slam: convert recovers it and world.mcap holds the world points."""
    path = tmp_path / "lsd.mcap"
    want = _write_aligned_lsd_log(path)

    conv = s2w.convert(path, filter=s2w.PointFilter.none())
    assert conv.transform.scale == pytest.approx(S_TRUE, rel=1e-5)
    np.testing.assert_allclose(conv.transform.rotation, R_TRUE, atol=1e-5)
    assert conv.report["frames_used"] == 8
    assert conv.report["reference_topic"] == "/mocap/pose"
    assert conv.cloud.points.shape == want.shape
    conv.write_all(tmp_path / "out")
    for name in ["world.mcap", "cloud.ply", "report.json"]:
        assert (tmp_path / "out" / name).exists()

    with open(tmp_path / "out" / "world.mcap", "rb") as f:
        reader = make_reader(f, decoder_factories=[ProtobufDecoderFactory()])
        clouds = [
            msg
            for schema, _, _, msg in reader.iter_decoded_messages()
            if schema.name == "foxglove.PointCloud"
        ]
    assert len(clouds) == 1
    rec = np.frombuffer(clouds[0].data, dtype=[("p", "<f4", (3,)), ("c", "u1", (4,))])
    assert len(rec) == len(want) == 8 * (W * H - 1)
    np.testing.assert_allclose(rec["p"], want, atol=1e-3)
    assert np.all(rec["c"][:, :3] == 200)

    # The same from a Log object; no reference match: a FormatError naming the topics.
    log = s2w.read_mcap(path)
    assert len(s2w.convert(log, filter=s2w.PointFilter.none()).cloud.points) == len(want)
    with pytest.raises(s2w.FormatError, match="/mocap/pose"):
        s2w.convert(log, offset=100.0)


def _sorted_rows(a: np.ndarray) -> np.ndarray:
    return a[np.lexsort(a.T[::-1])]


def test_convert_with_an_octree_writes_cubes_and_a_bt_octomap_reads(tmp_path: Path) -> None:
    """convert(octree_resolution=0.1): the SceneUpdate in world.mcap decodes (protobuf) to
    one cube per occupied leaf with the leaf's size; octomap-python reads map.bt."""
    octomap = pytest.importorskip("octomap")
    path = tmp_path / "lsd.mcap"
    want = _write_aligned_lsd_log(path)
    conv = s2w.convert(path, filter=s2w.PointFilter.none(), octree_resolution=0.1)
    m = conv.octree
    assert isinstance(m, s2w.OccupancyMap)
    assert m.resolution == 0.1
    centres, sizes = m.occupied_leaves()
    assert len(centres) > 20
    report = conv.report["octree"]
    assert report["resolution"] == 0.1
    assert report["leaves_occupied"] == len(centres)
    assert report["points"] == len(want)
    # Occupied voxels hold converted points: each occupied voxel centre lies within
    # half a voxel (per axis) of a point.
    occ = m.occupied_centers()
    d = np.abs(occ[:, None, :] - conv.cloud.points[None, :, :].astype(np.float64)).max(axis=2)
    assert np.all(d.min(axis=1) <= 0.05 + 1e-6)
    assert np.mean(m.state(conv.cloud.points) == 1) > 0.5

    out = tmp_path / "out"
    conv.write_all(out)
    assert (out / "map.bt").exists()
    with open(out / "world.mcap", "rb") as f:
        reader = make_reader(f, decoder_factories=[ProtobufDecoderFactory()])
        updates = [
            (channel.topic, msg)
            for schema, channel, _, msg in reader.iter_decoded_messages()
            if schema.name == "foxglove.SceneUpdate"
        ]
    assert len(updates) == 1
    topic, update = updates[0]
    assert topic == "/slam2world/octomap"
    assert len(update.entities) == 1
    entity = update.entities[0]
    assert entity.frame_id == "world"
    assert len(entity.cubes) == len(centres)
    got = np.array(
        [
            [c.pose.position.x, c.pose.position.y, c.pose.position.z, c.size.x, c.size.y, c.size.z]
            for c in entity.cubes
        ]
    )
    np.testing.assert_allclose(got[:, 3], got[:, 4])
    np.testing.assert_allclose(got[:, 3], got[:, 5])
    expected = np.column_stack([centres, sizes, sizes, sizes])
    np.testing.assert_allclose(_sorted_rows(got), _sorted_rows(expected), atol=1e-9)
    rgba = np.array([[c.color.r, c.color.g, c.color.b, c.color.a] for c in entity.cubes])
    assert np.all((rgba >= 0.0) & (rgba <= 1.0)) and np.all(rgba[:, 3] == 1.0)
    # Coloured by height: the lowest cube blue, the highest red.
    assert rgba[np.argmin(got[:, 2]), 2] == 1.0 and rgba[np.argmax(got[:, 2]), 0] == 1.0

    tree = octomap.OcTree(0.1)
    assert tree.readBinary(str(out / "map.bt").encode())
    assert tree.getResolution() == pytest.approx(0.1)
    n_occ = 0
    for leaf in tree.begin_leafs():
        if tree.isNodeOccupied(leaf):
            n_occ += round(leaf.getSize() / 0.1) ** 3
    assert n_occ == len(occ)
    assert all(tree.isNodeOccupied(tree.search(c)) for c in occ)

    conv.write_bt(tmp_path / "again.bt")
    assert (tmp_path / "again.bt").read_bytes() == (out / "map.bt").read_bytes()
    plain = s2w.convert(path, filter=s2w.PointFilter.none())
    assert plain.octree is None and "octree" not in plain.report
    with pytest.raises(s2w.InvalidInputError, match="octree"):
        plain.write_bt(tmp_path / "none.bt")
    with pytest.raises(s2w.InvalidInputError, match="resolution"):
        s2w.convert(path, octree_resolution=0.0)


def test_convert_beyond_one_fit(tmp_path: Path) -> None:
    """convert takes align_trajectories' options beyond one fit: the start-up cut drops
    exactly the first pairs, RANSAC flags the displaced pose, and the alignment carries
    a covariance whose scale interval brackets the scale (and agrees with the report)."""
    path = tmp_path / "lsd.mcap"
    _write_aligned_lsd_log(path, noise=0.01, outliers=(5,))
    none = s2w.PointFilter.none()

    conv = s2w.convert(path, filter=none, skip_init=3)
    rep = conv.report
    assert conv.alignment.fit_start == rep["fit"]["fit_start"] == 3
    assert [p["fitted"] for p in rep["pairs"]] == [k >= 3 for k in range(8)]
    assert rep["pairs_fitted"] == 5
    assert conv.alignment.n_pairs == 8
    assert len(conv.alignment.alignment.residuals) == 5
    assert conv.alignment.transform.scale == pytest.approx(conv.transform.scale, rel=1e-12)
    assert conv.alignment.inliers is None

    conv = s2w.convert(path, filter=none, robust="ransac", inlier_threshold=0.2)
    mask = conv.alignment.inliers
    assert mask is not None and mask.shape == (8,) and mask.dtype == np.bool_
    assert list(np.flatnonzero(~mask)) == [5]
    assert conv.report["fit"]["n_outliers"] == 1
    assert [p["fitted"] for p in conv.report["pairs"]] == list(mask)
    scale = conv.transform.scale
    assert conv.alignment.transform.scale == pytest.approx(scale, rel=1e-12)
    lo, hi = conv.alignment.scale_interval(0.95)
    assert lo < scale < hi
    assert lo < S_TRUE < hi
    assert hi - lo < 0.1 * S_TRUE
    assert [lo, hi] == pytest.approx(conv.report["fit"]["intervals"]["scale"], rel=1e-9)
    assert conv.alignment.covariance.shape == (7, 7)

    # From a Log too, with a windowed comparison in the report.
    log = s2w.read_mcap(path)
    conv = s2w.convert(log, filter=none, skip_init=2, compare_windowed=4)
    assert conv.alignment.fit_start == 2
    assert conv.report["windowed"]["windowed_rmse"] >= 0.0
    assert conv.report["windowed"]["cloud"] == "single"
    # The cloud carried keyframe by keyframe with the windowed fit: as many
    # points, the single fit still reported.
    conv_w = s2w.convert(log, filter=none, skip_init=2, compare_windowed=4, windowed_cloud=True)
    assert conv_w.report["windowed"]["cloud"] == "windowed"
    assert len(conv_w.cloud) == len(conv.cloud)
    assert conv_w.transform.scale == pytest.approx(conv.transform.scale, rel=1e-12)
    with pytest.raises(s2w.InvalidInputError, match="windowed_cloud"):
        s2w.convert(log, windowed_cloud=True)

    with pytest.raises(s2w.InvalidInputError, match="robust"):
        s2w.convert(path, robust="lmeds")
    with pytest.raises(s2w.InvalidInputError, match="inlier_threshold"):
        s2w.convert(path, inlier_threshold=0.1)
    with pytest.raises(s2w.InvalidInputError, match="skip_init"):
        s2w.convert(path, skip_init="sometimes")
    with pytest.raises(s2w.InvalidInputError, match="compare_windowed"):
        s2w.convert(path, compare_windowed="wide")  # type: ignore[arg-type]
