"""``read_trajectory``: time units detected on the real files, CSV, repeated
stamps, and the override."""

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
