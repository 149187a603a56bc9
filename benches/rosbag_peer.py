"""The Python peer of `benches/rosbag.rs`: `rosbags` reading + deserialising the
same 1e6-PoseStamped lz4 bag, and the ratio to slam2world's criterion figure.

    cargo bench --bench rosbag -- rosbag_poses     # writes target/bench-data/poses_1e6_lz4.bag
    .venv/bin/python benches/rosbag_peer.py [--limit N]

The peer is timed on the first `--limit` messages (default: all) and its rate is
compared with the mean time criterion measured for the whole bag
(`target/criterion/rosbag_poses/.../new/estimates.json`).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
BAG = ROOT / "target/bench-data/poses_1e6_lz4.bag"
ESTIMATES = (
    ROOT / "target/criterion/rosbag_poses/scan_decode_pose_stamped_lz4/1000000/new/estimates.json"
)


def peer(path: Path, limit: int | None) -> tuple[int, float]:
    """Messages read and deserialised by rosbags, and the seconds it took."""
    from rosbags.rosbag1 import Reader
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    n = 0
    t0 = time.perf_counter()
    with Reader(path) as reader:
        for conn, _, raw in reader.messages():
            msg: Any = store.deserialize_ros1(raw, conn.msgtype)
            _ = msg.pose.position.x
            n += 1
            if limit is not None and n >= limit:
                break
    return n, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bag", type=Path, default=BAG)
    ap.add_argument("--limit", type=int, default=None, help="time the first N messages")
    args = ap.parse_args()
    if not args.bag.exists():
        raise SystemExit(f"{args.bag} is absent: run `cargo bench --bench rosbag` first")
    n, secs = peer(args.bag, args.limit)
    rate = n / secs
    print(f"rosbags Reader + deserialize_ros1: {n} msgs in {secs:.2f} s = {rate:,.0f} msg/s")
    if ESTIMATES.exists():
        mean_ns = json.loads(ESTIMATES.read_text())["mean"]["point_estimate"]
        ours = 1_000_000 / (mean_ns * 1e-9)
        print(f"slam2world Ros1Bag::scan_map + pose_sample: {ours:,.0f} msg/s (criterion mean)")
        print(f"ratio: {ours / rate:.1f}x (issue bar: >= 30x)")
    else:
        print(f"no criterion estimate at {ESTIMATES}: run the Rust bench for the ratio")


if __name__ == "__main__":
    main()
