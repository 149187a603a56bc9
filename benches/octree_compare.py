"""Occupancy insertion, slam2world vs OctoMap (octomap-python), same points, one process.

Scene: cubes on a ground plane seen from several camera centres (rays cast at the
surfaces, as a depth camera would see them). Both maps use resolution 0.1 m and a
10 m max range; OctoMap runs on one thread (OMP_NUM_THREADS=1), slam2world on the
machine's rayon pool. Each side is timed --repeats times (fresh map each time) and
the best wall time is kept; CPU time (all threads) is reported too, since the
machine may be shared. Prints points/s of both, the ratios, memory per leaf and
whether the two trees are the same (their .ot files compared byte for byte).

    python benches/octree_compare.py [--scans 8] [--width 320] [--height 240] [--repeats 3]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path
from typing import Callable, TypeVar

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import octomap  # noqa: E402

import slam2world  # noqa: E402

T = TypeVar("T")

CUBES = [  # (centre, half size) in metres
    ((2.0, 0.0, 0.5), 0.5),
    ((4.0, 3.0, 0.75), 0.75),
    ((-3.0, 2.0, 0.5), 0.5),
    ((0.0, -4.0, 1.0), 1.0),
    ((6.0, -2.0, 1.5), 1.5),
]


def cast_scene(origin: np.ndarray, dirs: np.ndarray, far: float = 40.0) -> np.ndarray:
    """First hit of rays `origin + t*dirs` with the plane z = 0 and the cubes (slab test)."""
    t_best = np.full(len(dirs), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_plane = -origin[2] / dirs[:, 2]
    t_best = np.where((t_plane > 0) & np.isfinite(t_plane), t_plane, t_best)
    for centre, h in CUBES:
        c = np.asarray(centre)
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (c - h - origin) / dirs
            t2 = (c + h - origin) / dirs
        t_near = np.nanmax(np.minimum(t1, t2), axis=1)
        t_far = np.nanmin(np.maximum(t1, t2), axis=1)
        hit = (t_near <= t_far) & (t_near > 0)
        t_best = np.where(hit & (t_near < t_best), t_near, t_best)
    keep = np.isfinite(t_best) & (t_best < far)
    return origin + dirs[keep] * t_best[keep, None]


def camera_scan(origin, target, width: int, height: int, hfov_deg: float = 90.0) -> np.ndarray:
    """Points seen by a pinhole camera at `origin` looking at `target`."""
    origin = np.asarray(origin, float)
    fwd = np.asarray(target, float) - origin
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    down = np.cross(fwd, right)
    f = 0.5 * width / np.tan(np.radians(hfov_deg) / 2)
    u, v = np.meshgrid(np.arange(width) - width / 2 + 0.5, np.arange(height) - height / 2 + 0.5)
    d = fwd[None] * f + u.reshape(-1, 1) * right[None] + v.reshape(-1, 1) * down[None]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return cast_scene(origin, d)


def scans(n: int, width: int, height: int) -> list[tuple[np.ndarray, np.ndarray]]:
    out = []
    for i in range(n):
        a = 2 * np.pi * i / n
        origin = np.array([9.0 * np.cos(a), 9.0 * np.sin(a), 1.6])
        out.append((origin, camera_scan(origin, (1.0, 0.0, 0.5), width, height)))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scans", type=int, default=8)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--resolution", type=float, default=0.1)
    ap.add_argument("--max-range", type=float, default=10.0)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    data = scans(args.scans, args.width, args.height)
    n_points = sum(len(p) for _, p in data)

    def run_ours() -> slam2world.OccupancyMap:
        m = slam2world.OccupancyMap(args.resolution, max_range=args.max_range)
        for origin, pts in data:
            m.insert(pts, origin)
        return m

    def run_ref() -> octomap.OcTree:
        t = octomap.OcTree(args.resolution)
        for origin, pts in data:
            t.insertPointCloud(pts, origin, maxrange=args.max_range)
        return t

    def best(fn: Callable[[], T]) -> tuple[T, float, float]:
        wall, cpu = float("inf"), float("inf")
        for _ in range(args.repeats):
            c0, w0 = time.process_time(), time.perf_counter()
            out = fn()
            wall = min(wall, time.perf_counter() - w0)
            cpu = min(cpu, time.process_time() - c0)
        return out, wall, cpu

    ours, t_ours, c_ours = best(run_ours)
    ref, t_ref, c_ref = best(run_ref)

    with tempfile.TemporaryDirectory() as d:
        ours.write_ot(Path(d, "ours.ot"))
        ref.write(str(Path(d, "ref.ot")).encode())
        same = Path(d, "ours.ot").read_bytes() == Path(d, "ref.ot").read_bytes()

    leaves_ours, leaves_ref = ours.num_leaf_nodes, ref.getNumLeafNodes()
    rate_ours, rate_ref = n_points / t_ours, n_points / t_ref
    print(
        f"points: {n_points} in {args.scans} scans, resolution {args.resolution} m, "
        f"max range {args.max_range} m, cores {os.cpu_count()}, best of {args.repeats}"
    )
    print(
        f"octomap    insertPointCloud: {rate_ref:10.0f} points/s "
        f"(wall {t_ref:.3f} s, cpu {c_ref:.3f} s, one thread)"
    )
    print(
        f"slam2world insert:           {rate_ours:10.0f} points/s "
        f"(wall {t_ours:.3f} s, cpu {c_ours:.3f} s, all cores)"
    )
    print(
        f"ratio: {rate_ours / rate_ref:.1f}x points/s (wall); {c_ref / c_ours:.1f}x less cpu time"
    )
    print(
        f"memory per leaf: octomap {ref.memoryUsage() / leaves_ref:.1f} B (memoryUsage), "
        f"slam2world {ours.memory_bytes / leaves_ours:.1f} B (allocated)"
    )
    print(f"leaves: octomap {leaves_ref}, slam2world {leaves_ours}; identical .ot: {same}")


if __name__ == "__main__":
    main()
