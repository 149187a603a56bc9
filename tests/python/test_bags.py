"""ROS bags through one door: a bag and the MCAP log of the same messages, each
written by an independent writer (``rosbags`` for the bags, ``mcap`` with
``mcap-ros1-support`` / ``mcap-ros2-support`` for the MCAP), convert to the same
``Conversion``; ``slam2world align LOG --est-topic --ref-topic`` equals
``evo_ape bag ... -as`` on a real bag; bad input is a typed error."""

from __future__ import annotations

import json
import subprocess
import sys
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import data_path
from mcap_ros1._vendor.genpy.dynamic import generate_dynamic
from mcap_ros1.writer import Writer as Ros1McapWriter
from mcap_ros2.writer import Writer as Ros2McapWriter
from rosbags.rosbag1 import Writer as Bag1Writer
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Bag2Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

import slam2world as s2w

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

W, H = 16, 12
T0 = 1_700_000_000  # s

# T_world_slam of the session: the SLAM side is this map's inverse of the world.
SCALE = 2.5
ROT = s2w.Sim3.from_quaternion([0.1, -0.2, 0.3, 0.9], [0.0, 0.0, 0.0]).rotation
SHIFT = np.array([4.0, -1.0, 0.5])


def world_position(t: float) -> np.ndarray:
    """Where the body is at time t (seconds after T0), metres."""
    return np.array([2.0 * np.cos(0.7 * t), 1.5 * np.sin(0.9 * t), 0.3 * t])


def slam_position(t: float) -> np.ndarray:
    p: np.ndarray = ROT.T @ (world_position(t) - SHIFT) / SCALE
    return p


def ns(t: float) -> int:
    return T0 * 10**9 + int(round(t * 1e9))


# ----------------------------------------------------------------- the session


def session() -> dict[str, Any]:
    """Plain data of an LSD-SLAM session: keyframes (one re-published), live
    frames, graph updates, ground truth PoseStamped at 20 Hz, IMU at 200 Hz."""
    rng = np.random.default_rng(14)
    keyframes: list[dict[str, Any]] = []
    for k, kid in enumerate([0, 1, 2, 3, 2, 4, 5, 6, 7, 8, 9, 10]):
        t = 0.4 * k + 0.003
        q = rng.normal(size=4)
        q *= (1.0 + 0.05 * kid) / np.linalg.norm(q)  # non-unit: the norm is the scale
        rec = np.zeros((H, W), dtype=[("d", "<f4"), ("v", "<f4"), ("c", "u1", (4,))])
        rec["d"] = rng.uniform(0.3, 2.0, (H, W))
        rec["v"] = rng.uniform(1e-5, 1e-3, (H, W))
        rec["c"] = rng.integers(0, 256, (H, W, 4))
        keyframes.append(
            {
                "ns": ns(t),
                "id": kid,
                "time": T0 + t,
                "c2w": np.concatenate([q, slam_position(t)]).astype(np.float32),
                "cloud": rec.tobytes(),
            }
        )
    live = [{"ns": ns(0.4 * k + 0.2), "id": 100 + k, "time": T0 + 0.4 * k + 0.2} for k in range(10)]
    graphs = []
    for g, upto in enumerate([3, 6, 9]):
        t = 0.4 * (upto + 1) + 0.1
        frames = np.zeros(upto, dtype=[("id", "<i4"), ("c", "<f4", 7)])
        frames["id"] = np.arange(upto)
        for j in range(upto):
            # the latest version of keyframe j (id 2 is published twice)
            c = [k for k in keyframes if k["id"] == j][-1]["c2w"].copy()
            c[4:] += rng.normal(scale=1e-3, size=3)  # the graph refines the positions
            frames["c"][j] = c
        graphs.append({"ns": ns(t) + g, "frames": frames.tobytes(), "n": upto})
    poses = []
    for i in range(100):
        t = 0.05 * i
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        poses.append({"ns": ns(t) + 1000, "stamp": ns(t), "p": world_position(t), "q": q})
    imu = []
    for i in range(800):
        t = 0.005 * i
        gyro = rng.normal(size=3) * 0.1
        acc = rng.normal(size=3) * 0.2 + np.array([0.0, 0.0, 9.81])
        imu.append({"ns": ns(t) + 2000, "stamp": ns(t), "g": gyro, "a": acc})
    return {"kf": keyframes, "live": live, "graph": graphs, "poses": poses, "imu": imu}


