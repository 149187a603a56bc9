"""``align(dof=..., anchor=...)``, ``align_trajectories`` and ``convert`` with
degrees of freedom, anchoring, the one-to-one association and the fit-quality
refusals, from Python.

The reference for the 4-DoF fit is rpg_trajectory_evaluation's ``posyaw``
alignment over all frames, reimplemented here with numpy from
uzh-rpg/rpg_trajectory_evaluation@8c8ceec (MIT),
``src/rpg_trajectory_evaluation/align_utils.py`` (``alignPositionYaw`` with
``n_aligned=-1``) and ``align_trajectory.py`` (``align_umeyama(gt, est,
known_scale=True, yaw_only=True)``, ``get_best_yaw``, ``rot_z``), with its
timestamp association ``associate_timestamps.py`` (``associate``: every pair
closer than ``max_difference``, closest first, each stamp used once;
``load_stamped_dataset`` calls it with 0.02 s).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
from conftest import data_path

import slam2world as s2w

F64 = npt.NDArray[np.float64]


def rot_z(theta: float) -> F64:
    """``transformations.rotation_matrix(theta, [0, 0, 1])[:3, :3]``."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def get_best_yaw(c: F64) -> float:
    """rpg: maximise ``trace(Rz(theta) @ C)``."""
    a = c[0, 1] - c[1, 0]
    b = c[0, 0] + c[1, 1]
    return float(np.pi / 2 - np.arctan2(b, a))


def rpg_posyaw(p_es: F64, p_gt: F64) -> tuple[F64, F64]:
    """rpg ``alignPositionYaw(p_es, p_gt, ..., n_aligned=-1)``: ``gt = R @ est + t``."""
    model, data = p_gt, p_es  # "note the order"
    mu_m = model.mean(0)
    mu_d = data.mean(0)
    model_zc = model - mu_m
    data_zc = data - mu_d
    rot_c = data_zc.T @ model_zc
    r = rot_z(get_best_yaw(rot_c))
    t = mu_m - r @ mu_d
    return r, t


def yaw_sim3(theta: float, t: tuple[float, float, float], scale: float = 1.0) -> s2w.Sim3:
    return s2w.Sim3(rotation=rot_z(theta), translation=np.array(t), scale=scale)


def tilt(deg: float) -> F64:
    """A rotation of ``deg`` about a horizontal axis."""
    axis = np.array([0.6, -0.8, 0.0])
    a = np.radians(deg)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    r: F64 = np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * (k @ k)
    return r


@pytest.fixture(scope="module")
def ground_truth() -> F64:
    gt = s2w.Trajectory.read_euroc(str(data_path("euroc_v102", "V102_groundtruth.csv")))
    return np.asarray(gt.positions)


def synthetic(n: int = 120, seed: int = 0) -> F64:
    rng = np.random.default_rng(seed)
    i = np.arange(n, dtype=np.float64)
    path = np.stack([4 * np.cos(0.05 * i), 2.5 * np.sin(0.07 * i), 0.8 * np.sin(0.02 * i)], 1)
    return path + 0.2 * rng.standard_normal((n, 3))


def test_4dof_equals_rpg_posyaw_with_a_secret_yaw(ground_truth: F64) -> None:
    secret = yaw_sim3(2.1, (-6.5, 3.0, 1.25))
    est = secret.inverse().apply(ground_truth)
    fit = s2w.align(est, ground_truth, dof="4dof")
    r, t = rpg_posyaw(est, ground_truth)
    np.testing.assert_allclose(fit.transform.rotation, r, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fit.transform.translation, t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fit.transform.matrix(), secret.matrix(), rtol=0, atol=1e-12)
    assert fit.transform.scale == 1.0
    assert fit.rmse < 1e-12


def test_4dof_equals_rpg_posyaw_on_a_vio_like_estimate(ground_truth: F64) -> None:
    rng = np.random.default_rng(3)
    world = ground_truth[::20]
    n = len(world)
    drift = np.cumsum(0.002 * rng.standard_normal((n, 3)), axis=0)
    psi = np.radians(1.5) * np.arange(n) / n
    vio = np.einsum("nij,nj->ni", np.stack([rot_z(p) for p in psi]), world)
    vio += drift + 0.01 * rng.standard_normal((n, 3))
    est = yaw_sim3(-0.7, (2.0, 1.0, -0.3)).inverse().apply(vio)
    fit = s2w.align(est, world, dof="4dof")
    r, t = rpg_posyaw(est, world)
    np.testing.assert_allclose(fit.transform.rotation, r, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fit.transform.translation, t, rtol=0, atol=1e-9)
    d = fit.diagnostics["dof"]
    assert d["dof"] == "4dof" and d["anchor"] == "none"
    assert d["gravity_tilt_deg"] < 0.5
    assert 0.99 < d["yaw_determinacy"] <= 1.0
    # The covariance maps onto the Sim(3) parameters: no roll, pitch or scale.
    cov = fit.covariance
    assert cov.shape == (7, 7)
    assert np.all(cov[[0, 1, 6], :] == 0) and cov[2, 2] > 0
    assert fit.scale_interval(0.95) == (1.0, 1.0)


