"""Plain-numpy references for `slam2world.backproject`, written from the LSD-SLAM
viewer's `KeyFrameDisplay::refreshPC` (lsd_slam_viewer) as DESIGN.md states it.

`reference_loop` follows the viewer pixel by pixel (small images, tests);
`reference_vectorised` applies the same rules with whole-array numpy operations
(the peer in the side-by-side benchmark). Both take plain arrays, not slam2world
objects, so they share no code with the library.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

F32 = npt.NDArray[np.float32]


@dataclass
class RefKeyframe:
    id: int
    pose: npt.NDArray[np.float64]  # 4x4 T_slam_cam = [[sR, t], [0, 1]]
    scale: float  # s of the pose
    fx: float
    fy: float
    cx: float
    cy: float
    idepth: F32  # (H, W)
    idepth_var: F32 | None
    color: npt.NDArray[np.uint8] | None  # (H, W, 3)


@dataclass
class RefFilter:
    scaled_depth_var: float = 1e-3
    abs_depth_var: float = 1e-1
    min_near_support: int = 7
    sparsify: int = 1
    cut_first_keyframes: int | None = 5
    skip_border: bool = True
    seed: int = 0


def splitmix64(z: npt.NDArray[np.uint64]) -> npt.NDArray[np.uint64]:
    """SplitMix64 on uint64 arrays (wrapping arithmetic)."""
    z = z + np.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


def sparsify_keeps(
    seed: int, kf_id: int, pixels: npt.NDArray[np.int64], factor: int
) -> npt.NDArray[np.bool_]:
    """The documented draw: splitmix64(((id as u32) << 32 ^ pixel) ^ seed) % factor == 0."""
    key = (np.uint64(kf_id & 0xFFFFFFFF) << np.uint64(32)) ^ pixels.astype(np.uint64)
    h = splitmix64(key ^ np.uint64(seed))
    return np.asarray(h % np.uint64(factor) == 0)


def _world_cam(kf: RefKeyframe, world_slam: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    return world_slam @ kf.pose


def reference_loop(
    kfs: list[RefKeyframe], f: RefFilter, world_slam: npt.NDArray[np.float64] | None = None
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.uint8] | None, npt.NDArray[np.int64]]:
    """Pixel by pixel, in the viewer's order of tests, float32 where the viewer uses float."""
    ws = np.eye(4) if world_slam is None else world_slam
    pts: list[npt.NDArray[np.float64]] = []
    cols: list[npt.NDArray[np.uint8]] = []
    ids: list[int] = []
    with_color = all(k.color is not None for k in kfs) and len(kfs) > 0
    for i, kf in enumerate(kfs):
        if f.cut_first_keyframes is not None and i <= f.cut_first_keyframes:
            continue
        m = _world_cam(kf, ws)
        h, w = kf.idepth.shape
        b = 1 if f.skip_border else 0
        s = np.float32(kf.scale)
        for y in range(b, h - b):
            for x in range(b, w - b):
                idp = kf.idepth[y, x]
                if not (idp > 0 and np.isfinite(idp)):
                    continue
                if (
                    f.sparsify > 1
                    and not sparsify_keeps(f.seed, kf.id, np.array([x + y * w]), f.sparsify)[0]
                ):
                    continue
                if kf.idepth_var is not None:
                    v = kf.idepth_var[y, x]
                    depth = np.float32(1.0) / idp
                    d4 = (depth * depth) * (depth * depth)
                    if np.isfinite(f.scaled_depth_var) and not (
                        v * d4 <= np.float32(f.scaled_depth_var)
                    ):
                        continue
                    if np.isfinite(f.abs_depth_var) and not (
                        v * d4 * s * s <= np.float32(f.abs_depth_var)
                    ):
                        continue
                    if f.min_near_support > 1:
                        support = 0
                        for dy in (-1, 0, 1):
                            for dx in (-1, 0, 1):
                                nx, ny = x + dx, y + dy
                                if not (0 <= nx < w and 0 <= ny < h):
                                    continue
                                n = kf.idepth[ny, nx]
                                diff = n - idp
                                if n > 0 and diff * diff < np.float32(2) * v:
                                    support += 1
                        if support < f.min_near_support:
                            continue
                d = 1.0 / float(idp)
                p_cam = np.array([(x - kf.cx) / kf.fx * d, (y - kf.cy) / kf.fy * d, d, 1.0])
                pts.append((m @ p_cam)[:3])
                if with_color:
                    assert kf.color is not None
                    cols.append(kf.color[y, x])
                ids.append(kf.id)
    points = np.array(pts, dtype=np.float64).reshape(-1, 3)
    colors = np.array(cols, dtype=np.uint8).reshape(-1, 3) if with_color else None
    return points, colors, np.array(ids, dtype=np.int64)


def reference_vectorised(
    kfs: list[RefKeyframe], f: RefFilter, world_slam: npt.NDArray[np.float64] | None = None
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]:
    """The same rules on whole arrays (keyframes with a variance, border skipped).

    The sparsify draw is applied after the other rules; it is independent per pixel,
    so the order does not change the result.
    """
    ws = np.eye(4) if world_slam is None else world_slam
    out_pts = []
    out_ids = []
    for i, kf in enumerate(kfs):
        if f.cut_first_keyframes is not None and i <= f.cut_first_keyframes:
            continue
        assert f.skip_border and kf.idepth_var is not None
        idp = kf.idepth
        var = kf.idepth_var
        h, w = idp.shape
        c = idp[1:-1, 1:-1]
        v = var[1:-1, 1:-1]
        with np.errstate(all="ignore"):
            keep = (c > 0) & np.isfinite(c)
            depth = np.float32(1.0) / c
            vd4 = v * ((depth * depth) * (depth * depth))
            keep &= vd4 <= np.float32(f.scaled_depth_var)
            s = np.float32(kf.scale)
            keep &= vd4 * s * s <= np.float32(f.abs_depth_var)
            if f.min_near_support > 1:
                two_var = np.float32(2) * v
                support = np.zeros(c.shape, dtype=np.int32)
                for dy in (-1, 0, 1):
                    for dx in (-1, 0, 1):
                        n = idp[1 + dy : h - 1 + dy, 1 + dx : w - 1 + dx]
                        diff = n - c
                        support += (n > 0) & (diff * diff < two_var)
                keep &= support >= f.min_near_support
        if f.sparsify > 1:
            yy, xx = np.mgrid[1 : h - 1, 1 : w - 1]
            keep &= sparsify_keeps(f.seed, kf.id, (xx + yy * w).astype(np.int64), f.sparsify)
        ys, xs = np.nonzero(keep)
        d = 1.0 / c[ys, xs].astype(np.float64)
        p_cam = np.stack([(xs + 1 - kf.cx) / kf.fx * d, (ys + 1 - kf.cy) / kf.fy * d, d], axis=1)
        m = _world_cam(kf, ws)
        out_pts.append(p_cam @ m[:3, :3].T + m[:3, 3])
        out_ids.append(np.full(len(d), kf.id, dtype=np.int64))
    if not out_pts:
        return np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    return np.concatenate(out_pts), np.concatenate(out_ids)
