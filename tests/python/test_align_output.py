"""``align --output`` and ``--save-transform``: the estimate carried into the reference frame,
written as TUM, EuRoC or KITTI and scored by evo without alignment, and the fitted transform as
JSON and as a 4×4 matrix numpy reads."""

from __future__ import annotations

import json
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from conftest import align_error, align_json, data_path

import slam2world as sw


def fr2() -> tuple[Path, Path]:
    d = data_path("evo_tum_fr2_desk")
    return d / "fr2_desk_ORB_kf_mono.txt", d / "fr2_desk_groundtruth.txt"


def test_the_aligned_estimate_scores_in_evo_without_alignment(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    est, ref = fr2()
    out = tmp_path / "aligned.txt"
    doc = align_json(capfd, str(est), str(ref), "--output", str(out))
    evo_ape = Path(sys.executable).with_name("evo_ape")
    if not evo_ape.exists():
        pytest.skip(f"evo_ape is not installed beside {sys.executable}")
    results = tmp_path / "evo.zip"
    subprocess.run(
        [str(evo_ape), "tum", str(ref), str(out), "--save_results", str(results)],
        check=True,
        capture_output=True,
        cwd=tmp_path,
        timeout=300,
    )
    with zipfile.ZipFile(results) as z:
        stats = json.loads(z.read("stats.json"))
    assert abs(stats["rmse"] - doc["ape"]["rmse"]) < 1e-6
    # Every EST pose is written, with its stamp as EST wrote it.
    src = sw.Trajectory.read_tum(est)
    back = sw.Trajectory.read_tum(out)
    assert np.array_equal(back.timestamps, src.timestamps)


def test_every_output_format_holds_the_same_poses(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    from evo.tools import file_interface

    est, ref = fr2()
    tum = tmp_path / "aligned.txt"
    align_json(
        capfd, str(est), str(ref), "-o", str(tum), "--save-transform", str(tmp_path / "T.json")
    )
    euroc = tmp_path / "aligned.csv"
    kitti = tmp_path / "aligned.kitti"
    align_json(capfd, str(est), str(ref), "-o", str(euroc), "--output-format", "euroc")
    doc = align_json(
        capfd,
        str(est),
        str(ref),
        "-o",
        str(kitti),
        "--output-format",
        "kitti",
        "--save-transform",
        str(tmp_path / "T.txt"),
    )
    t = file_interface.read_tum_trajectory_file(str(tum))
    e = file_interface.read_euroc_csv_trajectory(str(euroc))
    k = file_interface.read_kitti_poses_file(str(kitti))
    assert np.allclose(e.timestamps, t.timestamps, rtol=0, atol=1e-6)
    for other in (e, k):
        assert np.allclose(other.positions_xyz, t.positions_xyz, rtol=0, atol=1e-12)
        for a, b in zip(other.poses_se3, t.poses_se3, strict=True):
            assert np.allclose(a, b, rtol=0, atol=1e-9)
    # The transform files: the JSON the report holds and the 4×4 numpy reads, equal.
    saved = json.loads((tmp_path / "T.json").read_text())
    matrix = np.loadtxt(tmp_path / "T.txt")
    assert matrix.shape == (4, 4)
    assert np.array_equal(matrix, np.array(saved["matrix"]))
    assert saved["scale"] == pytest.approx(doc["scale"], rel=1e-12)
    # ... and it carries EST onto the written poses.
    src = sw.Trajectory.read_tum(est)
    carried = src.positions @ matrix[:3, :3].T + matrix[:3, 3]
    assert np.allclose(carried, t.positions_xyz, rtol=0, atol=1e-9)


def test_an_output_over_an_input_is_refused(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    est, ref = fr2()
    copy = tmp_path / "est.txt"
    copy.write_bytes(est.read_bytes())
    err = align_error(capfd, str(copy), str(ref), "-o", str(copy))
    assert len(err.strip().splitlines()) == 1, err
    assert copy.read_bytes() == est.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["est.txt"]
