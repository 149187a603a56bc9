"""``read_trajectory``: time units detected on the real files, CSV, repeated
stamps, and the override; ``match_time_units``: two sides read against each other."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

import slam2world as s2w


def test_orbslam3_nanoseconds_and_tum_seconds(data: Any) -> None:
    kf = data.path("euroc_mh01_orbslam3_mono", "kf_dataset-MH01_mono.txt")
    traj, info = s2w.read_trajectory(kf)
    assert (info.unit, info.unit_detected, info.delimiter) == ("ns", True, "whitespace")
    assert 1.4e9 < traj.timestamps[0] < 1.41e9
    raw = s2w.Trajectory.read_tum(kf)
    assert np.allclose(traj.timestamps, raw.timestamps[: len(traj.timestamps)] / 1e9)
    gt, info = s2w.read_trajectory(data.path("evo_tum_fr2_desk", "fr2_desk_groundtruth.txt"))
    assert info.unit == "s"
    forced, info = s2w.read_trajectory(kf, time_unit="s")
    assert not info.unit_detected and forced.timestamps[0] == raw.timestamps[0]


def test_csv_and_repeated_stamps(tmp_path: Path) -> None:
    p = tmp_path / "traj.csv"
    p.write_text("t,x,y,z,qx,qy,qz,qw\n0,0,0,0,0,0,0,1\n0,5,5,5,0,0,0,1\n1,1,0,0,0,0,0,1\n")
    traj, info = s2w.read_trajectory(p)
    assert (info.delimiter, info.header, info.repeated_stamps) == ("comma", True, 1)
    assert traj.positions[0, 0] == 0.0 and len(traj.timestamps) == 2
    with pytest.raises(s2w.InvalidInputError, match="time_unit"):
        s2w.read_trajectory(p, time_unit="minutes")
    p.write_text("0 0 0 0 0 0 0 1\n" + "#" * 70000 + "\n")
    with pytest.raises(s2w.FormatError, match="longer than"):
        s2w.read_trajectory(p)


def test_match_time_units_reads_each_side_against_the_other(data: Any) -> None:
    kf = data.path("euroc_mh01_orbslam3_mono", "kf_dataset-MH01_mono.txt")
    gt = data.path("euroc_mh01_orbslam3_mono", "MH_01_easy.txt")
    est = s2w.Trajectory.read_tum(kf).timestamps
    ref = s2w.Trajectory.read_tum(gt).timestamps
    assert s2w.match_time_units(est, ref) == ("ns", "s")
    assert s2w.match_time_units(est / 1e3, ref) == ("us", "s")
    # Stamps from 0: milliseconds at 20 Hz against seconds at 200 Hz.
    ms = np.arange(0.0, 60_000.0, 50.0)
    s = np.arange(0.0, 60.0, 0.005)
    assert s2w.match_time_units(ms, s) == ("ms", "s")
    assert s2w.match_time_units(s, ms) == ("s", "ms")
    # A side given stays as given; an offset in seconds moves the estimate.
    assert s2w.match_time_units(est, ref, est_unit="s") == ("s", "s")
    assert s2w.match_time_units(ref + 86400.0, ref, offset=-86400.0) == ("s", "s")
    with pytest.raises(s2w.InvalidInputError, match="time_unit"):
        s2w.match_time_units(est, ref, ref_unit="minutes")
    with pytest.raises(s2w.Slam2WorldError):
        s2w.match_time_units([0.0, float("nan")], ref)