def test_scale_4dof_recovers_a_secret_scale(ground_truth: F64) -> None:
    secret = yaw_sim3(-2.5, (-4.0, 8.0, -1.5), scale=3.7)
    est = secret.inverse().apply(ground_truth)
    fit = s2w.align(est, ground_truth, dof="scale+4dof")
    np.testing.assert_allclose(fit.transform.matrix(), secret.matrix(), rtol=0, atol=1e-11)
    assert fit.transform.scale == pytest.approx(3.7, rel=1e-12)


def test_tilted_gravity_is_refused() -> None:
    world = synthetic()
    for deg, refused in [(3.0, True), (0.5, False)]:
        t = s2w.Sim3(rotation=rot_z(0.4) @ tilt(deg), translation=np.array([1.0, -2.0, 0.5]))
        est = t.inverse().apply(world)
        for dof in ["4dof", "scale+4dof"]:
            if refused:
                with pytest.raises(s2w.InvalidInputError, match=r'tilted.*dof="sim3"'):
                    s2w.align(est, world, dof=dof)
            else:
                fit = s2w.align(est, world, dof=dof)
                assert fit.diagnostics["dof"]["gravity_tilt_deg"] == pytest.approx(deg, abs=1e-9)
        assert s2w.align(est, world, dof="4dof", max_tilt_deg=None).rmse > 0
        assert s2w.align(est, world, dof="sim3").rmse < 1e-12


def test_anchor_first_pins_the_first_pair() -> None:
    rng = np.random.default_rng(1)
    world = synthetic(seed=1)
    est = yaw_sim3(0.9, (3.0, -1.0, 0.2), scale=0.5).inverse().apply(world)
    est = est + 0.1 * rng.standard_normal(est.shape)
    for dof in ["sim3", "se3", "4dof", "scale+4dof"]:
        free = s2w.align(est, world, dof=dof, max_tilt_deg=None)
        pinned = s2w.align(est, world, dof=dof, anchor="first", max_tilt_deg=None)
        assert pinned.residuals[0] < 1e-12
        assert free.residuals[0] > 1e-3
        assert pinned.rmse >= free.rmse
        np.testing.assert_allclose(pinned.transform.apply(est[:1]), world[:1], atol=1e-12)


def test_robust_4dof_flags_outliers() -> None:
    world = synthetic(80, seed=2)
    secret = yaw_sim3(-1.1, (0.5, 0.5, 0.5))
    est = secret.inverse().apply(world)
    bad = world.copy()
    bad[3::7] += np.array([6.0, -4.0, 2.0])
    fit = s2w.align(est, bad, dof="4dof", robust="ransac")
    assert fit.inliers is not None
    expected = np.ones(80, dtype=bool)
    expected[3::7] = False
    np.testing.assert_array_equal(fit.inliers, expected)
    np.testing.assert_allclose(fit.transform.matrix(), secret.matrix(), atol=1e-9)


def test_bad_arguments_raise_typed_errors() -> None:
    world = synthetic(20)
    with pytest.raises(s2w.InvalidInputError, match="scale\\+4dof"):
        s2w.align(world, world, dof="6dof")
    with pytest.raises(s2w.InvalidInputError, match="first"):
        s2w.align(world, world, dof="4dof", anchor="last")
    with pytest.raises(s2w.InvalidInputError, match=r"\(N, 3\)"):
        s2w.align(world[:, :2], world, dof="4dof")
    with pytest.raises(s2w.InvalidInputError, match="target"):
        s2w.align(world, world[:5], dof="4dof")
    with pytest.raises(s2w.InvalidInputError, match="weights"):
        s2w.align(world, world, dof="4dof", weights=np.ones(3))
    with pytest.raises(s2w.InvalidInputError, match="max_tilt_deg"):
        s2w.align(world, world, dof="4dof", max_tilt_deg=-1.0)
    with pytest.raises(s2w.InvalidInputError, match="scale\\+4dof"):
        s2w.align(world, world, dof="scale+4dof", scale=False)
    column = np.zeros((10, 3))
    column[:, 2] = np.arange(10.0)
    with pytest.raises(s2w.DegenerateError, match="horizontally"):
        s2w.align(column, column + 1.0, dof="4dof")


