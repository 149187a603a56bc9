"""The paper's figures: files exist, are PNG, and are not blank."""

from __future__ import annotations

from pathlib import Path

import matplotlib.image
import numpy as np
import pytest

import slam2world as s2w
from slam2world import plot

PNG = b"\x89PNG\r\n\x1a\n"


def check_png(path: Path, min_bytes: int = 15_000) -> None:
    assert path.exists(), path
    data = path.read_bytes()
    assert data[:8] == PNG
    assert len(data) > min_bytes, f"{path} is only {len(data)} bytes"
    img = matplotlib.image.imread(path)
    assert img.shape[0] > 300 and img.shape[1] > 500
    # Not a single colour: something was drawn.
    assert float(img[..., :3].std()) > 0.02


@pytest.fixture(scope="module")
def sim() -> s2w.Simulation:
    return s2w.simulate(seed=1, reduced=8)


def world_points(sim: s2w.Simulation) -> np.ndarray:
    fx, fy, cx, cy, w, h = sim.camera
    ys, xs = np.mgrid[0:h, 0:w]
    out = []
    for pose, idepth in zip(sim.keyframe_poses, sim.keyframe_idepth):
        ok = idepth > 0
        d = 1.0 / idepth[ok].astype(np.float64)
        out.append(pose.apply(np.column_stack([(xs[ok] - cx) / fx * d, (ys[ok] - cy) / fy * d, d])))
    return sim.t_world_slam.apply(np.vstack(out))


@pytest.mark.slow
def test_every_figure(sim: s2w.Simulation, tmp_path: Path) -> None:
    pts = world_points(sim)
    dist = s2w.point_distances(sim, pts)
    p_k = plot.frame_scale_factors(
        sim.slam_timestamps, sim.slam_positions, sim.reference_timestamps, sim.reference_positions
    )
    files = [
        plot.plot_paths(sim.true_positions, sim.slam_positions, tmp_path / "paths.png"),
        plot.plot_scale_factors(
            p_k, sim.stages, tmp_path / "p_k.png", true_level=sim.t_world_slam.scale**2
        ),
        plot.plot_cloud(
            pts,
            tmp_path / "cloud.png",
            cube_min=sim.cube_min,
            cube_size=sim.cube_size,
            plane_half=sim.plane_half,
            trajectory=sim.true_positions,
        ),
        plot.plot_error_histogram(dist, tmp_path / "hist.png", reference=dist * 0.9),
    ]
    for f in files:
        check_png(f)
    # Written by rename: no temporary files left beside them.
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(f.name for f in files)


def test_bad_input_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        plot.plot_paths(np.zeros((5, 2)), np.zeros((5, 3)), tmp_path / "x.png")
    with pytest.raises(ValueError):
        plot.plot_error_histogram(np.zeros(0), tmp_path / "y.png")
    assert not list(tmp_path.iterdir())


def test_octree_figure(tmp_path: Path) -> None:
    # A floor of 0.1 m voxels with a 0.4 m cube standing on it, one pruned 0.2 m leaf.
    xs = np.arange(-2.0, 2.0, 0.1) + 0.05
    floor = np.array([[x, y, 0.05, 0.1] for x in xs for y in xs])
    cube = np.array(
        [[x, y, z, 0.1] for x in xs[:4] for y in xs[:4] for z in np.arange(0.15, 0.5, 0.1)]
    )
    pruned = np.array([[1.1, 1.1, 0.3, 0.2]])
    out = plot.plot_octree(
        np.vstack([floor, cube, pruned]),
        tmp_path / "octree.png",
        resolution=0.1,
        cube_min=[[-2.0, -2.0, 0.0]],
        cube_size=0.4,
        plane_half=(2.0, 2.0),
    )
    check_png(out)
    # The pruned leaf counts as its eight voxels.
    idx = plot._finest_voxels(pruned, 0.1)
    assert idx.shape == (8, 3)
    assert sorted({tuple(i) for i in idx}) == [
        (a, b, c) for a in (10, 11) for b in (10, 11) for c in (2, 3)
    ]
    # A lone voxel shows five faces (not its bottom); two stacked ones nine (4 + 5).
    assert plot._exposed_faces(np.array([[0, 0, 0]]))[0].shape == (5, 4, 3)
    assert plot._exposed_faces(np.array([[0, 0, 0], [0, 0, 1]]))[0].shape == (9, 4, 3)
    with pytest.raises(ValueError, match=r"\(N, 4\)"):
        plot.plot_octree(
            np.zeros((3, 3)),
            tmp_path / "x.png",
            resolution=0.1,
            cube_min=[[0, 0, 0]],
            cube_size=1.0,
            plane_half=(1, 1),
        )


def test_demo_folder_missing_is_an_error(tmp_path: Path) -> None:
    assert plot.main([str(tmp_path)]) == 1
    assert plot.main([]) == 2


@pytest.mark.slow
def test_demo_writes_its_figures(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import sys

    monkeypatch.setenv("SLAM2WORLD_PYTHON", sys.executable)
    out = tmp_path / "demo"
    assert s2w._slam2world.run_cli(["slam2world", "demo", "-o", str(out), "--reduced", "8"]) == 0
    for name in (
        "paths.png",
        "scale_factors.png",
        "cloud.png",
        "error_histogram.png",
        "octree.png",
    ):
        check_png(out / name)
    assert (out / "map.bt").stat().st_size > 1000
    assert (out / "demo.json").stat().st_size > 1000
