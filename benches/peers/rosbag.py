"""ROS bag read + decode rows, beside the MCAP rows.

(a) A ROS 1 bag of small ``geometry_msgs/PoseStamped`` messages in lz4 chunks
    (768 KiB, as ``rosbag record`` writes them): ``slam2world.read_log`` against
    the Python ``rosbags`` reader + ``deserialize_ros1`` (the reader evo uses),
    timed on its first 200 000 messages at most, compared per message.
(b) ROS 1 bags of 640x480 LSD-SLAM keyframes, lz4 and bz2 chunks:
    ``slam2world.read_log`` against plain decompression of the same chunks
    (the Python ``lz4`` / ``bz2`` modules, one thread: the limit), compared per
    decompressed byte.
(c) A rosbag2 ``.db3`` of ``PoseStamped`` (cdr): ``slam2world.read_log``
    against ``rosbags``' rosbag2 reader + ``deserialize_cdr``.

Every bag is written with ``rosbags``, not with ours.
"""

from __future__ import annotations

import bz2
import struct
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

import slam2world as s2w

from .registry import Case, Skip, register

PEER_MESSAGES = 200_000
T0 = 1_500_000_000_000_000_000  # ns

KEYFRAME_MSG = (
    "int32 id\nfloat64 time\nbool isKeyframe\nfloat32[7] camToWorld\nfloat32 fx\nfloat32 fy\n"
    "float32 cx\nfloat32 cy\nuint32 height\nuint32 width\nuint8[] pointcloud\n"
)

# Bags live as long as the process (the rows' callables read them).
_TMP = tempfile.TemporaryDirectory(prefix="s2w-bench-bags-")


def _rosbags() -> Any:
    try:
        import rosbags.rosbag1
        import rosbags.rosbag2
        import rosbags.typesys
    except ImportError as e:
        raise Skip(f"rosbags is not installed ({e})") from e
    return rosbags


