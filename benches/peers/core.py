"""Alignment and transform rows: numpy, evo, Open3D, a plain memory copy."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

import slam2world as s2w

from .registry import CURVE_SIZES, Case, Skip, register

DATA = Path(__file__).resolve().parents[3] / "shared" / "data"


def _pairs(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, 3))
    t = s2w.Sim3.from_quaternion([0.1, 0.2, 0.3, 0.9], [1.0, 2.0, 3.0], 15.49)
    b = t.apply(a) + rng.normal(scale=1e-3, size=(n, 3))
    return a, b


def numpy_umeyama(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Vectorised Umeyama on (N, 3) arrays: the numpy peer."""
    mx, my = x.mean(axis=0), y.mean(axis=0)
    xc, yc = x - mx, y - my
    var_x = np.einsum("ij,ij->", xc, xc) / len(x)
    cov = yc.T @ xc / len(x)
    u, d, vt = np.linalg.svd(cov)
    s = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        s[2, 2] = -1
    r = u @ s @ vt
    c = float(np.trace(np.diag(d) @ s) / var_x)
    return r, my - c * r @ mx, c


@register(
    "align",
    "align Sim(3)",
    peer="numpy vectorised Umeyama",
    size=10**6,
    quick_size=10**5,
    target=10,
    unit="pairs",
    curve=CURVE_SIZES,
    issue="#2",
)
def _align_numpy(n: int) -> Case:
    a, b = _pairs(n)
    return Case(lambda: s2w.align(a, b), lambda: numpy_umeyama(a, b), n)


@register(
    "align",
    "align Sim(3)",
    peer="evo umeyama_alignment",
    size=10**6,
    quick_size=10**5,
    target=500,
    unit="pairs",
    curve=CURVE_SIZES[:4],
    issue="#2",
)
def _align_evo(n: int) -> Case:
    try:
        from evo.core.geometry import umeyama_alignment
    except ImportError as e:
        raise Skip(f"evo is not installed ({e})") from e
    a, b = _pairs(n)
    at, bt = a.T.copy(), b.T.copy()
    return Case(lambda: s2w.align(a, b), lambda: umeyama_alignment(at, bt, True), n)


@register(
    "align",
    "align_trajectories fr2/desk keyframes",
    peer="evo associate + align + APE",
    size=157,
    unit="poses",
    parallel=False,
)
def _traj_evo(_: int) -> Case:
    est_path = DATA / "evo_tum_fr2_desk" / "fr2_desk_ORB_kf_mono.txt"
    ref_path = DATA / "evo_tum_fr2_desk" / "fr2_desk_groundtruth.txt"
    if not est_path.exists():
        raise Skip(f"data not present: {est_path}")
    try:
        from evo.core import metrics, sync
        from evo.tools import file_interface
    except ImportError as e:
        raise Skip(f"evo is not installed ({e})") from e
    import copy

    est, ref = s2w.Trajectory.read_tum(est_path), s2w.Trajectory.read_tum(ref_path)
    e_est = file_interface.read_tum_trajectory_file(str(est_path))
    e_ref = file_interface.read_tum_trajectory_file(str(ref_path))

    def evo() -> float:
        r, e = sync.associate_trajectories(e_ref, e_est, max_diff=0.01)
        e = copy.deepcopy(e)
        e.align(r, correct_scale=True)
        ape = metrics.APE(metrics.PoseRelation.translation_part)
        ape.process_data((r, e))
        return float(ape.get_statistic(metrics.StatisticsType.rmse))

    return Case(lambda: s2w.align_trajectories(est, ref), evo, len(est.timestamps))


WORLD = s2w.Sim3.from_quaternion([0.1, 0.2, 0.3, 0.9], [1.0, 2.0, 3.0], 15.49)


def _points(n: int, dtype: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    p = np.random.default_rng(1).normal(size=(n, 3)).astype(dtype)
    m = (WORLD.scale * WORLD.rotation).T.astype(dtype)
    return p, m, WORLD.translation.astype(dtype)


@register(
    "transform",
    "Sim3.apply float32",
    peer="numpy P @ (sR).T + t (float32)",
    size=10**7,
    quick_size=10**6,
    target=3,
    unit="points",
    curve=CURVE_SIZES,
    issue="#2 #3",
)
def _apply_f32(n: int) -> Case:
    p, m, tr = _points(n, np.float32)
    return Case(lambda: WORLD.apply(p), lambda: p @ m + tr, n)


@register(
    "transform",
    "Sim3.apply float64",
    peer="numpy P @ (sR).T + t (float64)",
    size=10**7,
    quick_size=10**6,
    unit="points",
    curve=CURVE_SIZES,
)
def _apply_f64(n: int) -> Case:
    p, m, tr = _points(n, np.float64)
    return Case(lambda: WORLD.apply(p), lambda: p @ m + tr, n)


@register(
    "transform",
    "Sim3.apply float32",
    peer="copy of the same bytes (the limit)",
    size=10**7,
    quick_size=10**6,
    target=1 / 1.5,
    target_text="<=1.5x copy",
    unit="points",
    curve=CURVE_SIZES,
    issue="#8",
)
def _apply_copy(n: int) -> Case:
    p, _, _ = _points(n, np.float32)
    return Case(lambda: WORLD.apply(p), lambda: p.copy(), n)


@register(
    "transform",
    "PointCloud.transformed",
    peer="numpy P @ (sR).T + t (float32)",
    size=10**7,
    quick_size=10**6,
    target=3,
    unit="points",
    curve=CURVE_SIZES,
    issue="#3",
)
def _transformed_numpy(n: int) -> Case:
    p, m, tr = _points(n, np.float32)
    cloud = s2w.PointCloud(p)
    return Case(lambda: cloud.transformed(WORLD), lambda: p @ m + tr, n)


@register(
    "transform",
    "PointCloud.transformed",
    peer="Open3D transform (float64, in place)",
    size=10**7,
    quick_size=10**6,
    target=1,
    unit="points",
    curve=CURVE_SIZES,
    issue="#3",
)
def _transformed_open3d(n: int) -> Case:
    try:
        import open3d as o3d  # type: ignore[import-not-found]
    except ImportError as e:
        raise Skip(f"Open3D is not installed ({e})") from e
    p, _, _ = _points(n, np.float32)
    cloud = s2w.PointCloud(p)
    o = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(p.astype(np.float64)))
    m = WORLD.matrix()
    return Case(lambda: cloud.transformed(WORLD), lambda: o.transform(m), n)