def ros1_store() -> Any:
    store = get_typestore(Stores.ROS1_NOETIC)
    types = {}
    types.update(get_types_from_msg(KEYFRAME_MSG, "lsd_slam_viewer/msg/keyframeMsg"))
    types.update(get_types_from_msg(GRAPH_MSG, "lsd_slam_viewer/msg/keyframeGraphMsg"))
    store.register(types)
    return store


KF, GRAPH = "lsd_slam_viewer/msg/keyframeMsg", "lsd_slam_viewer/msg/keyframeGraphMsg"
POSE, IMU = "geometry_msgs/msg/PoseStamped", "sensor_msgs/msg/Imu"


def write_ros1_bag(path: Path, s: dict[str, Any], compression: str | None) -> None:
    """The session as a ROS 1 bag, serialised and written by rosbags."""
    store = ros1_store()
    t = store.types

    def stamp(n: int) -> Any:
        return t["builtin_interfaces/msg/Time"](sec=n // 10**9, nanosec=n % 10**9)

    def header(n: int, frame: str) -> Any:
        return t["std_msgs/msg/Header"](seq=0, stamp=stamp(n), frame_id=frame)

    def kf(k: dict[str, Any], live: bool) -> Any:
        cloud = np.zeros(0, np.uint8) if live else np.frombuffer(k["cloud"], np.uint8)
        c2w = np.array([0, 0, 0, 1, 0, 0, 0], np.float32) if live else k["c2w"]
        return t[KF](
            id=k["id"],
            time=k["time"],
            isKeyframe=not live,
            camToWorld=c2w,
            fx=15.0,
            fy=15.5,
            cx=7.5,
            cy=5.5,
            height=H,
            width=W,
            pointcloud=cloud,
        )

    records: list[tuple[int, str, str, Any]] = []
    records += [(k["ns"], "/lsd_slam/keyframes", KF, kf(k, False)) for k in s["kf"]]
    records += [(k["ns"], "/lsd_slam/liveframes", KF, kf(k, True)) for k in s["live"]]
    for g in s["graph"]:
        msg = t[GRAPH](
            numFrames=g["n"],
            frameData=np.frombuffer(g["frames"], np.uint8),
            numConstraints=0,
            constraintsData=np.zeros(0, np.uint8),
        )
        records.append((g["ns"], "/lsd_slam/graph", GRAPH, msg))
    for p in s["poses"]:
        pose = t["geometry_msgs/msg/Pose"](
            position=t["geometry_msgs/msg/Point"](x=p["p"][0], y=p["p"][1], z=p["p"][2]),
            orientation=t["geometry_msgs/msg/Quaternion"](
                x=p["q"][0], y=p["q"][1], z=p["q"][2], w=p["q"][3]
            ),
        )
        msg = t[POSE](header=header(p["stamp"], "world"), pose=pose)
        records.append((p["ns"], "/vicon/pose", POSE, msg))
    v3 = t["geometry_msgs/msg/Vector3"]
    for m in s["imu"]:
        msg = t[IMU](
            header=header(m["stamp"], "imu"),
            orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=np.full(9, -1.0),
            angular_velocity=v3(x=m["g"][0], y=m["g"][1], z=m["g"][2]),
            angular_velocity_covariance=np.zeros(9),
            linear_acceleration=v3(x=m["a"][0], y=m["a"][1], z=m["a"][2]),
            linear_acceleration_covariance=np.zeros(9),
        )
        records.append((m["ns"], "/imu0", IMU, msg))
    records.sort(key=lambda r: r[0])
    writer = Bag1Writer(path)
    writer.chunk_threshold = 64 * 1024  # several chunks
    if compression == "bz2":
        writer.set_compression(Bag1Writer.CompressionFormat.BZ2)
    elif compression == "lz4":
        writer.set_compression(Bag1Writer.CompressionFormat.LZ4)
    with writer:
        conns: dict[str, Any] = {}
        for n, topic, ty, msg in records:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, ty, typestore=store)
            writer.write(conns[topic], n, store.serialize_ros1(msg, ty))


