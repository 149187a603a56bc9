"""The paper's figures as PNG files (matplotlib, Agg backend).

- :func:`plot_paths`: ground-truth path and SLAM path, each in its own axes;
- :func:`plot_scale_factors`: the frame-to-frame factors ``p_k`` with the three stages marked;
- :func:`plot_cloud`: the converted cloud over the true scene (top view and 3-D);
- :func:`plot_error_histogram`: distances of the converted points to the true surfaces;
- :func:`plot_octree`: the occupied octree voxels coloured by height over the true scene
  (the paper's Fig. 1c), in 3-D and from above.

``python -m slam2world.plot DIR`` draws all five from the files that ``slam2world demo``
writes into ``DIR`` (``demo.json`` and raw little-endian arrays in ``DIR/plot_data``).
Every file is written to a temporary name in its folder and renamed.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import numpy.typing as npt  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.patches import Rectangle  # noqa: E402

__all__ = [
    "frame_scale_factors",
    "plot_cloud",
    "plot_demo",
    "plot_error_histogram",
    "plot_octree",
    "plot_paths",
    "plot_scale_factors",
]

FloatArray = npt.NDArray[np.float64]


def _save(fig: Figure, path: str | os.PathLike[str]) -> Path:
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".png", dir=out.parent)
    os.close(fd)
    try:
        fig.savefig(tmp, dpi=110, format="png")
        # mkstemp makes a private file; the figure is an ordinary one (umask applies).
        mask = os.umask(0)
        os.umask(mask)
        os.chmod(tmp, 0o666 & ~mask)
        os.replace(tmp, out)
    finally:
        plt.close(fig)
        if os.path.exists(tmp):
            os.unlink(tmp)
    return out


def _rows3(a: npt.ArrayLike, what: str) -> FloatArray:
    arr = np.asarray(a, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{what}: expected shape (N, 3), got {arr.shape}")
    return arr


def frame_scale_factors(
    slam_timestamps: npt.ArrayLike,
    slam_positions: npt.ArrayLike,
    reference_timestamps: npt.ArrayLike,
    reference_positions: npt.ArrayLike,
) -> FloatArray:
    """The paper's ``p_k = |t'_{k+1} - t'_k|² / |t_{k+1} - t_k|²`` per SLAM frame.

    ``t`` are SLAM positions, ``t'`` the reference interpolated (linearly) at the SLAM
    times, so ``p_k`` is about the squared scale once SLAM is stable. Shape ``(N-1,)``.
    """
    ts = np.asarray(slam_timestamps, dtype=np.float64)
    ps = _rows3(slam_positions, "slam_positions")
    tr = np.asarray(reference_timestamps, dtype=np.float64)
    pr = _rows3(reference_positions, "reference_positions")
    ref = np.column_stack([np.interp(ts, tr, pr[:, i]) for i in range(3)])
    num = np.sum(np.diff(ref, axis=0) ** 2, axis=1)
    den = np.sum(np.diff(ps, axis=0) ** 2, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        out: FloatArray = np.where(den > 0, num / np.where(den > 0, den, 1.0), np.nan)
    return out


def _path_axes(fig: Figure, pos: int, p: FloatArray, title: str, unit: str) -> None:
    ax: Any = fig.add_subplot(1, 2, pos, projection="3d")
    ax.plot(p[:, 0], p[:, 1], p[:, 2], lw=0.6, color="tab:blue")
    ax.scatter(*p[0], color="tab:green", s=20, label="start")
    ax.scatter(*p[-1], color="tab:red", s=20, label="end")
    # The paper colours the axes x, y, z red, green, blue.
    span = float(np.max(np.ptp(p, axis=0))) * 0.15 or 1.0
    o = p.min(axis=0)
    for k, c in enumerate(("r", "g", "b")):
        d = np.zeros(3)
        d[k] = span
        ax.quiver(*o, *d, color=c, lw=1.5)
    # Equal scale on the three axes, so that the shapes compare.
    mid = 0.5 * (p.min(axis=0) + p.max(axis=0))
    half = 0.5 * float(np.max(np.ptp(p, axis=0))) or 1.0
    ax.set_xlim(mid[0] - half, mid[0] + half)
    ax.set_ylim(mid[1] - half, mid[1] + half)
    ax.set_zlim(mid[2] - half, mid[2] + half)
    ax.set_box_aspect((1.0, 1.0, 1.0))
    ax.set_xlabel(f"x [{unit}]")
    ax.set_ylabel(f"y [{unit}]")
    ax.set_zlabel(f"z [{unit}]")
    ax.set_title(title)
    ax.legend(loc="upper left", fontsize=7)


def plot_paths(
    true_positions: npt.ArrayLike,
    slam_positions: npt.ArrayLike,
    path: str | os.PathLike[str],
) -> Path:
    """Ground-truth path (metres) and SLAM path (SLAM units), each in its own 3-D axes."""
    t = _rows3(true_positions, "true_positions")
    s = _rows3(slam_positions, "slam_positions")
    fig = plt.figure(figsize=(12, 5.5))
    lt = float(np.sum(np.linalg.norm(np.diff(t, axis=0), axis=1)))
    ls = float(np.sum(np.linalg.norm(np.diff(s, axis=0), axis=1)))
    _path_axes(fig, 1, t, f"Ground-truth camera path ({lt:.2f} m)", "m")
    _path_axes(fig, 2, s, f"SLAM camera path ({ls:.2f} SLAM units)", "SLAM units")
    fig.tight_layout()
    return _save(fig, path)


def plot_scale_factors(
    p_k: npt.ArrayLike,
    stages: Sequence[int],
    path: str | os.PathLike[str],
    *,
    true_level: float | None = None,
) -> Path:
    """``p_k`` against the frame number (log scale) with the three stages marked.

    ``stages = (converge_start, stable_start)`` are frame indices; ``true_level`` (e.g. the
    true scale squared) is drawn as a dashed line when given.
    """
    p = np.asarray(p_k, dtype=np.float64)
    if p.ndim != 1 or len(stages) != 2:
        raise ValueError("p_k must be 1-D and stages (converge_start, stable_start)")
    a, b = int(stages[0]), int(stages[1])
    k = np.arange(p.size)
    ok = np.isfinite(p) & (p > 0)
    fig, ax = plt.subplots(figsize=(11, 4.5))
    first = ok & (k < a)
    rest = ok & (k >= a)
    ax.scatter(k[first], p[first], s=2, color="tab:red", label="1: occasional deviations")
    ax.scatter(k[rest], p[rest], s=2, color="black", label="2-3: converging, then stable")
    ax.axvspan(a, b, color="tab:orange", alpha=0.12, label=f"2: converging ({a}-{b})")
    ax.axvspan(b, p.size, color="tab:green", alpha=0.10, label=f"3: stable (after {b})")
    for x in (a, b):
        ax.axvline(x, color="grey", lw=0.8, ls=":")
    stable = p[ok & (k >= b)]
    if stable.size:
        ax.axhline(float(np.median(stable)), color="tab:green", lw=1.0, label="stable median")
    if true_level is not None:
        ax.axhline(true_level, color="tab:blue", lw=1.0, ls="--", label="true s²")
    ax.set_yscale("log")
    ax.set_xlabel("frame k")
    ax.set_ylabel("p_k = |Δt'|² / |Δt|²")
    ax.set_title("Frame-to-frame scale factors")
    ax.legend(loc="upper right", fontsize=7, markerscale=4)
    fig.tight_layout()
    return _save(fig, path)


def _cube_edges(lo: FloatArray, size: float) -> list[FloatArray]:
    c = np.array([[(i >> 0) & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)], dtype=float)
    c = lo + c * size
    pairs = [(i, j) for i in range(8) for j in range(i + 1, 8) if bin(i ^ j).count("1") == 1]
    return [np.vstack([c[i], c[j]]) for i, j in pairs]


def plot_cloud(
    points: npt.ArrayLike,
    path: str | os.PathLike[str],
    *,
    cube_min: npt.ArrayLike,
    cube_size: float,
    plane_half: Sequence[float],
    trajectory: npt.ArrayLike | None = None,
    max_points: int = 150_000,
    seed: int = 0,
) -> Path:
    """The converted cloud (world, metres) over the true scene: top view and 3-D view.

    Points are coloured by height; at most ``max_points`` (a seeded random subset) are drawn.
    """
    p = _rows3(points, "points")
    if p.shape[0] > max_points:
        idx = np.random.default_rng(seed).choice(p.shape[0], max_points, replace=False)
        p = p[np.sort(idx)]
    cubes = _rows3(cube_min, "cube_min")
    hx, hy = float(plane_half[0]), float(plane_half[1])
    fig = plt.figure(figsize=(14, 6))
    ax = fig.add_subplot(1, 2, 1)
    sc = ax.scatter(p[:, 0], p[:, 1], c=p[:, 2], s=0.3, cmap="viridis", vmin=-0.05, vmax=1.1)
    ax.add_patch(Rectangle((-hx, -hy), 2 * hx, 2 * hy, fill=False, ec="k", lw=1.0))
    for lo in cubes:
        ax.add_patch(Rectangle((lo[0], lo[1]), cube_size, cube_size, fill=False, ec="r", lw=1.0))
    if trajectory is not None:
        tr = _rows3(trajectory, "trajectory")
        ax.plot(tr[:, 0], tr[:, 1], color="tab:orange", lw=0.6, label="aligned SLAM path")
        ax.legend(loc="upper right", fontsize=7)
    ax.set_aspect("equal")
    ax.set_xlim(-hx - 1.5, hx + 1.5)
    ax.set_ylim(-hy - 1.5, hy + 1.5)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("Converted cloud, top view (red: true cubes, black: plane)")
    fig.colorbar(sc, ax=ax, label="z [m]", shrink=0.8)
    ax3: Any = fig.add_subplot(1, 2, 2, projection="3d")
    sub = p[:: max(1, p.shape[0] // 60_000)]
    ax3.scatter(sub[:, 0], sub[:, 1], sub[:, 2], c=sub[:, 2], s=0.2, cmap="viridis")
    for lo in cubes:
        for e in _cube_edges(lo, cube_size):
            ax3.plot(e[:, 0], e[:, 1], e[:, 2], color="r", lw=0.8)
    ax3.plot([-hx, hx, hx, -hx, -hx], [-hy, -hy, hy, hy, -hy], [0, 0, 0, 0, 0], color="k", lw=0.8)
    ax3.set_xlim(-hx, hx)
    ax3.set_ylim(-hy, hy)
    ax3.set_zlim(-0.5, 2.5)
    ax3.set_box_aspect((2 * hx, 2 * hy, 3.0))
    ax3.set_xlabel("x [m]")
    ax3.set_ylabel("y [m]")
    ax3.set_zlabel("z [m]")
    ax3.set_title("Converted cloud, 3-D")
    fig.tight_layout()
    return _save(fig, path)


def plot_error_histogram(
    distances: npt.ArrayLike,
    path: str | os.PathLike[str],
    *,
    reference: npt.ArrayLike | None = None,
) -> Path:
    """Histogram of point-to-surface distances (millimetres), with the median and 95th
    percentile; ``reference`` (the same cloud carried with the true transform) is overlaid."""
    d = np.asarray(distances, dtype=np.float64) * 1e3
    if d.ndim != 1 or d.size == 0:
        raise ValueError(f"distances: expected a non-empty 1-D array, got shape {d.shape}")
    hi = float(np.percentile(d, 99.5)) or 1.0
    bins = [float(b) for b in np.linspace(0.0, hi, 80)]
    fig, ax = plt.subplots(figsize=(8, 4.5))
    ax.hist(d, bins=bins, color="tab:blue", alpha=0.7, label="estimated T_world_slam")
    if reference is not None:
        r = np.asarray(reference, dtype=np.float64) * 1e3
        ax.hist(r, bins=bins, histtype="step", color="k", lw=1.0, label="true T_world_slam")
    med, p95 = float(np.median(d)), float(np.percentile(d, 95))
    ax.axvline(med, color="tab:green", lw=1.2, label=f"median {med:.1f} mm")
    ax.axvline(p95, color="tab:red", lw=1.2, label=f"95th percentile {p95:.1f} mm")
    ax.set_xlabel("distance to the true surface [mm]")
    ax.set_ylabel("points")
    ax.set_title(f"Converted cloud error ({d.size} points)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return _save(fig, path)


def _finest_voxels(voxels: FloatArray, resolution: float) -> npt.NDArray[np.int64]:
    """Integer voxel indices ``floor(centre / resolution)`` of every finest voxel, pruned
    leaves (edges of ``2^k`` voxels) expanded."""
    out = []
    for edge in np.unique(np.round(voxels[:, 3] / resolution).astype(np.int64)):
        sel = voxels[np.round(voxels[:, 3] / resolution).astype(np.int64) == edge]
        lo = np.floor((sel[:, :3] - 0.5 * edge * resolution) / resolution + 0.5).astype(np.int64)
        steps = np.arange(max(int(edge), 1), dtype=np.int64)
        offs = np.stack(np.meshgrid(steps, steps, steps, indexing="ij"), -1).reshape(-1, 3)
        out.append((lo[:, None, :] + offs[None, :, :]).reshape(-1, 3))
    if not out:
        return np.zeros((0, 3), dtype=np.int64)
    unique: npt.NDArray[np.int64] = np.unique(np.vstack(out), axis=0)
    return unique


def _exposed_faces(idx: npt.NDArray[np.int64]) -> tuple[FloatArray, npt.NDArray[np.int64]]:
    """Quads (M, 4, 3) in voxel units of the faces of ``idx`` that no occupied voxel
    covers (bottom faces left out: the view is from above), and the voxel of each."""
    span: npt.NDArray[np.int64] = (
        idx.max(axis=0) - idx.min(axis=0) + 3 if idx.size else np.ones(3, dtype=np.int64)
    )
    base: npt.NDArray[np.int64] = idx - idx.min(axis=0) + 1 if idx.size else idx

    def key(a: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
        k: npt.NDArray[np.int64] = (a[:, 0] * span[1] + a[:, 1]) * span[2] + a[:, 2]
        return k

    occupied = np.sort(key(base))
    corners = {
        (0, 1): [(1, 0, 0), (1, 1, 0), (1, 1, 1), (1, 0, 1)],
        (0, -1): [(0, 0, 0), (0, 1, 0), (0, 1, 1), (0, 0, 1)],
        (1, 1): [(0, 1, 0), (1, 1, 0), (1, 1, 1), (0, 1, 1)],
        (1, -1): [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)],
        (2, 1): [(0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)],
    }
    quads, owner = [], []
    for (axis, sign), cs in corners.items():
        nb = base.copy()
        nb[:, axis] += sign
        k = key(nb)
        pos = np.clip(np.searchsorted(occupied, k), 0, max(len(occupied) - 1, 0))
        free = occupied[pos] != k if len(occupied) else np.ones(len(k), dtype=bool)
        sel = np.nonzero(free)[0]
        quads.append(idx[sel][:, None, :] + np.asarray(cs, dtype=np.int64)[None, :, :])
        owner.append(sel)
    if not quads:
        return np.zeros((0, 4, 3)), np.zeros(0, dtype=np.int64)
    return np.concatenate(quads).astype(np.float64), np.concatenate(owner)


def plot_octree(
    voxels: npt.ArrayLike,
    path: str | os.PathLike[str],
    *,
    resolution: float,
    cube_min: npt.ArrayLike,
    cube_size: float,
    plane_half: Sequence[float],
) -> Path:
    """The occupied voxels of the octree (rows ``cx, cy, cz, edge`` in metres, as
    ``OccupancyMap`` leaves), coloured by height, over the true scene (red: the cubes,
    black: the plane): a 3-D view of the voxel faces and the height seen from above.
    """
    from matplotlib.colors import Normalize
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # type: ignore[import-untyped]

    v = np.asarray(voxels, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 4 or v.shape[0] == 0:
        raise ValueError(f"voxels: expected a non-empty (N, 4) array, got shape {v.shape}")
    if not resolution > 0:
        raise ValueError(f"resolution must be > 0, got {resolution}")
    idx = _finest_voxels(v, resolution)
    quads, owner = _exposed_faces(idx)
    z = (idx[:, 2] + 0.5) * resolution
    norm = Normalize(vmin=-0.05, vmax=1.1)
    cmap = plt.get_cmap("viridis")
    cubes = _rows3(cube_min, "cube_min")
    hx, hy = float(plane_half[0]), float(plane_half[1])
    fig = plt.figure(figsize=(15, 6.5))
    ax: Any = fig.add_subplot(1, 2, 1, projection="3d")
    shade = np.where(quads[:, 0, 2] == quads[:, 2, 2], 1.0, 0.72)  # tops lit, sides darker
    colours = cmap(norm(z[owner]))
    colours[:, :3] *= shade[:, None]
    ax.add_collection3d(
        Poly3DCollection(quads * resolution, facecolors=colours, edgecolors="none", linewidths=0)
    )
    for lo in cubes:
        for e in _cube_edges(lo, cube_size):
            ax.plot(e[:, 0], e[:, 1], e[:, 2], color="r", lw=0.9)
    ax.plot([-hx, hx, hx, -hx, -hx], [-hy, -hy, hy, hy, -hy], [0, 0, 0, 0, 0], color="k", lw=0.8)
    ax.set_xlim(-hx, hx)
    ax.set_ylim(-hy, hy)
    ax.set_zlim(-0.5, 2.5)
    ax.set_box_aspect((2 * hx, 2 * hy, 3.0))
    ax.view_init(elev=35, azim=-60)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.set_title(f"Occupied voxels ({len(idx)} of {resolution:g} m), coloured by height")
    ax2 = fig.add_subplot(1, 2, 2)
    lo_xy = idx[:, :2].min(axis=0)
    shape = tuple(int(s) for s in idx[:, :2].max(axis=0) - lo_xy + 1)
    top = np.full(shape, np.nan)
    order = np.argsort(z)
    top[idx[order, 0] - lo_xy[0], idx[order, 1] - lo_xy[1]] = z[order]
    extent = (
        lo_xy[0] * resolution,
        (lo_xy[0] + shape[0]) * resolution,
        lo_xy[1] * resolution,
        (lo_xy[1] + shape[1]) * resolution,
    )
    im = ax2.imshow(top.T, origin="lower", extent=extent, cmap=cmap, norm=norm)
    ax2.add_patch(Rectangle((-hx, -hy), 2 * hx, 2 * hy, fill=False, ec="k", lw=1.0))
    for lo in cubes:
        ax2.add_patch(Rectangle((lo[0], lo[1]), cube_size, cube_size, fill=False, ec="r", lw=1.0))
    ax2.set_aspect("equal")
    ax2.set_xlim(-hx - 1.5, hx + 1.5)
    ax2.set_ylim(-hy - 1.5, hy + 1.5)
    ax2.set_xlabel("x [m]")
    ax2.set_ylabel("y [m]")
    ax2.set_title("Highest occupied voxel, top view (red: true cubes)")
    fig.colorbar(im, ax=ax2, label="z [m]", shrink=0.8)
    fig.tight_layout()
    return _save(fig, path)


def _raw(folder: Path, name: str, dtype: type, cols: int) -> npt.NDArray[Any]:
    a = np.fromfile(folder / name, dtype=np.dtype(dtype).newbyteorder("<"))
    return a.reshape(-1, cols) if cols > 1 else a


def _octree_resolution(folder: Path, voxels: npt.NDArray[Any]) -> float:
    """The octree's resolution from ``report.json``, else the smallest leaf edge."""
    try:
        return float(json.loads((folder / "report.json").read_text())["octree"]["resolution"])
    except (OSError, KeyError, TypeError, ValueError):
        return float(np.min(voxels[:, 3]))


