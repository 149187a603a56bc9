"""Writes the ROS bag fixtures of tests/it/rosbag.rs with the independent `rosbags` package.

    .venv/bin/python tests/data/rosbag/make_fixtures.py

ROS 1 (`ros1_{none,bz2,lz4}.bag`, the same messages three times): LSD-SLAM
`lsd_slam_viewer/keyframeMsg` (8x6 keyframes and live frames) and
`keyframeGraphMsg` (registered from their .msg text), `geometry_msgs/PoseStamped`
and `sensor_msgs/Imu`. Chunks are kept small (4 KiB) so that each bag has several,
and the graph connection is added after the first chunks were written (as a
recorder that sees the topic late does). Expected records: `ros1_expected.json`.

ROS 2 (`ros2_{sqlite3,mcap}_{none,file,message}/`, the same messages six times):
`geometry_msgs/PoseStamped`, `nav_msgs/Odometry`, `tf2_msgs/TFMessage`,
`sensor_msgs/Imu`, zstd per file and per message. Expected: `ros2_expected.json`.

Each expected record is `{topic, type, time (ns), data (hex of the serialised
message)}`, in time order. Everything is seeded: running the script again writes
the same messages.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

HERE = Path(__file__).resolve().parent

KEYFRAME_MSG = """\
int32 id
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

GRAPH_MSG = """\
uint32 numFrames
uint8[] frameData
uint32 numConstraints
uint8[] constraintsData
"""

T0 = 1_700_000_000_000_000_000  # ns
W, H = 8, 6


def ros1_store() -> Any:
    store = get_typestore(Stores.ROS1_NOETIC)
    types = {}
    types.update(get_types_from_msg(KEYFRAME_MSG, "lsd_slam_viewer/msg/keyframeMsg"))
    types.update(get_types_from_msg(GRAPH_MSG, "lsd_slam_viewer/msg/keyframeGraphMsg"))
    store.register(types)
    return store


