"""The synthetic experiment from Python: shapes, truth, reproducibility, scoring."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pytest

import slam2world as s2w
from slam2world.plot import frame_scale_factors


@pytest.fixture(scope="module")
def sim() -> s2w.Simulation:
    return s2w.simulate(seed=3, reduced=8)


@pytest.fixture(scope="module")
def clean() -> s2w.Simulation:
    return s2w.simulate(seed=3, reduced=8, noiseless=True)


def slam_points(sim: s2w.Simulation) -> npt.NDArray[np.float64]:
    """Every keyframe pixel with depth, in the SLAM frame (numpy, independent of the core)."""
    fx, fy, cx, cy, w, h = sim.camera
    ys, xs = np.mgrid[0:h, 0:w]
    out = []
    for pose, idepth in zip(sim.keyframe_poses, sim.keyframe_idepth):
        ok = idepth > 0
        d = 1.0 / idepth[ok].astype(np.float64)
        cam = np.column_stack([(xs[ok] - cx) / fx * d, (ys[ok] - cy) / fy * d, d])
        out.append(pose.apply(cam))
    return np.vstack(out)


def test_shapes_and_types(sim: s2w.Simulation) -> None:
    cfg = sim.config
    k, n = cfg["n_keyframes"], cfg["n_frames"]
    _, _, _, _, w, h = sim.camera
    assert sim.keyframe_idepth.shape == (k, h, w)
    assert sim.keyframe_idepth.dtype == np.float32
    assert sim.keyframe_idepth_var.shape == (k, h, w)
    assert sim.keyframe_intensity.dtype == np.uint8
    assert sim.slam_positions.shape == (n, 3)
    orient = sim.slam_orientations
    assert orient is not None and orient.shape == (n, 4)
    np.testing.assert_allclose(np.linalg.norm(orient, axis=1), 1.0, atol=1e-12)
    assert sim.gyro.shape == sim.accel.shape == (sim.imu_timestamps.size, 3)
    assert sim.reference_positions.shape == (sim.reference_timestamps.size, 3)
    assert sim.scale_errors.shape == (n - 1,)
    assert sim.stages == (cfg["converge_start"], cfg["stable_start"])
    assert np.all(np.diff(sim.keyframe_timestamps) > 0)
    assert sim.cube_min.shape == (8, 3)
    assert sim.plane_half == (5.0, 2.5)


def test_normalised_inverse_depth(sim: s2w.Simulation) -> None:
    for idepth in sim.keyframe_idepth:
        assert abs(float(idepth[idepth > 0].mean()) - 1.0) < 1e-5


def test_noiseless_cloud_lies_on_the_scene(clean: s2w.Simulation) -> None:
    pts = clean.t_world_slam.apply(slam_points(clean))
    d = s2w.point_distances(clean, pts)
    assert d.shape == (pts.shape[0],)
    assert float(d.max()) < 2e-5
    # A wrong scale moves points off the surfaces.
    t = clean.t_world_slam
    wrong = s2w.Sim3.from_quaternion(t.quaternion, t.translation, t.scale * 1.05)
    assert float(np.median(s2w.point_distances(clean, wrong.apply(slam_points(clean))))) > 0.01


def test_evaluate_with_the_true_transform(clean: s2w.Simulation) -> None:
    pts = clean.t_world_slam.apply(slam_points(clean).astype(np.float32))
    ev = s2w.evaluate(clean, pts, clean.t_world_slam)
    assert set(ev) == {"cloud", "transform", "ape"}
    assert ev["transform"]["scale_error"] == 0.0
    assert ev["transform"]["gravity_error_deg"] < 1e-9
    assert ev["cloud"]["n"] == pts.shape[0]
    assert ev["cloud"]["p95"] < 2e-5
    assert ev["ape"]["rmse"] < 1e-6
    tilted = s2w.Sim3.from_quaternion([0.01, 0.0, 0.0, 1.0]) @ clean.t_world_slam
    ev2 = s2w.evaluate(clean, pts, tilted)
    assert ev2["transform"]["gravity_error_deg"] == pytest.approx(np.degrees(2 * np.arctan(0.01)))
    assert ev2["ape"]["rmse"] > 1e-3


def test_same_seed_same_numbers() -> None:
    a = s2w.simulate(seed=5, reduced=16, n_keyframes=3)
    b = s2w.simulate(seed=5, reduced=16, n_keyframes=3)
    c = s2w.simulate(seed=6, reduced=16, n_keyframes=3)
    np.testing.assert_array_equal(a.keyframe_idepth, b.keyframe_idepth)
    np.testing.assert_array_equal(a.accel, b.accel)
    np.testing.assert_array_equal(a.t_world_slam.matrix(), b.t_world_slam.matrix())
    assert not np.array_equal(a.accel, c.accel)


def test_scale_factors_show_the_stages(sim: s2w.Simulation) -> None:
    p = frame_scale_factors(
        sim.slam_timestamps,
        sim.slam_positions,
        sim.reference_timestamps,
        sim.reference_positions,
    )
    a, b = sim.stages
    s2 = sim.t_world_slam.scale**2
    assert abs(float(np.median(p[b:])) / s2 - 1.0) < 0.1
    assert abs(float(np.median(p[:a])) / s2 - 1.0) > 0.3


def test_bad_arguments() -> None:
    with pytest.raises(s2w.InvalidInputError, match="unknown name"):
        s2w.simulate(reduced=16, no_such_parameter=1.0)
    with pytest.raises(s2w.InvalidInputError):
        s2w.simulate(reduced=16, stable_start=10**6)
    with pytest.raises(s2w.InvalidInputError):
        s2w.simulate(reduced=16, n_frames=1.5)
    sim = s2w.simulate(reduced=16, n_keyframes=3)
    with pytest.raises(s2w.InvalidInputError):
        s2w.point_distances(sim, np.zeros((4, 2)))
    with pytest.raises(s2w.InvalidInputError):
        s2w.evaluate(sim, np.zeros((4, 3)), sim.t_world_slam, timestamps=np.zeros(3))


def test_convert_with_the_core(sim: s2w.Simulation) -> None:
    """The whole experiment in Python: align, backproject, score."""
    fit = s2w.align_trajectories(sim.keyframe_trajectory, sim.reference)
    est = fit.transform
    cloud = s2w.backproject(sim.keyframes, s2w.PointFilter(), transform=est)
    truth = s2w.backproject(sim.keyframes, s2w.PointFilter(), transform=sim.t_world_slam)
    ev = s2w.evaluate(sim, cloud.points, est)
    ev_true = s2w.evaluate(sim, truth.points, sim.t_world_slam)
    assert abs(ev["transform"]["scale_error"]) < 5e-3
    assert ev["transform"]["gravity_error_deg"] < 0.5
    assert ev["cloud"]["rmse"] <= 1.1 * ev_true["cloud"]["rmse"]
    assert len(sim.slam_trajectory) == sim.config["n_frames"]
    assert len(sim.true_trajectory) == sim.config["n_frames"]