def write_ros1_mcap(path: Path, s: dict[str, Any]) -> None:
    """The session as an MCAP log, serialised by genpy (mcap-ros1-support)."""
    store = ros1_store()

    def cls(ty: str, text: str | None = None) -> Any:
        name = ty.replace("/msg/", "/")
        return generate_dynamic(name, text or store.generate_msgdef(ty)[0])[name]  # type: ignore[no-untyped-call]

    Kf, Graph, Pose, Imu = cls(KF, KEYFRAME_MSG), cls(GRAPH, GRAPH_MSG), cls(POSE), cls(IMU)

    def stamp(obj: Any, n: int) -> None:
        obj.secs, obj.nsecs = n // 10**9, n % 10**9

    records: list[tuple[int, str, Any]] = []
    for k in s["kf"]:
        msg = Kf(
            id=k["id"],
            time=k["time"],
            isKeyframe=True,
            camToWorld=[float(v) for v in k["c2w"]],
            fx=15.0,
            fy=15.5,
            cx=7.5,
            cy=5.5,
            height=H,
            width=W,
            pointcloud=k["cloud"],
        )
        records.append((k["ns"], "/lsd_slam/keyframes", msg))
    for k in s["live"]:
        msg = Kf(
            id=k["id"],
            time=k["time"],
            isKeyframe=False,
            camToWorld=[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
            fx=15.0,
            fy=15.5,
            cx=7.5,
            cy=5.5,
            height=H,
            width=W,
            pointcloud=b"",
        )
        records.append((k["ns"], "/lsd_slam/liveframes", msg))
    for g in s["graph"]:
        msg = Graph(numFrames=g["n"], frameData=g["frames"], numConstraints=0, constraintsData=b"")
        records.append((g["ns"], "/lsd_slam/graph", msg))
    for p in s["poses"]:
        m = Pose()
        stamp(m.header.stamp, p["stamp"])
        m.header.frame_id = "world"
        m.pose.position.x, m.pose.position.y, m.pose.position.z = (float(v) for v in p["p"])
        o = m.pose.orientation
        o.x, o.y, o.z, o.w = (float(v) for v in p["q"])
        records.append((p["ns"], "/vicon/pose", m))
    for i in s["imu"]:
        m = Imu()
        stamp(m.header.stamp, i["stamp"])
        m.header.frame_id = "imu"
        m.orientation.w = 1.0
        m.orientation_covariance = [-1.0] * 9
        g, a = m.angular_velocity, m.linear_acceleration
        g.x, g.y, g.z = (float(v) for v in i["g"])
        a.x, a.y, a.z = (float(v) for v in i["a"])
        records.append((i["ns"], "/imu0", m))
    records.sort(key=lambda r: r[0])
    with open(path, "wb") as f:
        w = Ros1McapWriter(f)
        for n, topic, msg in records:
            w.write_message(topic, msg, log_time=n, publish_time=n)
        w.finish()  # type: ignore[no-untyped-call]


def assert_same_conversion(a: s2w.Conversion, b: s2w.Conversion, what: str) -> None:
    np.testing.assert_allclose(
        a.transform.matrix(), b.transform.matrix(), rtol=0, atol=1e-12, err_msg=what
    )
    assert a.cloud.points.tobytes() == b.cloud.points.tobytes(), what
    ca, cb = a.cloud.colors, b.cloud.colors
    assert (ca is None) == (cb is None), what
    if ca is not None and cb is not None:
        assert ca.tobytes() == cb.tobytes(), what
    np.testing.assert_array_equal(a.cloud.keyframe_ids, b.cloud.keyframe_ids, err_msg=what)
    ra, rb = dict(a.report), dict(b.report)
    for key in ("input", "format", "timing"):
        ra.pop(key, None)
        rb.pop(key, None)
    assert ra == rb, what


def test_ros1_bags_convert_like_the_mcap_of_the_same_messages(tmp_path: Path) -> None:
    s = session()
    mcap = tmp_path / "session.mcap"
    write_ros1_mcap(mcap, s)
    ref = s2w.convert(mcap, filter=s2w.PointFilter.none())
    assert ref.report["format"] == "mcap"
    # The fit finds the session's T_world_slam (the graph moved positions by 1 mm).
    assert abs(ref.transform.scale - SCALE) < 0.01
    assert len(ref.cloud.points) > 1000
    assert ref.report["graph_topic"] == "/lsd_slam/graph"
    assert ref.report["imu"] is not None
    for compression in (None, "bz2", "lz4"):
        bag = tmp_path / f"session_{compression}.bag"
        write_ros1_bag(bag, s, compression)
        conv = s2w.convert(bag, filter=s2w.PointFilter.none())
        assert conv.report["format"] == "ros1 bag"
        assert_same_conversion(conv, ref, f"bag {compression}")
        # The Log is the same too, through read_log and a Log object.
        log = s2w.read_log(bag)
        assert log.format == "ros1 bag"
        assert [k.id for k in log.keyframes] == list(range(11))
        assert log.graph_updates == 3 + 6 + 9
        assert_same_conversion(s2w.convert(log, filter=s2w.PointFilter.none()), ref, "Log")
    # read_log of an MCAP file is read_mcap's log.
    a, b = s2w.read_log(mcap), s2w.read_mcap(mcap)
    assert a.topics == b.topics and len(a.keyframes) == len(b.keyframes)


# ----------------------------------------------------------------------- ROS 2


def ros2_session() -> list[tuple[int, str, str, dict[str, Any]]]:
    """A ROS 2 session as plain dicts: SLAM odometry (arbitrary scale and
    frame), ground truth PoseStamped, the same as TF, IMU."""
    rng = np.random.default_rng(2)
    out: list[tuple[int, str, str, dict[str, Any]]] = []

    def header(n: int, frame: str) -> dict[str, Any]:
        return {"stamp": {"sec": n // 10**9, "nanosec": n % 10**9}, "frame_id": frame}

    def pose(p: np.ndarray, q: np.ndarray) -> dict[str, Any]:
        return {
            "position": {"x": p[0], "y": p[1], "z": p[2]},
            "orientation": {"x": q[0], "y": q[1], "z": q[2], "w": q[3]},
        }

    zero3 = {"x": 0.0, "y": 0.0, "z": 0.0}
    for i in range(60):
        t = 0.1 * i
        n = ns(t)
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        p = world_position(t)
        out.append((n + 1000, "/gt", POSE, {"header": header(n, "map"), "pose": pose(p, q)}))
        tf = {
            "header": header(n, "map"),
            "child_frame_id": "base_link",
            "transform": {
                "translation": {"x": p[0], "y": p[1], "z": p[2]},
                "rotation": {"x": q[0], "y": q[1], "z": q[2], "w": q[3]},
            },
        }
        out.append((n + 2000, "/tf", "tf2_msgs/msg/TFMessage", {"transforms": [tf]}))
        if i % 2 == 0:
            ps = slam_position(t) + rng.normal(scale=1e-3, size=3)
            odom = {
                "header": header(n + 3000, "odom"),
                "child_frame_id": "camera",
                "pose": {"pose": pose(ps, q), "covariance": [0.0] * 36},
                "twist": {"twist": {"linear": zero3, "angular": zero3}, "covariance": [0.0] * 36},
            }
            out.append((n + 3000, "/odom", "nav_msgs/msg/Odometry", odom))
    for i in range(300):
        n = ns(0.02 * i)
        g = rng.normal(size=3) * 0.1
        a = rng.normal(size=3) * 0.2 + np.array([0.0, 0.0, 9.81])
        imu = {
            "header": header(n, "imu"),
            "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
            "orientation_covariance": [-1.0] * 9,
            "angular_velocity": {"x": g[0], "y": g[1], "z": g[2]},
            "angular_velocity_covariance": [0.0] * 9,
            "linear_acceleration": {"x": a[0], "y": a[1], "z": a[2]},
            "linear_acceleration_covariance": [0.0] * 9,
        }
        out.append((n + 4000, "/imu", IMU, imu))
    out.sort(key=lambda r: r[0])
    return out


def _build(store: Any, ty: str, value: Any) -> Any:
    """A rosbags message of type `ty` from a plain dict."""
    cls = store.types[ty]
    fields = store.fielddefs[ty][1]
    kwargs = {}
    for name, (kind, sub) in fields:
        v = value[name]
        if kind == 2:  # a nested message
            kwargs[name] = _build(store, sub, v)
        elif kind in (3, 4) and isinstance(v, list) and v and isinstance(v[0], dict):
            kwargs[name] = [_build(store, sub[0][1], x) for x in v]
        elif kind in (3, 4):
            kwargs[name] = np.array(v, dtype=np.float64)
        else:
            kwargs[name] = v
    return cls(**kwargs)


def write_ros2_bag(path: Path, records: list[Any], storage: StoragePlugin) -> None:
    store = get_typestore(Stores.ROS2_HUMBLE)
    with Bag2Writer(path, version=8, storage_plugin=storage) as w:
        conns: dict[str, Any] = {}
        for n, topic, ty, value in records:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, ty, typestore=store)
            w.write(conns[topic], n, store.serialize_cdr(_build(store, ty, value), ty))


def write_ros2_mcap(path: Path, records: list[Any]) -> None:
    store = get_typestore(Stores.ROS2_HUMBLE)
    with open(path, "wb") as f:
        w = Ros2McapWriter(f)
        schemas: dict[str, Any] = {}
        for n, topic, ty, value in records:
            if ty not in schemas:
                schemas[ty] = w.register_msgdef(ty, store.generate_msgdef(ty, ros_version=2)[0])
            w.write_message(topic, schemas[ty], value, log_time=n, publish_time=n)
        w.finish()  # type: ignore[no-untyped-call]


def test_ros2_bags_convert_like_the_mcap_of_the_same_messages(tmp_path: Path) -> None:
    records = ros2_session()
    mcap = tmp_path / "session.mcap"
    write_ros2_mcap(mcap, records)
    db3 = tmp_path / "db3_folder"
    write_ros2_bag(db3, records, StoragePlugin.SQLITE3)
    folder = tmp_path / "mcap_folder"
    write_ros2_bag(folder, records, StoragePlugin.MCAP)
    lone = next(db3.glob("*.db3"))
    for opts in (
        {"est_topic": "/odom"},
        {"est_topic": "/odom", "pose_topic": "/tf", "tf_parent": "map", "tf_child": "base_link"},
    ):
        ref = s2w.convert(mcap, **opts)  # type: ignore[arg-type]
        assert abs(ref.transform.scale - SCALE) < 0.01
        assert ref.report["imu"] is not None
        assert len(ref.cloud.points) == 0  # poses only: no depth
        for path, fmt in (
            (db3, "rosbag2 folder"),
            (folder, "rosbag2 folder"),
            (lone, "rosbag2 db3"),
        ):
            conv = s2w.convert(path, **opts)  # type: ignore[arg-type]
            assert conv.report["format"] == fmt
            assert_same_conversion(conv, ref, f"{path.name} {opts}")
    log = s2w.read_log(db3, est_topic="/odom")
    assert log.est_topic == "/odom" and log.reference_topic == "/gt" and log.imu_topic == "/imu"
    assert log.frames is not None and len(log.frames) == 30
    assert not log.keyframes


# ------------------------------------------------------- TransformStamped


TFS = "geometry_msgs/msg/TransformStamped"


def test_transform_stamped_reads_from_ros1_and_cdr(tmp_path: Path) -> None:
    """geometry_msgs/TransformStamped (a motion-capture body) in a ROS 1 bag
    (ros1) and a rosbag2 .db3 (cdr), both written by rosbags, read as the
    reference with the header stamps, translations and unit rotations given."""
    rng = np.random.default_rng(7)
    n = 25
    stamps = [ns(0.04 * i) + 17 for i in range(n)]
    pos = rng.normal(size=(n, 3)) * 3.0
    quat = rng.normal(size=(n, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    quat[quat[:, 3] < 0] *= -1  # w >= 0; read back, q and -q are the same rotation

    def value(i: int) -> dict[str, Any]:
        return {
            "header": {
                "stamp": {"sec": stamps[i] // 10**9, "nanosec": stamps[i] % 10**9},
                "frame_id": "mocap",
            },
            "child_frame_id": "body",
            "transform": {
                "translation": dict(zip("xyz", pos[i], strict=True)),
                "rotation": dict(zip("xyzw", quat[i], strict=True)),
            },
        }

    ros1 = get_typestore(Stores.ROS1_NOETIC)
    bag = tmp_path / "mocap.bag"
    with Bag1Writer(bag) as w:
        c = w.add_connection("/mocap", TFS, typestore=ros1)
        for i in range(n):
            v = value(i)
            v["header"]["seq"] = i
            w.write(c, stamps[i] + 5000, ros1.serialize_ros1(_build(ros1, TFS, v), TFS))
    db3 = tmp_path / "mocap_db3"
    write_ros2_bag(
        db3, [(stamps[i] + 5000, "/mocap", TFS, value(i)) for i in range(n)], StoragePlugin.SQLITE3
    )
    for path, fmt in ((bag, "ros1 bag"), (db3, "rosbag2 folder")):
        log = s2w.read_log(path)
        assert log.format == fmt
        assert log.reference_topic == "/mocap", path
        r = log.reference
        assert r is not None and len(r) == n
        np.testing.assert_allclose(r.timestamps, np.array(stamps) * 1e-9, rtol=0, atol=1e-6)
        np.testing.assert_array_equal(r.positions, pos)
        o = r.orientations
        assert o is not None
        sign = np.sign(np.sum(o * quat, axis=1, keepdims=True))
        np.testing.assert_allclose(o * sign, quat, rtol=0, atol=1e-12)


# ------------------------------------------------------------------ bad input


def test_bad_bags_are_typed_errors(tmp_path: Path) -> None:
    s = session()
    bag = tmp_path / "ok.bag"
    write_ros1_bag(bag, s, "lz4")
    data = bag.read_bytes()
    cut = tmp_path / "cut.bag"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(s2w.FormatError, match="cut.bag"):
        s2w.read_log(cut)
    old = tmp_path / "old.bag"
    old.write_bytes(b"#ROSBAG V1.2\n" + data[13:])
    with pytest.raises(s2w.FormatError, match="1.2"):
        s2w.read_log(old)
    with pytest.raises(s2w.FormatError, match="/nope"):
        s2w.read_log(bag, pose_topic="/nope")
    with pytest.raises(s2w.FormatError, match="cannot be read as imu"):
        s2w.read_log(bag, imu_topic="/vicon/pose")
    db3 = tmp_path / "db3"
    write_ros2_bag(db3, ros2_session(), StoragePlugin.SQLITE3)
    (tmp_path / "nothing").mkdir()
    with pytest.raises(s2w.FormatError, match="metadata.yaml"):
        s2w.read_log(tmp_path / "nothing")
    next(db3.glob("*.db3")).unlink()
    with pytest.raises(s2w.FormatError, match="does not exist"):
        s2w.read_log(db3)
    out = tmp_path / "out"
    with pytest.raises(s2w.FormatError):
        s2w.convert(cut).write_all(out)
    assert not out.exists()


# --------------------------------------------------------------- evo on a bag


def test_align_of_two_topics_equals_evo_ape_bag(tmp_path: Path) -> None:
    bag = data_path("evo_ros1_example_bag", "ROS_example.bag")
    topics = [t[0] for t in s2w.read_log(bag).topics]
    gt = next(t for t in topics if t.strip("/") == "groundtruth")
    orb = next(t for t in topics if t.strip("/") == "ORB-SLAM")
    evo_ape = Path(sys.executable).with_name("evo_ape")
    if not evo_ape.exists():
        pytest.skip(f"evo_ape is not installed beside {sys.executable}")
    results = tmp_path / "evo.zip"
    subprocess.run(
        [str(evo_ape), "bag", str(bag), gt, orb, "-as", "--save_results", str(results)],
        check=True,
        capture_output=True,
        cwd=tmp_path,
        timeout=300,
    )
    with zipfile.ZipFile(results) as z:
        stats = json.loads(z.read("stats.json"))
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "slam2world.cli",
            "align",
            str(bag),
            "--est-topic",
            orb,
            "--ref-topic",
            gt,
            "--json",
        ],
        check=True,
        capture_output=True,
        text=True,
        timeout=300,
    )
    ours = json.loads(proc.stdout)
    assert ours["est"] == f"{bag}:{orb}" and ours["ref"] == f"{bag}:{gt}"
    for key in ("rmse", "mean", "median", "std", "min", "max"):
        assert abs(ours["ape"][key] / stats[key] - 1) < 1e-9, key
