"""A Rerun recording (``.rrd``) of a conversion's outputs, for users of that viewer.

``python -m slam2world.rerun OUTDIR [-o OUTDIR/world.rrd]`` reads what ``slam2world
convert`` (or ``demo``) wrote into ``OUTDIR``: the world cloud (``cloud.ply``), the paths
and occupied voxels (the data block of ``report.html``) and ``T_world_slam``
(``report.json``), and logs them under ``world/``: ``world/cloud`` (points with their
image colours), ``world/reference`` and ``world/slam`` (line strips; the SLAM path
coloured by the error of each matched pair as points ``world/slam/pairs``),
``world/voxels`` (boxes) and ``world/slam_frame`` (the transform ``T_world_slam``).

Needs the ``rerun-sdk`` package, imported only here; without it the module says so and
exits 1. Units: metres, world frame z up.
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = ["MissingRerun", "read_outputs", "write_rrd"]

_DATA = re.compile(r'<script id="s2w-data" type="application/json">(.*?)</script>', re.S)


class MissingRerun(ImportError):
    """``rerun-sdk`` is not installed."""


def _rerun() -> Any:
    try:
        import rerun  # type: ignore[import-not-found, unused-ignore]
    except ImportError as e:
        raise MissingRerun(
            "writing a Rerun recording needs the rerun-sdk package (pip install rerun-sdk)"
        ) from e
    return rerun


def _f32(text: str) -> npt.NDArray[np.float32]:
    return np.frombuffer(base64.b64decode(text), dtype="<f4").astype(np.float32)


def read_outputs(folder: str | os.PathLike[str]) -> dict[str, Any]:
    """The arrays of an output folder: ``cloud`` (N, 3) and ``colors`` (N, 3) or None,
    ``estimate`` / ``reference`` paths (M, 3), ``pairs`` (slam_index, error), ``voxels``
    centres (K, 3) and edges (K,), and ``t_world_slam`` (4, 4)."""
    from . import read_ply

    d = Path(folder)
    report = json.loads((d / "report.json").read_text())
    match = _DATA.search((d / "report.html").read_text())
    if match is None:
        raise ValueError(f"{d / 'report.html'}: no slam2world data block")
    fig = json.loads(match[1])["figures"]
    origin = np.asarray(fig["origin"], dtype=np.float64)
    cloud = read_ply(d / "cloud.ply")
    out: dict[str, Any] = {
        "cloud": np.asarray(cloud.points),
        "colors": None if cloud.colors is None else np.asarray(cloud.colors),
        "estimate": np.asarray(fig["estimate"]["xyz"], dtype=np.float64).reshape(-1, 3),
        "reference": None
        if fig["reference"] is None
        else np.asarray(fig["reference"]["xyz"], dtype=np.float64).reshape(-1, 3),
        "pair_index": np.asarray(fig["pairs"]["slam_index"], dtype=np.int64),
        "pair_error": np.asarray(fig["pairs"]["error"], dtype=np.float64),
        "voxel_centers": np.zeros((0, 3)),
        "voxel_sizes": np.zeros(0),
        "t_world_slam": np.asarray(report["t_world_slam"]["matrix"], dtype=np.float64),
    }
    if fig.get("voxels"):
        c = _f32(fig["voxels"]["center"]).reshape(-1, 3).astype(np.float64) + origin
        out["voxel_centers"] = c
        out["voxel_sizes"] = _f32(fig["voxels"]["size"]).astype(np.float64)
    return out


def _height_colors(z: npt.NDArray[np.float64]) -> npt.NDArray[np.uint8]:
    import matplotlib

    lo, hi = (float(v) for v in np.percentile(z, [1, 99])) if z.size else (0.0, 1.0)
    t = np.clip((z - lo) / max(hi - lo, 1e-9), 0, 1)
    rgba = matplotlib.colormaps["viridis"](t)
    return (rgba[:, :3] * 255).astype(np.uint8)


def write_rrd(folder: str | os.PathLike[str], path: str | os.PathLike[str]) -> Path:
    """Logs the outputs in ``folder`` into the Rerun recording ``path``; raises
    :class:`MissingRerun` without ``rerun-sdk``."""
    rr = _rerun()
    data = read_outputs(folder)
    out = Path(path)
    rec = rr.RecordingStream(application_id="slam2world")
    rec.save(str(out))
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    m = data["t_world_slam"]
    s = float(np.cbrt(np.linalg.det(m[:3, :3])))
    rec.log(
        "world/slam_frame",
        rr.Transform3D(translation=m[:3, 3], mat3x3=m[:3, :3] / s, scale=s),
        static=True,
    )
    pts = data["cloud"]
    colors = data["colors"] if data["colors"] is not None else _height_colors(pts[:, 2])
    rec.log("world/cloud", rr.Points3D(pts, colors=colors, radii=0.01), static=True)
    if data["reference"] is not None:
        rec.log(
            "world/reference",
            rr.LineStrips3D([data["reference"]], colors=[[160, 160, 170]]),
            static=True,
        )
    rec.log("world/slam", rr.LineStrips3D([data["estimate"]], colors=[[255, 150, 40]]), static=True)
    if data["pair_error"].size:
        e = data["pair_error"]
        import matplotlib

        t = (e - e.min()) / max(float(np.ptp(e)), 1e-12)
        c = (matplotlib.colormaps["plasma"](t)[:, :3] * 255).astype(np.uint8)
        rec.log(
            "world/slam/pairs",
            rr.Points3D(data["estimate"][data["pair_index"]], colors=c, radii=0.02),
            static=True,
        )
    if data["voxel_sizes"].size:
        rec.log(
            "world/voxels",
            rr.Boxes3D(
                centers=data["voxel_centers"],
                half_sizes=np.repeat(data["voxel_sizes"][:, None] / 2, 3, axis=1),
                colors=_height_colors(data["voxel_centers"][:, 2]),
            ),
            static=True,
        )
    if hasattr(rec, "flush"):
        rec.flush()
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m slam2world.rerun OUTDIR [-o FILE.rrd]``."""
    p = argparse.ArgumentParser(prog="python -m slam2world.rerun", description=__doc__)
    p.add_argument("folder", help="an output folder of slam2world convert or demo")
    p.add_argument("-o", "--output", help="the recording (default: FOLDER/world.rrd)")
    a = p.parse_args(argv)
    target = a.output or str(Path(a.folder) / "world.rrd")
    try:
        print(write_rrd(a.folder, target))
    except MissingRerun as e:
        print(f"slam2world.rerun: {e}", file=sys.stderr)
        return 1
    except (OSError, KeyError, ValueError) as e:
        print(f"slam2world.rerun: error: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