def _pose_ros1(i: int, ns: int) -> bytes:
    """A ROS 1 PoseStamped (seq, stamp, frame_id "world", pose)."""
    a = i * 1e-4
    head = struct.pack("<III I5s", i, ns // 10**9, ns % 10**9, 5, b"world")
    return head + struct.pack("<7d", np.sin(a), np.cos(a), 1.0, 0.0, 0.0, 0.0, 1.0)


def _pose_cdr(i: int, ns: int) -> bytes:
    """A ROS 2 PoseStamped in little-endian CDR (stamp, frame_id "world", pose)."""
    a = i * 1e-4
    # Encapsulation 00 01 (little-endian CDR), stamp, frame_id (length with the
    # NUL), then 6 bytes of padding: the doubles start 8-aligned (offset 24).
    head = b"\x00\x01\x00\x00" + struct.pack("<iII6s", ns // 10**9, ns % 10**9, 6, b"world\0")
    pad = b"\0" * 6
    return head + pad + struct.pack("<7d", np.sin(a), np.cos(a), 1.0, 0.0, 0.0, 0.0, 1.0)


def pose_bag(path: Path, n: int) -> None:
    rb = _rosbags()
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    w = rb.rosbag1.Writer(path)
    w.set_compression(rb.rosbag1.Writer.CompressionFormat.LZ4)
    with w:
        conn = w.add_connection("/groundtruth", "geometry_msgs/msg/PoseStamped", typestore=store)
        for i in range(n):
            ns = T0 + i * 5_000_000
            w.write(conn, ns, _pose_ros1(i, ns))


def pose_db3(path: Path, n: int) -> None:
    rb = _rosbags()
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    w = rb.rosbag2.Writer(path, version=8, storage_plugin=rb.rosbag2.StoragePlugin.SQLITE3)
    with w:
        conn = w.add_connection("/groundtruth", "geometry_msgs/msg/PoseStamped", typestore=store)
        for i in range(n):
            ns = T0 + i * 5_000_000
            w.write(conn, ns, _pose_cdr(i, ns))


def _keyframe(i: int, rng: np.random.Generator) -> bytes:
    w_, h_ = 640, 480
    yy, xx = np.mgrid[0:h_, 0:w_]
    rec = np.zeros((h_, w_), dtype=[("d", "<f4"), ("v", "<f4"), ("c", "u1", (4,))])
    mask = rng.random((h_, w_)) < 0.25  # semi-dense: a quarter of the pixels
    rec["d"][mask] = rng.uniform(0.5, 1.5, mask.sum())
    rec["v"][mask] = rng.uniform(0.0, 1e-4, mask.sum())
    rec["c"][..., 0] = xx // 3
    rec["c"][..., 1] = yy // 2
    rec["c"][..., 2] = (xx + yy) // 5
    blob = rec.tobytes()
    cam = (0.0, 0.0, 0.0, 1.0, 0.1 * i, 0.0, 0.0, 525.0, 525.0, 319.5, 239.5)
    return struct.pack("<idB7f4fIII", i, 1.0 + i, 1, *cam, h_, w_, len(blob)) + blob


def keyframe_bag(path: Path, k: int, compression: str) -> None:
    rb = _rosbags()
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(get_types_from_msg(KEYFRAME_MSG, "lsd_slam_viewer/msg/keyframeMsg"))
    w = rb.rosbag1.Writer(path)
    fmt = rb.rosbag1.Writer.CompressionFormat
    w.set_compression(fmt.LZ4 if compression == "lz4" else fmt.BZ2)
    rng = np.random.default_rng(0)
    with w:
        conn = w.add_connection(
            "/lsd_slam/keyframes", "lsd_slam_viewer/msg/keyframeMsg", typestore=store
        )
        for i in range(k):
            w.write(conn, T0 + i * 10**9, _keyframe(i, rng))


def _fields(header: bytes) -> dict[str, bytes]:
    out, pos = {}, 0
    while pos < len(header):
        (n,) = struct.unpack_from("<I", header, pos)
        name, _, value = header[pos + 4 : pos + 4 + n].partition(b"=")
        out[name.decode()] = value
        pos += 4 + n
    return out


def bag_chunks(path: Path) -> Iterator[tuple[str, bytes, int]]:
    """(compression, data, uncompressed size) of every chunk record of a ROS 1 bag."""
    buf = path.read_bytes()
    pos = len(b"#ROSBAG V2.0\n")
    while pos < len(buf):
        (hl,) = struct.unpack_from("<I", buf, pos)
        h = _fields(buf[pos + 4 : pos + 4 + hl])
        (dl,) = struct.unpack_from("<I", buf, pos + 4 + hl)
        data = buf[pos + 8 + hl : pos + 8 + hl + dl]
        if h["op"] == b"\x05":
            yield h["compression"].decode(), data, struct.unpack("<I", h["size"])[0]
        pos += 8 + hl + dl


@register(
    "rosbag",
    "read_log ros1 bag PoseStamped (lz4)",
    peer="rosbags Reader + deserialize_ros1",
    size=10**6,
    quick_size=10**5,
    smoke_size=500,
    target=30,
    unit="messages",
    issue="#14",
)
def _ros1_poses(n: int) -> Case:
    return _pose_row(n, "ros1")


def _pose_row(n: int, kind: str) -> Case:
    """``read_log(...).reference`` of ``n`` PoseStamped against ``rosbags``' reader
    and deserialiser of that bag kind (``ros1``: a ``.bag``; ``ros2``: a ``.db3``),
    the peer timed on its first ``PEER_MESSAGES``."""
    rb = _rosbags()
    from rosbags.typesys import Stores, get_typestore

    if kind == "ros1":
        path = Path(_TMP.name) / f"poses_{n}_lz4.bag"
        write, store = pose_bag, get_typestore(Stores.ROS1_NOETIC)
        reader, deserialize = rb.rosbag1.Reader, store.deserialize_ros1
    else:
        path = Path(_TMP.name) / f"poses_{n}_db3"
        write, store = pose_db3, get_typestore(Stores.ROS2_HUMBLE)
        reader, deserialize = rb.rosbag2.Reader, store.deserialize_cdr
    if not path.exists():
        write(path, n)
    peer_n = min(n, PEER_MESSAGES)

    def peer() -> None:
        with reader(path) as r:
            for i, (conn, _, raw) in enumerate(r.messages()):
                msg: Any = deserialize(raw, conn.msgtype)
                _ = msg.pose.position.x
                if i + 1 == peer_n:
                    break

    return Case(lambda: s2w.read_log(path).reference, peer, n, peer_n)


def _keyframe_row(k: int, compression: str) -> Case:
    path = Path(_TMP.name) / f"keyframes_{k}_{compression}.bag"
    if not path.exists():
        keyframe_bag(path, k, compression)
    chunks = [(d, size) for c, d, size in bag_chunks(path) if c == compression]
    if not chunks:
        raise Skip(f"the bag has no {compression} chunk")
    total = sum(size for _, size in chunks)
    if compression == "lz4":
        try:
            import lz4.frame  # type: ignore[import-untyped]
        except ImportError as e:
            raise Skip(f"lz4 is not installed ({e})") from e

        def plain() -> None:
            for data, _ in chunks:
                lz4.frame.decompress(data)
    else:

        def plain() -> None:
            for data, _ in chunks:
                bz2.decompress(data)

    return Case(lambda: s2w.read_log(path).keyframes, plain, total, extras={"bytes": total})


@register(
    "rosbag",
    "read_log ros1 bag keyframes 640x480 (lz4)",
    peer="plain lz4 decompression, 1 thread (the limit)",
    size=16,
    quick_size=4,
    smoke_size=1,
    target=1 / 1.5,
    target_text="<=1.5x lz4",
    unit="keyframes",
    work_unit="bytes",
    issue="#14",
)
def _ros1_keyframes_lz4(k: int) -> Case:
    _rosbags()
    return _keyframe_row(k, "lz4")


@register(
    "rosbag",
    "read_log ros1 bag keyframes 640x480 (bz2)",
    peer="plain bz2 decompression, 1 thread (the limit)",
    size=8,
    quick_size=2,
    smoke_size=1,
    target=1 / 1.5,
    target_text="<=1.5x bz2",
    unit="keyframes",
    work_unit="bytes",
    issue="#14",
)
def _ros1_keyframes_bz2(k: int) -> Case:
    _rosbags()
    return _keyframe_row(k, "bz2")


@register(
    "rosbag",
    "read_log rosbag2 .db3 PoseStamped (cdr)",
    peer="rosbags rosbag2 Reader + deserialize_cdr",
    size=10**6,
    quick_size=10**5,
    smoke_size=500,
    target=30,
    unit="messages",
    issue="#14",
)
def _db3_poses(n: int) -> Case:
    return _pose_row(n, "ros2")
