"""Occupancy insertion rows: ``OccupancyMap.insert`` against OctoMap's
``insertPointCloud`` (octomap-python, one thread), same points, resolution 0.1 m,
max range 10 m; and memory per leaf of the two trees.

Scene: cubes on a ground plane seen from camera centres on a circle (rays cast
at the surfaces, as a depth camera sees them).
"""

from __future__ import annotations

import numpy as np

import slam2world as s2w

from .registry import Case, Skip, register

RESOLUTION, MAX_RANGE = 0.1, 10.0
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


def camera_scan(
    origin: np.ndarray, target: tuple[float, float, float], width: int, height: int
) -> np.ndarray:
    """Points seen by a 90° pinhole camera at `origin` looking at `target`."""
    fwd = np.asarray(target, float) - origin
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    down = np.cross(fwd, right)
    f = 0.5 * width / np.tan(np.radians(90.0) / 2)
    u, v = np.meshgrid(np.arange(width) - width / 2 + 0.5, np.arange(height) - height / 2 + 0.5)
    d = fwd[None] * f + u.reshape(-1, 1) * right[None] + v.reshape(-1, 1) * down[None]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return cast_scene(origin, d)


def scans(n_points: int, n_scans: int = 8) -> list[tuple[np.ndarray, np.ndarray]]:
    """About `n_points` points in `n_scans` scans of 4:3 images."""
    per = max(12, n_points // n_scans)
    width = max(4, int(round(np.sqrt(per * 4 / 3))))
    height = max(3, per // width)
    out = []
    for i in range(n_scans):
        a = 2 * np.pi * i / n_scans
        origin = np.array([9.0 * np.cos(a), 9.0 * np.sin(a), 1.6])
        out.append((origin, camera_scan(origin, (1.0, 0.0, 0.5), width, height)))
    return out


def _octomap():  # type: ignore[no-untyped-def]
    try:
        import octomap  # type: ignore[import-not-found]
    except ImportError as e:
        raise Skip(f"octomap-python is not installed ({e})") from e
    return octomap


def _case(n: int) -> Case:
    octomap = _octomap()
    data = scans(n)
    total = sum(len(p) for _, p in data)

    def ours() -> s2w.OccupancyMap:
        m = s2w.OccupancyMap(RESOLUTION, max_range=MAX_RANGE)
        for origin, pts in data:
            m.insert(pts, origin)
        return m

    def peer() -> object:
        t = octomap.OcTree(RESOLUTION)
        for origin, pts in data:
            t.insertPointCloud(pts, origin, maxrange=MAX_RANGE)
        return t

    return Case(ours, peer, total)


@register(
    "octree",
    "OccupancyMap.insert 0.1 m, 10 m range",
    peer="OctoMap insertPointCloud (1 thread)",
    size=614_400,
    quick_size=76_800,
    smoke_size=2_000,
    target=10,
    unit="points",
    curve=(10**3, 10**4, 10**5, 10**6),
    issue="#7",
)
def _insert(n: int) -> Case:
    return _case(n)


@register(
    "octree",
    "memory per leaf",
    peer="OctoMap memoryUsage / leaves",
    size=614_400,
    quick_size=76_800,
    smoke_size=2_000,
    target=1,
    target_text="<= OctoMap",
    unit="points",
    parallel=False,
    issue="#7",
)
def _memory(n: int) -> Case:
    case = _case(n)
    assert case.peer is not None
    ref, ours = case.peer(), case.ours()
    ref_b = ref.memoryUsage() / ref.getNumLeafNodes()  # type: ignore[attr-defined]
    ours_b = ours.memory_bytes / ours.num_leaf_nodes  # type: ignore[attr-defined]
    return Case(
        case.ours,
        None,
        case.ours_work,
        values=(ours_b, ref_b),
        extras={"bytes_per_leaf_ours": ours_b, "bytes_per_leaf_peer": ref_b},
    )
