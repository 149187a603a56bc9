"""``align_dof``: degrees of freedom and anchoring from Python.

The reference for the 4-DoF fit is rpg_trajectory_evaluation's ``posyaw``
alignment over all frames, reimplemented here with numpy from
uzh-rpg/rpg_trajectory_evaluation@8c8ceec (MIT),
``src/rpg_trajectory_evaluation/align_utils.py`` (``alignPositionYaw`` with
``n_aligned=-1``) and ``align_trajectory.py`` (``align_umeyama(gt, est,
known_scale=True, yaw_only=True)``, ``get_best_yaw``, ``rot_z``).
"""

from __future__ import annotations

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
    fit = s2w.align_dof(est, ground_truth, dof="4dof")
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
    fit = s2w.align_dof(est, world, dof="4dof")
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
    fit = s2w.align_dof(est, ground_truth, dof="scale+4dof")
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
                    s2w.align_dof(est, world, dof=dof)
            else:
                fit = s2w.align_dof(est, world, dof=dof)
                assert fit.diagnostics["dof"]["gravity_tilt_deg"] == pytest.approx(deg, abs=1e-9)
        assert s2w.align_dof(est, world, dof="4dof", max_tilt_deg=None).rmse > 0
        assert s2w.align_dof(est, world, dof="sim3").rmse < 1e-12


def test_anchor_first_pins_the_first_pair() -> None:
    rng = np.random.default_rng(1)
    world = synthetic(seed=1)
    est = yaw_sim3(0.9, (3.0, -1.0, 0.2), scale=0.5).inverse().apply(world)
    est = est + 0.1 * rng.standard_normal(est.shape)
    for dof in ["sim3", "se3", "4dof", "scale+4dof"]:
        free = s2w.align_dof(est, world, dof=dof, max_tilt_deg=None)
        pinned = s2w.align_dof(est, world, dof=dof, anchor="first", max_tilt_deg=None)
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
    fit = s2w.align_dof(est, bad, dof="4dof", robust="ransac")
    assert fit.inliers is not None
    expected = np.ones(80, dtype=bool)
    expected[3::7] = False
    np.testing.assert_array_equal(fit.inliers, expected)
    np.testing.assert_allclose(fit.transform.matrix(), secret.matrix(), atol=1e-9)


def test_bad_arguments_raise_typed_errors() -> None:
    world = synthetic(20)
    with pytest.raises(s2w.InvalidInputError, match="scale\\+4dof"):
        s2w.align_dof(world, world, dof="6dof")
    with pytest.raises(s2w.InvalidInputError, match="first"):
        s2w.align_dof(world, world, anchor="last")
    with pytest.raises(s2w.InvalidInputError, match=r"\(N, 3\)"):
        s2w.align_dof(world[:, :2], world)
    with pytest.raises(s2w.InvalidInputError, match="target"):
        s2w.align_dof(world, world[:5])
    with pytest.raises(s2w.InvalidInputError, match="weights"):
        s2w.align_dof(world, world, weights=np.ones(3))
    with pytest.raises(s2w.InvalidInputError, match="max_tilt_deg"):
        s2w.align_dof(world, world, max_tilt_deg=-1.0)
    column = np.zeros((10, 3))
    column[:, 2] = np.arange(10.0)
    with pytest.raises(s2w.DegenerateError, match="horizontally"):
        s2w.align_dof(column, column + 1.0, dof="4dof")


def test_sim3_and_se3_are_align() -> None:
    rng = np.random.default_rng(4)
    world = synthetic(50, seed=4)
    est = world @ rot_z(0.3).T * 0.2 + 0.05 * rng.standard_normal(world.shape)
    w = rng.uniform(0.5, 2.0, len(world))
    for dof, scale in [("sim3", True), ("se3", False)]:
        ours = s2w.align_dof(est, world, dof=dof, weights=w)
        plain = s2w.align(est, world, scale=scale, weights=w)
        # The same core fit; `align` reads the arrays as flat rows, whose
        # moments are summed in another order (rounding only).
        np.testing.assert_allclose(ours.transform.matrix(), plain.transform.matrix(), atol=1e-13)
        np.testing.assert_allclose(ours.residuals, plain.residuals, rtol=1e-11, atol=1e-14)
        assert ours.rmse == pytest.approx(plain.rmse, rel=1e-12)
        assert "dof" not in ours.diagnostics
        cov = plain.covariance
        np.testing.assert_allclose(ours.covariance, cov, rtol=0, atol=1e-10 * np.abs(cov).max())
