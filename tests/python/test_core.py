"""The core surface: Sim3, align, Trajectory, associate, align_trajectories,
scale_factors. Agreement with evo is checked by running evo itself."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
from conftest import data_path

import slam2world as s2w

SCALES = [1e-3, 0.0646, 1.0, 15.49, 1e3]


def random_rotation(rng: np.random.Generator) -> npt.NDArray[np.float64]:
    q = rng.normal(size=4)
    return s2w.Sim3.from_quaternion(q).rotation


def random_sim3(rng: np.random.Generator, scale: float) -> s2w.Sim3:
    return s2w.Sim3(random_rotation(rng), rng.uniform(-100, 100, 3), scale)


def apply_np(t: s2w.Sim3, p: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    return p @ (t.scale * t.rotation).T + t.translation


# ------------------------------------------------------------------- Sim3


def test_sim3_round_trips_and_matrix_algebra() -> None:
    rng = np.random.default_rng(1)
    for s in SCALES:
        a, b = random_sim3(rng, s), random_sim3(rng, 1.0 / np.sqrt(s))
        np.testing.assert_allclose(
            s2w.Sim3.from_matrix(a.matrix()).matrix(), a.matrix(), rtol=1e-12, atol=1e-12 * s
        )
        back = s2w.Sim3.from_quaternion(a.quaternion, a.translation, a.scale)
        np.testing.assert_allclose(back.matrix(), a.matrix(), rtol=1e-12, atol=1e-12 * s)
        lsd = s2w.Sim3.from_lsd_slam(a.to_lsd_slam())
        np.testing.assert_allclose(lsd.matrix(), a.matrix(), rtol=1e-12, atol=1e-12 * s)
        ab = (a @ b).matrix()
        np.testing.assert_allclose(
            ab, a.matrix() @ b.matrix(), rtol=1e-12, atol=1e-12 * np.abs(ab).max()
        )
        inv = np.linalg.inv(a.matrix())
        np.testing.assert_allclose(
            a.inverse().matrix(), inv, rtol=1e-9, atol=1e-9 * np.abs(inv).max()
        )
        p = rng.normal(size=(50, 3))
        np.testing.assert_allclose(a.apply(p), apply_np(a, p), rtol=1e-12, atol=1e-9 * s)
        np.testing.assert_allclose((a @ b).apply(p), a.apply(b.apply(p)), rtol=1e-9, atol=1e-9 * s)
        assert a.quaternion[3] >= 0
        assert abs(np.linalg.det(a.rotation) - 1) < 1e-12


def test_sim3_pickle_and_repr() -> None:
    t = s2w.Sim3.from_quaternion([0.1, 0.2, 0.3, 0.9], [1.0, -2.0, 3.0], 15.49)
    u = pickle.loads(pickle.dumps(t))
    assert isinstance(u, s2w.Sim3)
    np.testing.assert_allclose(u.matrix(), t.matrix(), rtol=1e-12, atol=1e-12)
    assert "15.49" in repr(t) and repr(t).startswith("Sim3(")


def test_sim3_apply_keeps_dtype_and_rejects_bad_shapes() -> None:
    t = s2w.Sim3.from_quaternion([0.0, 0.0, 1.0, 1.0], [1.0, 2.0, 3.0], 2.0)
    p32 = np.arange(30, dtype=np.float32).reshape(10, 3)
    out32 = t.apply(p32)
    assert out32.dtype == np.float32 and out32.shape == (10, 3)
    np.testing.assert_allclose(out32, apply_np(t, p32.astype(np.float64)), rtol=1e-6)
    out64 = t.apply(p32.astype(np.float64))
    assert out64.dtype == np.float64
    assert t.apply(np.arange(6).reshape(2, 3)).dtype == np.float64  # integers become float64
    # A non-contiguous view is read correctly.
    big = np.arange(60, dtype=np.float64).reshape(10, 6)
    np.testing.assert_allclose(t.apply(big[:, ::2]), apply_np(t, big[:, ::2]))
    # Fortran order (contiguous, but column by column) is read by rows too.
    for dtype in (np.float32, np.float64):
        f = np.asfortranarray(big[:, :3].astype(dtype))
        np.testing.assert_array_equal(t.apply(f), t.apply(np.ascontiguousarray(f)))
    assert t.apply(np.zeros((0, 3))).shape == (0, 3)
    for bad in (np.zeros((4, 2)), np.zeros(3), np.zeros((2, 3, 1)), "points"):
        with pytest.raises(s2w.InvalidInputError):
            t.apply(bad)
    with pytest.raises(ValueError):
        s2w.Sim3.from_quaternion([0, 0, 0, 0])
    with pytest.raises(s2w.InvalidInputError):
        s2w.Sim3(np.eye(3), [0, 0, 0], -1.0)
    with pytest.raises(s2w.InvalidInputError):
        s2w.Sim3(np.eye(3) * 2, [0, 0, 0], 1.0)


# ------------------------------------------------------------------- align


def test_align_recovers_random_sim3_both_methods() -> None:
    rng = np.random.default_rng(2)
    for s in [*SCALES, *10 ** rng.uniform(-3, 3, 5)]:
        src = rng.normal(size=(int(rng.integers(3, 300)), 3)) * 2 + 5
        t = random_sim3(rng, s)
        dst = apply_np(t, src)
        h = s2w.align(src, dst)
        u = s2w.align(src, dst, method="umeyama")
        for r in (h, u):
            assert abs(r.transform.scale / s - 1) < 1e-9
            rel = np.linalg.norm(r.transform.translation - t.translation) / (
                np.linalg.norm(t.translation) + 10 * s
            )
            assert rel < 1e-9
            np.testing.assert_allclose(r.transform.rotation, t.rotation, atol=1e-9)
            assert r.residuals.shape == (len(src),)
            assert r.rmse < 1e-9 * 10 * s
        # The paper's inverted formula would give 1/s.
        if abs(s - 1) > 1e-3:
            assert abs(h.transform.scale * s - 1) > 1e-3


def test_align_horn_equals_umeyama_and_evo_on_noisy_data() -> None:
    from evo.core.geometry import umeyama_alignment

    rng = np.random.default_rng(3)
    for s in SCALES:
        for with_scale in (True, False):
            src = rng.normal(size=(200, 3))
            t = random_sim3(rng, s)
            dst = apply_np(t, src) + rng.normal(scale=0.05 * s, size=src.shape)
            h = s2w.align(src, dst, scale=with_scale)
            u = s2w.align(src, dst, scale=with_scale, method="umeyama")
            r_e, t_e, c_e = umeyama_alignment(src.T, dst.T, with_scale)
            for r in (h, u):
                assert abs(r.transform.scale / c_e - 1) < 1e-9
                np.testing.assert_allclose(r.transform.rotation, r_e, atol=1e-9)
                size = np.linalg.norm(t_e) + 10 * s
                assert np.linalg.norm(r.transform.translation - t_e) / size < 1e-9
            res = np.linalg.norm(dst - apply_np(h.transform, src), axis=1)
            np.testing.assert_allclose(h.residuals, res, rtol=1e-9, atol=1e-12 * s)
            assert abs(h.rmse - np.sqrt(np.mean(res**2))) <= 1e-9 * h.rmse


def test_align_weights_and_diagnostics() -> None:
    rng = np.random.default_rng(4)
    src = rng.normal(size=(40, 3))
    t = random_sim3(rng, 2.5)
    dst = apply_np(t, src)
    dst[5] += 100.0
    w = np.ones(40)
    w[5] = 0.0
    r = s2w.align(src, dst, weights=w)
    np.testing.assert_allclose(r.transform.matrix(), t.matrix(), atol=1e-9 * 100)
    d = r.diagnostics
    assert d["n"] == 40 and d["weight_sum"] == 39.0
    assert d["eigenvalues"][0] >= d["eigenvalues"][1] >= d["eigenvalues"][3]
    assert 0 < d["relative_eigen_gap"] <= 2
    assert d["singular_values"][0] >= d["singular_values"][2] > 0
    assert d["source_spread"] > 0 and d["target_spread"] > 0
    assert "Alignment(" in repr(r)


def test_align_exceptions() -> None:
    rng = np.random.default_rng(5)
    a = rng.normal(size=(10, 3))
    with pytest.raises(s2w.InvalidInputError, match="at least 3"):
        s2w.align(a[:2], a[:2])
    with pytest.raises(s2w.InvalidInputError, match="target"):
        s2w.align(a, a[:9])
    with pytest.raises(s2w.InvalidInputError):
        s2w.align(a[:, :2], a[:, :2])
    bad = a.copy()
    bad[3, 1] = np.nan
    with pytest.raises(s2w.InvalidInputError, match="index 3"):
        s2w.align(a, bad)
    bad[3, 1] = np.inf
    with pytest.raises(s2w.InvalidInputError):
        s2w.align(bad, a)
    with pytest.raises(s2w.DegenerateError, match="coincide"):
        s2w.align(np.ones((10, 3)), a)
    with pytest.raises(s2w.DegenerateError, match="coincide"):
        s2w.align(a, np.ones((10, 3)))
    line = np.outer(np.linspace(-1, 1, 10), [0.3, -1.0, 2.0])
    with pytest.raises(s2w.DegenerateError, match="collinear"):
        s2w.align(line, line * 3 + 1)
    with pytest.raises(s2w.InvalidInputError, match="method"):
        s2w.align(a, a, method="svd")
    with pytest.raises(s2w.InvalidInputError):
        s2w.align(a, a, weights=-np.ones(10))
    with pytest.raises(s2w.InvalidInputError):
        s2w.align(a, a, weights=np.ones(9))
    # Every error is a Slam2WorldError and a ValueError.
    assert issubclass(s2w.DegenerateError, s2w.InvalidInputError)
    assert issubclass(s2w.InvalidInputError, ValueError)
    assert issubclass(s2w.InvalidInputError, s2w.Slam2WorldError)


# ------------------------------------------------------------- trajectories


def make_traj(n: int = 20, orientations: bool = True) -> s2w.Trajectory:
    t = np.linspace(0.0, 1.9, n)
    p = np.stack([t, np.sin(t), np.cos(t)], axis=1)
    q = None
    if orientations:
        q = np.stack([np.zeros(n), np.zeros(n), np.sin(t / 2), np.cos(t / 2)], axis=1)
    return s2w.Trajectory(t, p, q)


def test_trajectory_construction_and_pickle() -> None:
    tr = make_traj()
    assert len(tr) == 20 and tr.positions.shape == (20, 3)
    assert tr.orientations is not None and tr.orientations.shape == (20, 4)
    assert make_traj(orientations=False).orientations is None
    back = pickle.loads(pickle.dumps(tr))
    np.testing.assert_array_equal(back.timestamps, tr.timestamps)
    np.testing.assert_array_equal(back.positions, tr.positions)
    assert "20 poses" in repr(tr)
    with pytest.raises(s2w.InvalidInputError):
        s2w.Trajectory([0.0, 1.0], np.zeros((3, 3)))
    with pytest.raises(s2w.InvalidInputError):
        s2w.Trajectory([1.0, 0.0], np.zeros((2, 3)))
    with pytest.raises(s2w.InvalidInputError):
        s2w.Trajectory([0.0, 1.0], np.zeros((2, 3)), np.zeros((2, 4)))
    with pytest.raises(s2w.InvalidInputError):
        s2w.Trajectory([0.0, np.nan], np.zeros((2, 3)))


def test_tum_round_trip_and_file_errors(tmp_path: Path) -> None:
    tr = make_traj()
    path = tmp_path / "t.txt"
    tr.write_tum(path)
    back = s2w.Trajectory.read_tum(str(path))
    np.testing.assert_array_equal(back.timestamps, tr.timestamps)
    np.testing.assert_array_equal(back.positions, tr.positions)
    assert back.orientations is not None and tr.orientations is not None
    np.testing.assert_allclose(back.orientations, tr.orientations, atol=1e-15)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.txt"]
    with pytest.raises(s2w.FileError) as e:
        s2w.Trajectory.read_tum(tmp_path / "missing.txt")
    assert isinstance(e.value, OSError)
    bad = tmp_path / "bad.txt"
    bad.write_text("1 2 3\n")
    with pytest.raises(s2w.FormatError, match=":1:"):
        s2w.Trajectory.read_tum(bad)
    with pytest.raises(s2w.FileError):
        tr.write_tum(tmp_path / "no" / "such" / "dir.txt")


def test_interpolate_matches_scipy_slerp() -> None:
    from scipy.spatial.transform import Rotation, Slerp

    tr = make_traj()
    times = np.linspace(0.05, 1.85, 37)
    out = tr.interpolate(times, max_gap=0.2)
    assert out.orientations is not None and tr.orientations is not None
    for k in range(3):
        np.testing.assert_allclose(
            out.positions[:, k], np.interp(times, tr.timestamps, tr.positions[:, k]), atol=1e-14
        )
    ref = Slerp(tr.timestamps, Rotation.from_quat(tr.orientations))(times)
    rel = Rotation.from_quat(out.orientations) * ref.inv()
    assert np.max(rel.magnitude()) < 1e-12
    with pytest.raises(s2w.InvalidInputError, match="before the first"):
        tr.interpolate([-0.1])
    with pytest.raises(s2w.InvalidInputError, match="gap"):
        tr.interpolate([0.05], max_gap=0.01)
    sub, kept, missing = tr.interpolate_where_covered([-1.0, 0.5, 5.0], max_gap=0.2)
    assert len(sub) == 1 and kept.tolist() == [1] and missing.tolist() == [0, 2]


def test_transformed_and_scale_factors() -> None:
    rng = np.random.default_rng(6)
    tr = make_traj()
    t = random_sim3(rng, 15.49)
    out = tr.transformed(t)
    np.testing.assert_allclose(out.positions, apply_np(t, tr.positions), rtol=1e-12, atol=1e-9)
    p = s2w.scale_factors(tr.positions, out.positions)
    assert p.shape == (19,)
    np.testing.assert_allclose(p, 15.49**2, rtol=1e-10)
    with pytest.raises(s2w.InvalidInputError):
        s2w.scale_factors(tr.positions, out.positions[:5])
    with pytest.raises(s2w.DegenerateError):
        s2w.scale_factors(np.zeros((3, 3)), out.positions[:3])


# ------------------------------------------------------ evo, run side by side


def evo_reference(est_path: Path, ref_path: Path, euroc: bool, with_scale: bool):  # type: ignore[no-untyped-def]
    from evo.core import metrics, sync
    from evo.tools import file_interface

    ref = (
        file_interface.read_euroc_csv_trajectory(str(ref_path))
        if euroc
        else file_interface.read_tum_trajectory_file(str(ref_path))
    )
    est = file_interface.read_tum_trajectory_file(str(est_path))
    ref, est = sync.associate_trajectories(ref, est, max_diff=0.01)
    r, t, s = est.align(ref, correct_scale=with_scale)
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((ref, est))
    return ref, est, r, t, s, ape.get_all_statistics()


CASES = [
    ("evo_tum_fr2_desk", "fr2_desk_ORB_kf_mono.txt", "fr2_desk_groundtruth.txt", False),
    ("evo_tum_fr1_xyz", "freiburg1_xyz-ORB_kf_mono.txt", "freiburg1_xyz-groundtruth.txt", False),
    ("euroc_v102", "V102.txt", "V102_groundtruth.csv", True),
]


@pytest.mark.parametrize("with_scale", [True, False])
@pytest.mark.parametrize(("folder", "est_file", "ref_file", "euroc"), CASES)
def test_align_trajectories_equals_evo(
    folder: str, est_file: str, ref_file: str, euroc: bool, with_scale: bool
) -> None:
    est_path, ref_path = data_path(folder, est_file), data_path(folder, ref_file)
    e_ref, e_est, r_e, t_e, s_e, stats = evo_reference(est_path, ref_path, euroc, with_scale)
    est = s2w.Trajectory.read_tum(est_path)
    ref = s2w.Trajectory.read_euroc(ref_path) if euroc else s2w.Trajectory.read_tum(ref_path)
    for method in ("horn", "umeyama"):
        r = s2w.align_trajectories(est, ref, scale=with_scale, method=method)
        i_est, i_ref = r.pairs
        np.testing.assert_array_equal(est.timestamps[i_est], e_est.timestamps)
        np.testing.assert_array_equal(ref.timestamps[i_ref], e_ref.timestamps)
        assert r.n_pairs == len(e_est.timestamps)
        assert abs(r.transform.scale / s_e - 1) < 1e-9
        np.testing.assert_allclose(r.transform.rotation, r_e, rtol=0, atol=1e-9)
        np.testing.assert_allclose(r.transform.translation, t_e, rtol=1e-9, atol=1e-12)
        for key in ("rmse", "mean", "median", "std", "min", "max"):
            assert abs(getattr(r, key) / stats[key] - 1) < 1e-9, key
        np.testing.assert_allclose(
            r.residuals,
            np.linalg.norm(e_est.positions_xyz - e_ref.positions_xyz, axis=1),
            rtol=1e-9,
        )


def test_associate_equals_evo_matching() -> None:
    from evo.core.sync import matching_time_indices

    est = s2w.Trajectory.read_tum(data_path("evo_tum_fr2_desk", "fr2_desk_ORB_kf_mono.txt"))
    ref = s2w.Trajectory.read_tum(data_path("evo_tum_fr2_desk", "fr2_desk_groundtruth.txt"))
    for max_diff, offset in [(0.01, 0.0), (0.02, 0.013), (0.005, -0.3)]:
        i_ref, i_est = s2w.associate(ref, est, max_diff=max_diff, offset=offset)
        e_est, e_ref = matching_time_indices(est.timestamps, ref.timestamps, max_diff, -offset)
        assert i_est.tolist() == e_est and i_ref.tolist() == e_ref
        # Arguments swapped: the same pairs, and the offset moves with its trajectory.
        j_est, j_ref = s2w.associate(est, ref, max_diff=max_diff, offset=-offset)
        assert j_est.tolist() == e_est and j_ref.tolist() == e_ref


def test_fr2_desk_se3_reproduces_published_rmse() -> None:
    est = s2w.Trajectory.read_tum(data_path("evo_tum_fr2_desk", "fr2_desk_ORB.txt"))
    ref = s2w.Trajectory.read_tum(data_path("evo_tum_fr2_desk", "fr2_desk_groundtruth.txt"))
    r = s2w.align_trajectories(est, ref, scale=False)
    assert round(r.rmse, 6) == 0.008119  # evo doc/performance.md
    assert r.transform.scale == 1.0
    assert "TrajectoryAlignment(" in repr(r)
    sub = s2w.align_trajectories(est, ref, scale=False, n_to_align=100)
    assert sub.n_pairs == r.n_pairs and len(sub.alignment.residuals) == 100
    with pytest.raises(s2w.InvalidInputError, match="match a reference pose"):
        s2w.align_trajectories(est, ref, offset=1e6)


def test_align_residuals_on_request_match_the_fit() -> None:
    # `align` reads its input once; the residuals are computed on first access
    # from the kept arrays (any layout or dtype), and then kept.
    rng = np.random.default_rng(12)
    t = random_sim3(rng, 15.49)
    src = rng.normal(size=(150_000, 3)) * 3 + 100
    dst = apply_np(t, src) + rng.normal(scale=1e-3, size=src.shape)
    for a, b in (
        (src, dst),
        (src.astype(np.float32), np.asfortranarray(dst)),
        (src.tolist()[:50], dst[:50]),
    ):
        r = s2w.align(a, b)
        ref = np.linalg.norm(
            np.asarray(b) - apply_np(r.transform, np.asarray(a, dtype=np.float64)), axis=1
        )
        res = r.residuals
        assert res is r.residuals
        assert res.shape == (len(ref),) and res.dtype == np.float64
        np.testing.assert_allclose(res, ref, rtol=1e-9, atol=1e-12)
        assert abs(r.rmse / np.sqrt(np.mean(ref**2)) - 1) < 1e-9
