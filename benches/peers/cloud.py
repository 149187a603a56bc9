"""Backprojection rows: ``slam2world.backproject`` against a vectorised numpy
implementation of the LSD-SLAM viewer's rules (``tests/python/cloud_reference.py``,
written from the viewer's formula and sharing no code with the library)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import slam2world as s2w

from .registry import CURVE_SIZES, Case, register

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests" / "python"))
from cloud_reference import RefFilter, RefKeyframe, reference_vectorised  # noqa: E402

W, H = 640, 480
WORLD = s2w.Sim3.from_quaternion([0.3, 0.1, 0.0, 1.0], [1.0, 2.0, 3.0], 2.5)


def keyframes(
    n_kf: int, height: int = H, seed: int = 0
) -> tuple[list[s2w.Keyframe], list[RefKeyframe]]:
    """Semi-dense keyframes: a smooth surface with noise, holes, variances spread
    across the thresholds, random poses of scale 0.5 … 2."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:height, 0:W].astype(np.float32)
    cam = s2w.PinholeCamera(517.3, 516.5, 318.6, 255.3, W, height)
    kfs, refs = [], []
    surface = 1.0 + 0.2 * np.sin(xx / 60.0) + 0.1 * np.cos(yy / 50.0)
    for i in range(n_kf):
        holes = np.sin(xx / 9.0 + rng.uniform(0, 6)) * np.sin(yy / 7.0) > 0.2
        idepth = (surface + rng.uniform(-0.01, 0.01, (height, W))).astype(np.float32)
        idepth[holes] = 0.0
        var = (10.0 ** rng.uniform(-6, -2, (height, W))).astype(np.float32)
        color = rng.integers(0, 256, (height, W, 3), dtype=np.uint8)
        q = [0.1, rng.uniform(-0.5, 0.5), 0.05, 1.0]
        pose = s2w.Sim3.from_quaternion(
            q, [rng.uniform(-2, 2), 0.0, rng.uniform(-2, 2)], rng.uniform(0.5, 2.0)
        )
        kfs.append(s2w.Keyframe(i, 0.1 * i, pose, cam, idepth, var, color))
        refs.append(
            RefKeyframe(
                i, pose.matrix(), pose.scale, cam.fx, cam.fy, cam.cx, cam.cy, idepth, var, color
            )
        )
    return kfs, refs


def _case(kfs: list[s2w.Keyframe], refs: list[RefKeyframe], cut: int | None) -> Case:
    flt = s2w.PointFilter(cut_first_keyframes=cut)
    ref_flt = RefFilter(cut_first_keyframes=cut)
    pixels = sum(k.camera.width * k.camera.height for k in kfs)
    ours = lambda: s2w.backproject(kfs, flt, transform=WORLD)  # noqa: E731
    peer = lambda: reference_vectorised(refs, ref_flt, WORLD.matrix())  # noqa: E731
    kept = len(ours())
    return Case(ours, peer, pixels, extras={"points_kept": float(kept)})


@register(
    "backproject",
    "backproject 640x480 keyframes, default filter",
    peer="numpy viewer rules (vectorised)",
    size=123,
    quick_size=16,
    smoke_size=7,
    target=5,
    unit="keyframes",
    work_unit="pixels",
    curve=(),
    issue="#3",
)
def _backproject(n_kf: int) -> Case:
    kfs, refs = keyframes(n_kf)
    case = _case(kfs, refs, 5)
    return case


@register(
    "backproject",
    "backproject (curve: pixels)",
    peer="numpy viewer rules (vectorised)",
    size=W * H,
    quick_size=W * H,
    smoke_size=W * 4,
    unit="pixels",
    curve=CURVE_SIZES,
)
def _backproject_pixels(n: int) -> Case:
    # Below one keyframe: one keyframe of fewer rows; above: whole keyframes.
    if n < W * H:
        kfs, refs = keyframes(1, height=max(3, n // W))
    else:
        kfs, refs = keyframes(max(1, round(n / (W * H))))
    return _case(kfs, refs, None)