def test_sim3_and_se3_are_the_plain_fit() -> None:
    """``dof="se3"`` is ``scale=False``; ``sim3``/``se3`` without anchor keep the plain
    fit (its lazily computed residuals and covariance), an anchor takes the dof path."""
    rng = np.random.default_rng(4)
    world = synthetic(50, seed=4)
    est = world @ rot_z(0.3).T * 0.2 + 0.05 * rng.standard_normal(world.shape)
    w = rng.uniform(0.5, 2.0, len(world))
    se3 = s2w.align(est, world, dof="se3", weights=w)
    plain = s2w.align(est, world, scale=False, weights=w)
    np.testing.assert_array_equal(se3.transform.matrix(), plain.transform.matrix())
    np.testing.assert_array_equal(se3.covariance, plain.covariance)
    assert se3.transform.scale == 1.0
    assert s2w.align(est, world, dof="4dof", scale=False).transform.scale == 1.0
    for dof in ["sim3", "se3"]:
        free = s2w.align(est, world, dof=dof, weights=w)
        assert "dof" not in free.diagnostics
        pinned = s2w.align(est, world, dof=dof, anchor="first", weights=w)
        assert pinned.diagnostics["dof"]["anchor"] == "first"
        assert pinned.residuals[0] < 1e-12 < free.residuals[0]
        # "none" is no anchor at all.
        none = s2w.align(est, world, dof=dof, anchor="none", weights=w)
        np.testing.assert_array_equal(none.transform.matrix(), free.transform.matrix())


def rpg_associate(first: F64, second: F64, max_difference: float) -> list[tuple[int, int]]:
    """rpg ``associate_timestamps.associate(first, second, 0.0, max_difference)``."""
    potential = sorted(
        (abs(a - b), ia, ib)
        for ia, a in enumerate(first)
        for ib, b in enumerate(second)
        if abs(a - b) < max_difference
    )
    used_a: set[int] = set()
    used_b: set[int] = set()
    matches = []
    for _, ia, ib in potential:
        if ia not in used_a and ib not in used_b:
            used_a.add(ia)
            used_b.add(ib)
            matches.append((ia, ib))
    return sorted(matches)


def test_align_trajectories_4dof_is_rpg_end_to_end() -> None:
    """EuRoC V1_02: the VIO-like estimate against the ground truth as rpg evaluates it:
    its association (one to one, 0.02 s), then ``posyaw`` over every pair."""
    gt = s2w.Trajectory.read_euroc(str(data_path("euroc_v102", "V102_groundtruth.csv")))
    est = s2w.Trajectory.read_tum(str(data_path("euroc_v102", "V102.txt")))
    t_es, t_gt = np.asarray(est.timestamps), np.asarray(gt.timestamps)
    # The candidate pairs lie within 0.02 s: search a window, not the full product.
    lo = np.searchsorted(t_gt, t_es - 0.02)
    hi = np.searchsorted(t_gt, t_es + 0.02, side="right")
    window = sorted({int(j) for a, b in zip(lo, hi) for j in range(a, b)})
    sub = [(ie, window[k]) for ie, k in rpg_associate(t_es, t_gt[window], 0.02)]
    fit = s2w.align_trajectories(est, gt, dof="4dof", association="one_to_one", max_diff=0.02)
    idx_s, idx_r = fit.pairs
    assert list(zip(idx_s.tolist(), idx_r.tolist())) == sub
    p_es = np.asarray(est.positions)[idx_s]
    p_gt = np.asarray(gt.positions)[idx_r]
    r, t = rpg_posyaw(p_es, p_gt)
    np.testing.assert_allclose(fit.transform.rotation, r, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fit.transform.translation, t, rtol=0, atol=1e-9)
    assert fit.transform.scale == 1.0
    assert fit.dof == "4dof" and fit.anchor == "none" and fit.association == "one_to_one"
    assert fit.alignment.diagnostics["dof"]["gravity_tilt_deg"] < 0.5
    assert fit.quality["noise_source"] == "second_differences"
    assert fit.quality["residual_over_spread"] < 0.2
    # Anchored, the first pair's error is 0.
    pinned = s2w.align_trajectories(est, gt, dof="4dof", anchor="first")
    assert pinned.residuals[0] < 1e-12 < fit.residuals[0]