def plot_demo(folder: str | os.PathLike[str]) -> list[Path]:
    """Draws the figures from the files ``slam2world demo`` wrote into ``folder`` (the
    octree's when the demo built one)."""
    d = Path(folder)
    meta = json.loads((d / "demo.json").read_text())
    files = meta["files"]
    pts = _raw(d, files["points"], np.float32, 3)
    dist = _raw(d, files["distances"], np.float32, 1)
    dist_true = _raw(d, files["distances_true_transform"], np.float32, 1)
    true_path = _raw(d, files["true_path"], np.float64, 3)
    slam_path = _raw(d, files["slam_path"], np.float64, 3)
    aligned = _raw(d, files["aligned_keyframes"], np.float64, 3)
    p_k = _raw(d, files["scale_factors"], np.float64, 1)
    scene = meta["scene"]
    truth = meta["truth"]
    extra = []
    if "voxels" in files:
        vox = _raw(d, files["voxels"], np.float32, 4)
        if vox.shape[0]:
            extra.append(
                plot_octree(
                    vox,
                    d / "octree.png",
                    resolution=_octree_resolution(d, vox),
                    cube_min=np.asarray(scene["cube_min"], dtype=np.float64),
                    cube_size=float(scene["cube_size"]),
                    plane_half=scene["plane_half"],
                )
            )
    return [
        plot_paths(true_path, slam_path, d / "paths.png"),
        plot_scale_factors(
            p_k,
            (meta["stages"]["converge_start"], meta["stages"]["stable_start"]),
            d / "scale_factors.png",
            true_level=float(truth["scale"]) ** 2,
        ),
        plot_cloud(
            pts,
            d / "cloud.png",
            cube_min=np.asarray(scene["cube_min"], dtype=np.float64),
            cube_size=float(scene["cube_size"]),
            plane_half=scene["plane_half"],
            trajectory=aligned,
        ),
        plot_error_histogram(dist, d / "error_histogram.png", reference=dist_true),
        *extra,
    ]


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m slam2world.plot DIR``: the demo's figures; prints the files written."""
    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) != 1:
        print("usage: python -m slam2world.plot DIR", file=sys.stderr)
        return 2
    try:
        for p in plot_demo(args[0]):
            print(p)
    except (OSError, KeyError, ValueError) as e:
        print(f"slam2world.plot: error: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
