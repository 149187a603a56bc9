"""Side by side, one process: `slam2world.backproject` against a vectorised numpy
implementation of the same viewer rules (123 keyframes of 640x480, default filter,
into the world frame), and `PointCloud.transformed` / `Sim3.apply` on 1e7 float32
points against numpy (and Open3D's in-place float64 `transform` when installed).

Run: `python benches/compare_cloud.py` after `maturin develop --release`.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

import slam2world as sw

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "python"))
from cloud_reference import RefFilter, RefKeyframe, reference_vectorised  # noqa: E402

N_KF, W, H = 123, 640, 480
N_POINTS = 10_000_000


CPU: dict[str, float] = {}


def best_of(fn: Callable[[], Any], repeat: int = 3, name: str = "") -> tuple[float, Any]:
    """Best wall time of `repeat` runs; the CPU time (all threads) of that run goes to CPU[name]."""
    best, out = np.inf, None
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        if wall < best:
            best, CPU[name] = wall, cpu
    return best, out


def keyframes(rng: np.random.Generator) -> tuple[list[sw.Keyframe], list[RefKeyframe]]:
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    cam = sw.PinholeCamera(517.3, 516.5, 318.6, 255.3, W, H)
    kfs, refs = [], []
    surface = 1.0 + 0.2 * np.sin(xx / 60.0) + 0.1 * np.cos(yy / 50.0)
    for i in range(N_KF):
        holes = np.sin(xx / 9.0 + rng.uniform(0, 6)) * np.sin(yy / 7.0) > 0.2
        idepth = (surface + rng.uniform(-0.01, 0.01, (H, W))).astype(np.float32)
        idepth[holes] = 0.0
        var = (10.0 ** rng.uniform(-6, -2, (H, W))).astype(np.float32)
        color = rng.integers(0, 256, (H, W, 3), dtype=np.uint8)
        q = [0.1, rng.uniform(-0.5, 0.5), 0.05, 1.0]
        pose = sw.Sim3.from_quaternion(
            q, [rng.uniform(-2, 2), 0.0, rng.uniform(-2, 2)], rng.uniform(0.5, 2.0)
        )
        kfs.append(sw.Keyframe(i, 0.1 * i, pose, cam, idepth, var, color))
        refs.append(
            RefKeyframe(
                i, pose.matrix(), pose.scale, cam.fx, cam.fy, cam.cx, cam.cy, idepth, var, color
            )
        )
    return kfs, refs


def main() -> None:
    rng = np.random.default_rng(0)
    kfs, refs = keyframes(rng)
    world = sw.Sim3.from_quaternion([0.3, 0.1, 0.0, 1.0], [1.0, 2.0, 3.0], 2.5)
    pixels = N_KF * W * H

    t_sw, cloud = best_of(lambda: sw.backproject(kfs, transform=world), name="sw")
    t_np, (pts, _) = best_of(
        lambda: reference_vectorised(refs, RefFilter(), world.matrix()), 2, name="np"
    )
    assert len(pts) == len(cloud), (len(pts), len(cloud))
    print(f"backproject {N_KF}x{W}x{H}, default filter, {len(cloud)} points kept")
    print(
        f"  slam2world {t_sw:.3f} s ({pixels / t_sw / 1e6:.1f} M pixels/s), cpu {CPU['sw']:.3f} s"
    )
    print(
        f"  numpy      {t_np:.3f} s ({pixels / t_np / 1e6:.1f} M pixels/s), cpu {CPU['np']:.3f} s"
    )
    print(f"  ratio      {t_np / t_sw:.1f}x wall, {CPU['np'] / CPU['sw']:.1f}x cpu")

    p32 = rng.uniform(-10, 10, (N_POINTS, 3)).astype(np.float32)
    pc = sw.PointCloud(p32)
    m = world.matrix()
    sr32, t32 = m[:3, :3].astype(np.float32), m[:3, 3].astype(np.float32)
    t_tr, out = best_of(lambda: pc.transformed(world), 5, name="tr")
    t_ap, _ = best_of(lambda: world.apply(p32), 5)
    t_n32, ref = best_of(lambda: p32 @ sr32.T + t32, 5, name="n32")
    np.testing.assert_allclose(out.points, ref, rtol=1e-5, atol=1e-4)
    print("transform 1e7 points (float32)")
    print(f"  PointCloud.transformed {t_tr:.4f} s ({N_POINTS / t_tr / 1e6:.0f} M points/s)")
    print(f"  Sim3.apply             {t_ap:.4f} s ({N_POINTS / t_ap / 1e6:.0f} M points/s)")
    print(f"  numpy f32              {t_n32:.4f} s ({N_POINTS / t_n32 / 1e6:.0f} M points/s)")
    print(f"  ratio numpy/transformed {t_n32 / t_tr:.1f}x, numpy/apply {t_n32 / t_ap:.1f}x (wall)")
    print(f"  cpu transformed {CPU['tr']:.4f} s, numpy {CPU['n32']:.4f} s")
    try:
        import open3d as o3d  # type: ignore[import-not-found]
    except ImportError:
        print("  Open3D not installed: skipped")
    else:
        o = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(p32.astype(np.float64)))
        t_o3d, _ = best_of(lambda: o.transform(m), 5)
        print(f"  Open3D f64 in place    {t_o3d:.4f} s, ratio {t_o3d / t_tr:.2f}x")


if __name__ == "__main__":
    main()
