"""MCAP read + decode rows.

(a) A log of small ros1 ``geometry_msgs/PoseStamped`` messages (zstd chunks):
    ``slam2world.read_mcap`` against the Python ``mcap`` reader with
    ``mcap-ros1-support`` (timed on its first 200 000 messages at most; its rate
    does not depend on the file length; rates are compared per message).
(b) A zstd log of 640x480 LSD-SLAM keyframes: ``slam2world.read_mcap`` against
    plain zstd decompression of the same chunks (``zstandard``, one thread: the
    limit), compared per decompressed byte.

Both logs are written with the Python ``mcap`` writer, not with ours.
"""

from __future__ import annotations

import struct
import tempfile
from pathlib import Path

import numpy as np

import slam2world as s2w

from .registry import Case, Skip, register

POSE_STAMPED = (
    "Header header\nPose pose\n" + "=" * 80 + "\nMSG: std_msgs/Header\nuint32 seq\ntime stamp\n"
    "string frame_id\n" + "=" * 80 + "\nMSG: geometry_msgs/Pose\nPoint position\n"
    "Quaternion orientation\n" + "=" * 80 + "\nMSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\n"
    "float64 z\n" + "=" * 80 + "\nMSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\n"
    "float64 z\nfloat64 w\n"
)
KEYFRAME = (
    "int32 id\nfloat64 time\nbool isKeyframe\nfloat32[7] camToWorld\nfloat32 fx\nfloat32 fy\n"
    "float32 cx\nfloat32 cy\nuint32 height\nuint32 width\nuint8[] pointcloud\n"
)
PEER_MESSAGES = 200_000

# Logs live as long as the process (the rows' callables read them).
_TMP = tempfile.TemporaryDirectory(prefix="s2w-bench-")


def _mcap():  # type: ignore[no-untyped-def]
    try:
        import mcap.writer
        import mcap_ros1.decoder  # noqa: F401
    except ImportError as e:
        raise Skip(f"mcap / mcap-ros1-support not installed ({e})") from e
    return mcap.writer


def pose_log(path: Path, n: int) -> None:
    writer = _mcap()
    with open(path, "wb") as f:
        w = writer.Writer(f, compression=writer.CompressionType.ZSTD)
        w.start(profile="ros1", library="slam2world-bench")
        sid = w.register_schema(
            name="geometry_msgs/PoseStamped", encoding="ros1msg", data=POSE_STAMPED.encode()
        )
        cid = w.register_channel(topic="/gt", message_encoding="ros1", schema_id=sid)
        pack = struct.Struct("<III I5s 7d").pack
        for i in range(n):
            t = 1000.0 + i * 0.001
            s = int(t)
            data = pack(i, s, int((t - s) * 1e9), 5, b"world", 0.1 * i, 1.0, 2.0, 0, 0, 0, 1)
            w.add_message(channel_id=cid, log_time=i, publish_time=i, data=data)
        w.finish()


def keyframe_log(path: Path, k: int) -> None:
    writer = _mcap()
    rng = np.random.default_rng(0)
    w_, h_ = 640, 480
    yy, xx = np.mgrid[0:h_, 0:w_]
    with open(path, "wb") as f:
        w = writer.Writer(f, compression=writer.CompressionType.ZSTD)
        w.start(profile="ros1", library="slam2world-bench")
        sid = w.register_schema(
            name="lsd_slam_viewer/keyframeMsg", encoding="ros1msg", data=KEYFRAME.encode()
        )
        cid = w.register_channel(
            topic="/lsd_slam/keyframes", message_encoding="ros1", schema_id=sid
        )
        for i in range(k):
            rec = np.zeros((h_, w_), dtype=[("d", "<f4"), ("v", "<f4"), ("c", "u1", (4,))])
            mask = rng.random((h_, w_)) < 0.25  # semi-dense: a quarter of the pixels
            rec["d"][mask] = rng.uniform(0.5, 1.5, mask.sum())
            rec["v"][mask] = rng.uniform(0.0, 1e-4, mask.sum())
            rec["c"][..., 0] = xx // 3
            rec["c"][..., 1] = yy // 2
            rec["c"][..., 2] = (xx + yy) // 5
            blob = rec.tobytes()
            cam = (0.0, 0.0, 0.0, 1.0, 0.1 * i, 0.0, 0.0, 525.0, 525.0, 319.5, 239.5)
            head = struct.pack("<idB7f4fIII", i, 1.0 + i, 1, *cam, h_, w_, len(blob))
            w.add_message(channel_id=cid, log_time=i, publish_time=i, data=head + blob)
        w.finish()


@register(
    "mcap",
    "read_mcap ros1 PoseStamped (zstd)",
    peer="Python mcap + mcap-ros1-support",
    size=10**6,
    quick_size=10**5,
    smoke_size=500,
    target=50,
    unit="messages",
    curve=(10**3, 10**4, 10**5, 10**6),
    issue="#4",
)
def _poses(n: int) -> Case:
    _mcap()
    from mcap.reader import make_reader
    from mcap_ros1.decoder import DecoderFactory

    path = Path(_TMP.name) / f"poses_{n}.mcap"
    if not path.exists():
        pose_log(path, n)
    peer_n = min(n, PEER_MESSAGES)

    def peer() -> None:
        with open(path, "rb") as f:
            r = make_reader(f, decoder_factories=[DecoderFactory()])
            for i, (_, _, _, m) in enumerate(r.iter_decoded_messages()):
                _ = m.pose.position.x
                if i + 1 == peer_n:
                    break

    return Case(lambda: s2w.read_mcap(path).reference, peer, n, peer_n)


@register(
    "mcap",
    "read_mcap zstd keyframes 640x480",
    peer="plain zstd decompression, 1 thread (the limit)",
    size=16,
    quick_size=4,
    smoke_size=1,
    target=1 / 1.5,
    target_text="<=1.5x zstd",
    unit="keyframes",
    work_unit="bytes",
    issue="#4",
)
def _keyframes(k: int) -> Case:
    _mcap()
    try:
        import zstandard
    except ImportError as e:
        raise Skip(f"zstandard is not installed ({e})") from e
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader

    path = Path(_TMP.name) / f"keyframes_{k}.mcap"
    if not path.exists():
        keyframe_log(path, k)
    with open(path, "rb") as f:
        chunks = [r for r in StreamReader(f, emit_chunks=True).records if isinstance(r, Chunk)]
    total = sum(c.uncompressed_size for c in chunks)
    dctx = zstandard.ZstdDecompressor()

    def plain() -> None:
        for c in chunks:
            dctx.decompress(c.data, max_output_size=c.uncompressed_size)

    return Case(lambda: s2w.read_mcap(path).keyframes, plain, total, extras={"bytes": total})