def test_align_trajectories_refusals_raise_degenerate_error() -> None:
    rng = np.random.default_rng(9)
    n = 80
    t = np.arange(n) * 0.1
    path = synthetic(n, seed=9)
    slam = s2w.Trajectory(t, path)
    still = s2w.Trajectory(t, np.array([3.0, 1.0, 0.0]) + rng.standard_normal((n, 3)))
    with pytest.raises(s2w.DegenerateError, match="does not move"):
        s2w.align_trajectories(slam, still)
    with pytest.raises(s2w.DegenerateError, match="does not move"):
        s2w.align_trajectories(slam, still, reference_noise=5.0)
    loose = s2w.align_trajectories(slam, still, fit_checks=False)
    assert loose.quality["residual_over_spread"] > 0.9
    with pytest.raises(s2w.InvalidInputError, match="reference_noise"):
        s2w.align_trajectories(slam, still, reference_noise=-1.0)
    with pytest.raises(s2w.InvalidInputError, match="association"):
        s2w.align_trajectories(slam, slam, association="nearest")
    # Half the reference in another frame (a jump of 6400 km): no rigid
    # transform explains it (a Sim(3) fit stretches the estimate towards both
    # halves instead; its figure is in the report).
    mixed = path.copy()
    mixed[n // 2 :] += np.array([6.4e6, 0.0, 0.0])
    with pytest.raises(s2w.DegenerateError, match="explains almost none"):
        s2w.align_trajectories(slam, s2w.Trajectory(t, mixed), dof="se3")
    stretched = s2w.align_trajectories(slam, s2w.Trajectory(t, mixed))
    assert stretched.transform.scale > 1e3
    # A tilted estimate under a yaw-only fit.
    tilted = s2w.Trajectory(t, path @ tilt(5.0).T)
    with pytest.raises(s2w.InvalidInputError, match="5.000 deg"):
        s2w.align_trajectories(tilted, slam, dof="4dof")
    ok = s2w.align_trajectories(tilted, slam, dof="4dof", max_tilt_deg=None, fit_checks=False)
    assert ok.dof == "4dof"


def test_windowed_fits_keep_the_dof() -> None:
    n = 150
    t = np.arange(n) * 0.1
    world = synthetic(n, seed=5)
    est = yaw_sim3(0.5, (1.0, 2.0, 0.0)).inverse().apply(world)
    w = s2w.align_windowed(s2w.Trajectory(t, est), s2w.Trajectory(t, world), window=15, dof="4dof")
    assert np.all(w.scales == 1.0)
    for tr in w.transforms:
        np.testing.assert_allclose(tr.rotation[2], [0.0, 0.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(
        w.single.transform.matrix(), yaw_sim3(0.5, (1.0, 2.0, 0.0)).matrix(), atol=1e-9
    )
    one = s2w.align_windowed(
        s2w.Trajectory(t, est), s2w.Trajectory(t, world), window=15, association="one_to_one"
    )
    assert len(one.times) == n


def test_convert_takes_the_dof_anchor_and_association(tmp_path: Path) -> None:
    """``convert`` passes the options to the fit and the report names them."""
    from test_mcap import S_TRUE, _write_aligned_lsd_log

    path = tmp_path / "lsd.mcap"
    _write_aligned_lsd_log(path, noise=0.01)
    none = s2w.PointFilter.none()
    conv = s2w.convert(path, filter=none, anchor="first", association="one_to_one")
    fit = conv.report["fit"]
    assert (fit["dof"], fit["anchor"], fit["association"]) == ("sim3", "first", "one_to_one")
    assert conv.report["pairs"][0]["error"] < 1e-9 < conv.report["pairs"][1]["error"]
    assert conv.alignment is not None and conv.alignment.anchor == "first"
    assert conv.transform.scale == pytest.approx(S_TRUE, rel=1e-2)
    assert fit["quality"]["residual_over_spread"] < 0.05
    # The log's SLAM frame is not gravity-aligned: a yaw-only fit is refused,
    # naming the angle; an SE(3) fit keeps the scale at 1.
    with pytest.raises(s2w.InvalidInputError, match=r"tilted: the Sim\(3\) fit turns its z axis"):
        s2w.convert(path, filter=none, dof="4dof")
    se3 = s2w.convert(path, filter=none, dof="se3", fit_checks=False)
    assert se3.transform.scale == 1.0 and se3.report["fit"]["dof"] == "se3"
    assert "dof_diagnostics" not in se3.report["fit"]
    with pytest.raises(s2w.InvalidInputError, match="dof"):
        s2w.convert(path, dof="7dof")
