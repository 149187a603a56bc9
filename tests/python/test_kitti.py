"""KITTI odometry pose files in and out, checked against evo's reader and writer: a KITTI pair
made by evo from the TUM fr2_desk run aligns as the TUM pair does (paired by index without
stamps, by time with ``times.txt``), evo reads the project's KITTI output back, and bad files
get one clear error."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import align_error, align_json, data_path

import slam2world as sw
from slam2world._slam2world import run_cli


@pytest.fixture
def fr2_pair(tmp_path: Path) -> Path:
    """The fr2_desk ORB keyframes and ground truth associated by evo, written by evo as TUM
    and as KITTI, with the stamps of each side as a ``times.txt``."""
    from evo.core import sync
    from evo.tools import file_interface

    d = data_path("evo_tum_fr2_desk")
    est = file_interface.read_tum_trajectory_file(str(d / "fr2_desk_ORB_kf_mono.txt"))
    ref = file_interface.read_tum_trajectory_file(str(d / "fr2_desk_groundtruth.txt"))
    ref, est = sync.associate_trajectories(ref, est)
    for name, traj in (("est", est), ("ref", ref)):
        file_interface.write_tum_trajectory_file(str(tmp_path / f"{name}.tum"), traj)
        file_interface.write_kitti_poses_file(str(tmp_path / f"{name}.kitti"), traj)
        np.savetxt(tmp_path / f"{name}_times.txt", traj.timestamps)
    return tmp_path


def test_a_kitti_pair_aligns_as_the_tum_pair(
    fr2_pair: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    d = fr2_pair
    tum = align_json(capfd, str(d / "est.tum"), str(d / "ref.tum"))
    by_index = align_json(capfd, str(d / "est.kitti"), str(d / "ref.kitti"))
    by_time = align_json(
        capfd,
        str(d / "est.kitti"),
        str(d / "ref.kitti"),
        "--est-times",
        str(d / "est_times.txt"),
        "--ref-times",
        str(d / "ref_times.txt"),
    )
    assert by_index["time_units"]["paired_by_index"] is True
    assert by_time["time_units"]["paired_by_index"] is False
    for doc in (by_index, by_time):
        assert doc["n_pairs"] == tum["n_pairs"] == 118
        assert abs(doc["scale"] - tum["scale"]) < 1e-9 * tum["scale"]
        assert abs(doc["ape"]["rmse"] - tum["ape"]["rmse"]) < 1e-9
        assert np.allclose(doc["translation"], tum["translation"], rtol=0, atol=1e-9)


def test_transform_cloud_takes_a_kitti_pair(
    fr2_pair: Path, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    d = fr2_pair
    cloud = tmp_path / "points.txt"
    cloud.write_text("0 0 0\n1 2 3\n")
    tum = align_json(capfd, str(d / "est.tum"), str(d / "ref.tum"))
    args = ["transform-cloud", str(cloud), "--align", str(d / "est.kitti"), str(d / "ref.kitti")]
    assert run_cli(["slam2world", *args, "-o", str(tmp_path / "world.ply")]) == 0
    out, _ = capfd.readouterr()
    assert "aligned 118 pose pairs" in out and f"scale {tum['scale']:.9f}" in out, out
    world = sw.read_ply(tmp_path / "world.ply")
    assert np.allclose(world.points[0], tum["translation"], rtol=0, atol=1e-5)


def test_kitti_written_here_reads_back_in_evo(fr2_pair: Path, tmp_path: Path) -> None:
    from evo.tools import file_interface

    est = sw.Trajectory.read_kitti(fr2_pair / "est.kitti", times=fr2_pair / "est_times.txt")
    tum = sw.Trajectory.read_tum(fr2_pair / "est.tum")
    assert np.array_equal(est.timestamps, tum.timestamps)
    assert np.allclose(est.positions, tum.positions, rtol=0, atol=1e-12)
    out = tmp_path / "out" / "poses.txt"
    out.parent.mkdir()
    est.write_kitti(out, times=out.with_name("times.txt"))
    evo = file_interface.read_kitti_poses_file(str(out))
    assert evo.num_poses == len(est)
    assert np.allclose(evo.positions_xyz, est.positions, rtol=0, atol=1e-9)
    theirs = file_interface.read_kitti_poses_file(str(fr2_pair / "est.kitti"))
    for a, b in zip(evo.poses_se3, theirs.poses_se3, strict=True):
        assert np.allclose(a, b, rtol=0, atol=1e-9)
    back = sw.Trajectory.read_kitti(out, times=out.with_name("times.txt"))
    assert np.array_equal(back.timestamps, est.timestamps)
    assert np.array_equal(back.positions, est.positions)
    rated = sw.Trajectory.read_kitti(out, rate=20.0)
    assert np.allclose(rated.timestamps, np.arange(len(est)) / 20.0, rtol=0, atol=1e-15)
    stamped = sw.Trajectory.read_kitti(out, times=est.timestamps)
    assert np.array_equal(stamped.timestamps, est.timestamps)


IDENTITY = "1 0 0 0 0 1 0 0 0 0 1 0"


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        (f"{IDENTITY}\n1 0 0 0 0 1 0 0 0 0 1\n", ":2: expected 12 values"),
        (f"{IDENTITY}\n2 0 0 0 0 2 0 0 0 0 2 0\n", ":2: the 3×3 part is not a rotation"),
        ("0 1 0 0 1 0 0 0 0 0 1 0\n", ":1: the 3×3 part is not a rotation"),
    ],
)
def test_bad_kitti_files_name_the_line(
    tmp_path: Path, capfd: pytest.CaptureFixture[str], text: str, needle: str
) -> None:
    bad = tmp_path / "bad.txt"
    bad.write_text(text)
    with pytest.raises(sw.FormatError, match=needle):
        sw.Trajectory.read_kitti(bad)
    good = tmp_path / "good.txt"
    good.write_text(f"{IDENTITY}\n{IDENTITY}\n")
    err = align_error(capfd, str(good), str(bad), "--format", "kitti")
    assert needle in err and len(err.strip().splitlines()) == 1, err


def test_counts_and_stamps_that_do_not_pair(
    fr2_pair: Path, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    d = fr2_pair
    short = tmp_path / "short.kitti"
    short.write_text("".join(d.joinpath("ref.kitti").read_text().splitlines(True)[:100]))
    err = align_error(capfd, str(d / "est.kitti"), str(short))
    assert "has 118 poses" in err and "has 100" in err and "pair by index" in err, err
    err = align_error(capfd, str(d / "est.kitti"), str(d / "ref.tum"))
    assert "--est-times" in err, err
    with pytest.raises(sw.InvalidInputError, match="118 poses"):
        sw.Trajectory.read_kitti(d / "est.kitti", times=np.arange(3.0))
    with pytest.raises(sw.InvalidInputError, match="not both"):
        sw.Trajectory.read_kitti(d / "est.kitti", times=np.arange(3.0), rate=10.0)
    with pytest.raises(sw.InvalidInputError):
        sw.Trajectory(np.zeros(0), np.zeros((0, 3))).write_kitti(tmp_path / "empty.txt")
    assert not (tmp_path / "empty.txt").exists()
