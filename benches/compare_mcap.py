"""MCAP read + decode: slam2world beside its peers, in one process, with ratios.

(a) N small ros1 PoseStamped messages (zstd chunks): slam2world.read_mcap vs the
    Python ``mcap`` reader with ``mcap-ros1-support`` (timed on its first
    ``PEER_MESSAGES`` messages; its rate does not depend on the file length).
(b) K 640x480 LSD-SLAM keyframes (zstd chunks): slam2world.read_mcap vs plain
    zstd decompression of the same chunks (``zstandard``, one thread: the limit)
    and the Python ``mcap`` reader (no decoding).

Usage: python benches/compare_mcap.py [N_POSES=1e6] [N_KEYFRAMES=16]
"""

from __future__ import annotations

import struct
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import zstandard
from mcap.reader import make_reader
from mcap.records import Chunk
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer
from mcap_ros1.decoder import DecoderFactory

import slam2world as s2w

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


def best(f: object, repeat: int = 3) -> tuple[float, float]:
    """Best wall time and best CPU time (all threads of the process) of `repeat` runs.
    On a shared machine the CPU time is the steadier measure of the work done."""
    walls, cpus = [], []
    for _ in range(repeat):
        c0, t0 = time.process_time(), time.perf_counter()
        f()  # type: ignore[operator]
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    return min(walls), min(cpus)


def pose_log(path: Path, n: int) -> None:
    with open(path, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start(profile="ros1", library="compare_mcap")
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
    rng = np.random.default_rng(0)
    w_, h_ = 640, 480
    with open(path, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start(profile="ros1", library="compare_mcap")
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
            yy, xx = np.mgrid[0:h_, 0:w_]
            rec["c"][..., 0] = xx // 3
            rec["c"][..., 1] = yy // 2
            rec["c"][..., 2] = (xx + yy) // 5
            blob = rec.tobytes()
            head = struct.pack(
                "<idB7f4fIII",
                i,
                1.0 + i,
                1,
                0,
                0,
                0,
                1,
                0.1 * i,
                0,
                0,
                525,
                525,
                319.5,
                239.5,
                h_,
                w_,
                len(blob),
            )
            w.add_message(channel_id=cid, log_time=i, publish_time=i, data=head + blob)
        w.finish()


def main() -> None:
    n = int(float(sys.argv[1])) if len(sys.argv) > 1 else 1_000_000
    k = int(float(sys.argv[2])) if len(sys.argv) > 2 else 16
    with tempfile.TemporaryDirectory() as d:
        poses = Path(d) / "poses.mcap"
        pose_log(poses, n)
        t_ours, c_ours = best(lambda: s2w.read_mcap(poses).reference)

        def peer() -> None:
            with open(poses, "rb") as f:
                r = make_reader(f, decoder_factories=[DecoderFactory()])
                for i, (_, _, _, m) in enumerate(r.iter_decoded_messages()):
                    _ = m.pose.position.x
                    if i + 1 == PEER_MESSAGES:
                        break

        t_peer, c_peer = best(peer, repeat=2)
        ours, theirs = n / t_ours, PEER_MESSAGES / t_peer
        ours_c, theirs_c = n / c_ours, PEER_MESSAGES / c_peer
        print(f"(a) {n} ros1 PoseStamped, zstd  (wall; per CPU-second)")
        rows = [
            ("slam2world.read_mcap", f"{ours / 1e3:8.0f} k msg/s", f"{ours_c / 1e3:8.0f} k"),
            ("python mcap + ros1", f"{theirs / 1e3:8.0f} k msg/s", f"{theirs_c / 1e3:.0f} k"),
            ("ratio", f"{ours / theirs:8.1f} x", f"{ours_c / theirs_c:8.1f} x"),
        ]
        for name, wall, cpu in rows:
            print(f"    {name:<28} {wall:>16}; {cpu:>10}")

        kfs = Path(d) / "keyframes.mcap"
        keyframe_log(kfs, k)
        chunks = []
        with open(kfs, "rb") as f:
            for rec in StreamReader(f, emit_chunks=True).records:
                if isinstance(rec, Chunk):
                    chunks.append(rec)
        total = sum(c.uncompressed_size for c in chunks)
        dctx = zstandard.ZstdDecompressor()

        def plain() -> None:
            for c in chunks:
                dctx.decompress(c.data, max_output_size=c.uncompressed_size)

        def python_reader() -> None:
            with open(kfs, "rb") as f:
                for _ in make_reader(f).iter_messages():
                    pass

        t_ours, c_ours = best(lambda: s2w.read_mcap(kfs), repeat=5)
        t_zstd, c_zstd = best(plain, repeat=5)
        t_py, c_py = best(python_reader, repeat=2)
        mb = total / 1e6
        print(f"(b) {k} keyframes 640x480, zstd, {mb:.0f} MB decompressed  (wall; per CPU-second)")
        for name, t, c in [
            ("slam2world.read_mcap", t_ours, c_ours),
            ("plain zstd, 1 thread", t_zstd, c_zstd),
            ("python mcap reader", t_py, c_py),
        ]:
            print(f"    {name:<22} {mb / t:8.0f} MB/s; {mb / c:8.0f} MB/s")
        print(f"    ours / plain zstd: wall {t_ours / t_zstd:.2f}, CPU {c_ours / c_zstd:.2f}")


if __name__ == "__main__":
    main()
