"""Beyond one closed-form fit from Python: robust fit, covariance intervals,
start-up stages, time offset, windowed alignment, extrinsic."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pytest
from conftest import data_path

import slam2world as s2w

EUROC_T_BS = np.array(
    [
        [0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975],
        [0.999557249008, 0.0149672133247, 0.025715529948, -0.064676986768],
        [-0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949],
        [0.0, 0.0, 0.0, 1.0],
    ]
)


def cloud(rng: np.random.Generator, n: int) -> npt.NDArray[np.float64]:
    return rng.uniform(-1.0, 1.0, size=(n, 3))


def truth() -> s2w.Sim3:
    return s2w.Sim3.from_quaternion([0.1, -0.3, 0.2, 0.9], [1.0, 2.0, -0.5], 3.7)


def read_ns(path: object) -> s2w.Trajectory:
    """ORB-SLAM3 stamps are nanoseconds written as floats."""
    t = s2w.Trajectory.read_tum(str(path))
    return s2w.Trajectory(t.timestamps * 1e-9, t.positions, t.orientations)


def test_robust_align_finds_outliers_and_equals_plain_without() -> None:
    rng = np.random.default_rng(0)
    a = cloud(rng, 80)
    b = truth().apply(a)
    plain = s2w.align(a, b)
    rob = s2w.align(a, b, robust="ransac")
    np.testing.assert_allclose(
        rob.transform.matrix(), plain.transform.matrix(), rtol=1e-12, atol=1e-12
    )
    assert plain.inliers is None
    assert rob.inliers is not None and rob.inliers.all()
    bad = b.copy()
    out = rng.choice(80, size=24, replace=False)
    bad[out] += rng.normal(size=(24, 3)) * 3.0
    r = s2w.align(a, bad, robust="ransac", loss="cauchy")
    assert r.inliers is not None
    assert r.inliers.dtype == np.bool_ and r.inliers.shape == (80,)
    assert not r.inliers[out].any()
    assert r.inliers.sum() == 56
    assert abs(r.transform.scale - 3.7) < 1e-9
    with pytest.raises(s2w.InvalidInputError):
        s2w.align(a, b, robust="lmeds")
    with pytest.raises(s2w.InvalidInputError):
        s2w.align(a, b, inlier_threshold=0.1)


def test_covariance_interval_covers_by_monte_carlo() -> None:
    rng = np.random.default_rng(1)
    t = truth()
    hits = 0
    runs = 200
    for _ in range(runs):
        a = cloud(rng, 40)
        b = t.apply(a) + rng.normal(scale=0.05, size=(40, 3))
        fit = s2w.align(a, b)
        cov = fit.covariance
        assert cov.shape == (7, 7)
        np.testing.assert_allclose(cov, cov.T, atol=1e-15)
        lo, hi = fit.scale_interval(0.95)
        hits += lo <= 3.7 <= hi
        assert lo < fit.transform.scale < hi
    assert 0.88 <= hits / runs <= 0.99
    d = fit.intervals(0.9)
    assert set(d) >= {"scale", "translation", "rotation_half_width_deg", "sigma"}
    with pytest.raises(s2w.InvalidInputError):
        fit.scale_interval(1.5)


def test_detect_stages_on_synthetic_factors() -> None:
    rng = np.random.default_rng(2)
    k = np.arange(1200)
    level = np.full(k.size, np.log(9.0))
    level[k < 300] = np.log(2.0)
    ramp = (k >= 300) & (k < 700)
    level[ramp] = np.log(2.0) + (np.log(9.0) - np.log(2.0)) * (k[ramp] - 300) / 400
    p = np.exp(level + rng.normal(scale=0.1, size=k.size))
    st = s2w.detect_stages(p)
    # A straight ramp over 300..700: its kinks are rounded by the smooth step the rule
    # fits, so the stable start lands after 700 (never before), within a quarter of the span.
    assert 700 <= st.stable_start <= 800
    assert 200 <= st.converging_start < 400
    assert abs(st.stable_level - 9.0) < 0.3
    assert "stable from" in st.describe()
    with pytest.raises(s2w.InvalidInputError):
        s2w.detect_stages(-p)


def test_windowed_alignment_follows_scale_drift() -> None:
    n = 200
    times = np.arange(n) * 0.1
    world = np.stack([times, 3 * np.sin(0.7 * times), np.cos(0.3 * times)], axis=1)
    steps = np.diff(world, axis=0) / 5.0 * (1.0 + 0.3 * np.arange(1, n) / n)[:, None]
    slam = np.vstack([np.zeros(3), np.cumsum(steps, axis=0)])
    s = s2w.Trajectory(times, slam)
    r = s2w.Trajectory(times, world)
    w = s2w.align_windowed(s, r, window=15)
    assert w.rmse < 0.1 * w.single.rmse
    assert len(w.transforms) == n and w.scales.shape == (n,)
    assert w.scales[10] > 1.2 * w.scales[190]
    mid = w.transform_at(5.05).scale
    assert w.scales[51] < mid < w.scales[50]
    by_distance = s2w.align_windowed(s, r, window=4.0)
    assert by_distance.rmse < 0.2 * by_distance.single.rmse


@pytest.mark.slow
def test_extended_trajectory_fit_on_euroc() -> None:
    folder = "euroc_mh01_orbslam3_mono"
    est = read_ns(data_path(folder, "f_dataset-MH01_mono.txt"))
    gt = s2w.Trajectory.read_tum(str(data_path(folder, "MH_01_easy.txt")))
    plain = s2w.align_trajectories(est, gt)
    assert plain.offset == 0.0 and plain.fit_start == 0 and plain.stages is None
    lo, hi = plain.scale_interval()
    assert lo < plain.transform.scale < hi
    lever = s2w.align_trajectories(est, gt, body_from_cam=s2w.Sim3.from_matrix(EUROC_T_BS))
    assert lever.rmse < 0.8 * plain.rmse
    auto = s2w.align_trajectories(est, gt, skip_init="auto")
    assert auto.stages is not None
    assert auto.fit_start == auto.stages.stable_start > 0
    assert "dropped" in auto.skip_reason
    late = s2w.Trajectory(est.timestamps - 0.05, est.positions, est.orientations)
    base = s2w.estimate_time_offset(est, gt)
    off = s2w.estimate_time_offset(late, gt)
    assert abs(off - base - 0.05) < 2e-3
    fitted = s2w.align_trajectories(late, gt, estimate_offset=True)
    assert abs(fitted.offset - off) < 1e-9
    rob = s2w.align_trajectories(est, gt, robust="ransac")
    assert rob.inliers is not None and rob.inliers.mean() > 0.8
    with pytest.raises(s2w.InvalidInputError):
        s2w.align_trajectories(est, gt, skip_init="sometimes")


def test_body_from_cam_is_estimated_on_synthetic_poses() -> None:
    body_from_cam = s2w.Sim3.from_quaternion([0.5, -0.5, 0.5, 0.5], [-0.02, -0.06, 0.01])
    t_ws = truth()
    f = np.arange(120) * 0.1
    p = np.stack([np.sin(f), np.cos(0.7 * f), 0.3 * f], axis=1)
    rots = [
        s2w.Sim3.from_quaternion(
            [np.sin(0.25 * np.sin(x)), np.sin(0.2 * np.cos(1.3 * x)), np.sin(0.5 * x), 1.0]
        )
        for x in f
    ]
    q = np.array([r.quaternion for r in rots])
    slam = s2w.Trajectory(f, p, q)
    cam_from_body = body_from_cam.inverse()
    cams = [t_ws @ s2w.Sim3.from_quaternion(qq, pp) for qq, pp in zip(q, p)]
    # The lever arm is metres: it is not scaled with the SLAM frame.
    ref = s2w.Trajectory(
        f,
        np.array([c.translation + c.rotation @ cam_from_body.translation for c in cams]),
        np.array([(c @ cam_from_body).quaternion for c in cams]),
    )
    est, fit, rot_rmse = s2w.estimate_body_from_cam(slam, ref)
    assert fit.rmse < 1e-8
    assert rot_rmse < 1e-6
    np.testing.assert_allclose(est.matrix(), body_from_cam.matrix(), atol=1e-8)
    with pytest.raises(s2w.InvalidInputError, match="orientations"):
        s2w.estimate_body_from_cam(s2w.Trajectory(f, p), ref)