def stamp(store: Any, ns: int) -> Any:
    return store.types["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)


def header(store: Any, ns: int, frame: str, ros1: bool) -> Any:
    h = store.types["std_msgs/msg/Header"]
    if ros1:
        return h(seq=0, stamp=stamp(store, ns), frame_id=frame)
    return h(stamp=stamp(store, ns), frame_id=frame)


def pose(store: Any, rng: np.random.Generator) -> Any:
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    p = rng.normal(size=3)
    t = store.types
    return t["geometry_msgs/msg/Pose"](
        position=t["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=p[2]),
        orientation=t["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]),
    )


def imu(store: Any, ns: int, rng: np.random.Generator, ros1: bool) -> Any:
    t = store.types
    v = t["geometry_msgs/msg/Vector3"]
    g = rng.normal(size=3) * 0.1
    a = rng.normal(size=3) * 0.2 + np.array([0.0, 0.0, 9.81])
    return t["sensor_msgs/msg/Imu"](
        header=header(store, ns, "imu", ros1),
        orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.full(9, -1.0),
        angular_velocity=v(x=g[0], y=g[1], z=g[2]),
        angular_velocity_covariance=np.eye(3).ravel() * 1e-4,
        linear_acceleration=v(x=a[0], y=a[1], z=a[2]),
        linear_acceleration_covariance=np.eye(3).ravel() * 1e-2,
    )


def keyframe(store: Any, i: int, ns: int, rng: np.random.Generator, is_kf: bool) -> Any:
    q = rng.normal(size=4)
    q *= (1.0 + 0.1 * i) / np.linalg.norm(q)  # non-unit: the norm is the Sim(3) scale
    cam = np.concatenate([q, rng.normal(size=3)]).astype(np.float32)
    if is_kf:
        points = np.zeros(W * H, dtype=[("i", "<f4"), ("v", "<f4"), ("c", "u1", 4)])
        points["i"] = rng.uniform(0.2, 2.0, W * H)
        points["v"] = rng.uniform(1e-4, 1e-2, W * H)
        points["c"] = rng.integers(0, 256, (W * H, 4))
        cloud = np.frombuffer(points.tobytes(), dtype=np.uint8)
    else:
        cloud = np.zeros(0, dtype=np.uint8)
    return store.types["lsd_slam_viewer/msg/keyframeMsg"](
        id=i,
        time=ns / 1e9,
        isKeyframe=is_kf,
        camToWorld=cam,
        fx=6.0,
        fy=6.5,
        cx=3.5,
        cy=2.5,
        height=H,
        width=W,
        pointcloud=cloud,
    )


def graph(store: Any, ids: list[int], rng: np.random.Generator) -> Any:
    frames = np.zeros(len(ids), dtype=[("id", "<i4"), ("c", "<f4", 7)])
    frames["id"] = ids
    frames["c"] = rng.normal(size=(len(ids), 7))
    return store.types["lsd_slam_viewer/msg/keyframeGraphMsg"](
        numFrames=len(ids),
        frameData=np.frombuffer(frames.tobytes(), dtype=np.uint8),
        numConstraints=0,
        constraintsData=np.zeros(0, dtype=np.uint8),
    )


Record = tuple[int, str, str, bytes]  # time, topic, type, data


def ros1_records() -> list[Record]:
    """The ROS 1 messages: (time ns, topic, type, serialised bytes), time order."""
    store = ros1_store()
    rng = np.random.default_rng(14)
    out: list[Record] = []

    def add(ns: int, topic: str, ty: str, msg: Any) -> None:
        out.append((ns, topic, ty, bytes(store.serialize_ros1(msg, ty))))

    for k in range(40):  # poses, 20 Hz
        ns = T0 + k * 50_000_000
        ps = store.types["geometry_msgs/msg/PoseStamped"](
            header=header(store, ns, "world", True), pose=pose(store, rng)
        )
        add(ns + 1_000, "/vicon/pose", "geometry_msgs/msg/PoseStamped", ps)
    for k in range(40):  # imu, 200 Hz over 0.2 s
        ns = T0 + k * 5_000_000 + 2_000
        add(ns, "/imu0", "sensor_msgs/msg/Imu", imu(store, ns, rng, True))
    kf_ids: list[int] = []
    for k in range(16):  # keyframes and live frames
        ns = T0 + k * 180_000_000 + 3_000
        is_kf = k % 4 != 3
        kid = len(kf_ids) if is_kf else max(kf_ids, default=0)
        if is_kf and k % 5 == 4 and kf_ids:
            kid = kf_ids[-1]  # the same id refined again
        elif is_kf:
            kf_ids.append(kid)
        msg = keyframe(store, kid, ns, rng, is_kf)
        add(ns, "/lsd_slam/keyframes", "lsd_slam_viewer/msg/keyframeMsg", msg)
    for k in range(4):
        ns = T0 + 700_000_000 + k * 600_000_000 + 4_000
        msg = graph(store, kf_ids[: 3 + 2 * k], rng)
        add(ns, "/lsd_slam/graph", "lsd_slam_viewer/msg/keyframeGraphMsg", msg)
    out.sort(key=lambda r: r[0])
    return out


def write_ros1(path: Path, records: list[Record], fmt: Writer1.CompressionFormat | None) -> None:
    store = ros1_store()
    path.unlink(missing_ok=True)
    writer = Writer1(path)
    writer.chunk_threshold = 4096
    if fmt is not None:
        writer.set_compression(fmt)
    with writer:
        conns = {}
        late = "/lsd_slam/graph"
        for _, topic, ty, _ in records:
            if topic not in conns and topic != late:
                conns[topic] = writer.add_connection(topic, ty, typestore=store)
        for i, (ns, topic, ty, data) in enumerate(records):
            if topic == late and topic not in conns:
                assert i > 50, "the graph connection should come after some chunks"
                conns[topic] = writer.add_connection(topic, ty, typestore=store, callerid="/lsd")
            writer.write(conns[topic], ns, data)


def ros2_records() -> list[Record]:
    store = get_typestore(Stores.ROS2_HUMBLE)
    rng = np.random.default_rng(2)
    t = store.types
    out: list[Record] = []

    def add(ns: int, topic: str, ty: str, msg: Any) -> None:
        out.append((ns, topic, ty, bytes(store.serialize_cdr(msg, ty))))

    for k in range(15):
        ns = T0 + k * 50_000_000 + 1_000
        ps = t["geometry_msgs/msg/PoseStamped"](
            header=header(store, ns, "map", False), pose=pose(store, rng)
        )
        add(ns, "/pose", "geometry_msgs/msg/PoseStamped", ps)
    for k in range(15):
        ns = T0 + k * 50_000_000 + 2_000
        cov = np.zeros(36)
        odom = t["nav_msgs/msg/Odometry"](
            header=header(store, ns, "odom", False),
            child_frame_id="base_link",
            pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose(store, rng), covariance=cov),
            twist=t["geometry_msgs/msg/TwistWithCovariance"](
                twist=t["geometry_msgs/msg/Twist"](
                    linear=t["geometry_msgs/msg/Vector3"](x=0.1, y=0.0, z=0.0),
                    angular=t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.01),
                ),
                covariance=cov,
            ),
        )
        add(ns, "/odom", "nav_msgs/msg/Odometry", odom)
    for k in range(15):
        ns = T0 + k * 50_000_000 + 3_000
        p = pose(store, rng)
        tf = t["geometry_msgs/msg/TransformStamped"](
            header=header(store, ns, "odom", False),
            child_frame_id="base_footprint",
            transform=t["geometry_msgs/msg/Transform"](
                translation=t["geometry_msgs/msg/Vector3"](
                    x=p.position.x, y=p.position.y, z=p.position.z
                ),
                rotation=p.orientation,
            ),
        )
        add(ns, "/tf", "tf2_msgs/msg/TFMessage", t["tf2_msgs/msg/TFMessage"](transforms=[tf]))
    for k in range(30):
        ns = T0 + k * 25_000_000 + 4_000
        add(ns, "/imu", "sensor_msgs/msg/Imu", imu(store, ns, rng, False))
    out.sort(key=lambda r: r[0])
    return out


def write_ros2(
    path: Path, records: list[Record], storage: StoragePlugin, mode: CompressionMode | None
) -> None:
    store = get_typestore(Stores.ROS2_HUMBLE)
    if path.exists():
        shutil.rmtree(path)
    writer = Writer2(path, version=9, storage_plugin=storage)
    if mode is not None:
        writer.set_compression(mode, CompressionFormat.ZSTD)
    with writer:
        conns = {}
        for _, topic, ty, _ in records:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, ty, typestore=store)
        for ns, topic, _, data in records:
            writer.write(conns[topic], ns, data)


def dump(path: Path, records: list[Record]) -> None:
    rows = [{"topic": t, "type": ty, "time": ns, "data": d.hex()} for ns, t, ty, d in records]
    path.write_text(json.dumps(rows, indent=0) + "\n")


def main() -> None:
    r1 = ros1_records()
    write_ros1(HERE / "ros1_none.bag", r1, None)
    write_ros1(HERE / "ros1_bz2.bag", r1, Writer1.CompressionFormat.BZ2)
    write_ros1(HERE / "ros1_lz4.bag", r1, Writer1.CompressionFormat.LZ4)
    dump(HERE / "ros1_expected.json", r1)
    r2 = ros2_records()
    for storage, name in ((StoragePlugin.SQLITE3, "sqlite3"), (StoragePlugin.MCAP, "mcap")):
        for mode, mname in (
            (None, "none"),
            (CompressionMode.FILE, "file"),
            (CompressionMode.MESSAGE, "message"),
        ):
            write_ros2(HERE / f"ros2_{name}_{mname}", r2, storage, mode)
    dump(HERE / "ros2_expected.json", r2)


if __name__ == "__main__":
    main()
