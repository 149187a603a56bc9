"""Issue 17 from Python: typed errors for bad integers, shapes, paths and text;
MemoryError instead of an abort; outputs never over inputs; Ctrl-C of the
console script stops the run and leaves the previous outputs."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import slam2world as s2w
from slam2world._slam2world import run_cli


def _traj_files(tmp: Path) -> tuple[Path, Path]:
    t = np.arange(60) * 0.1
    p = np.stack([np.sin(t), np.cos(0.7 * t), 0.2 * t], axis=1)
    q = np.tile([0.0, 0.0, 0.0, 1.0], (len(t), 1))
    est, ref = tmp / "est.txt", tmp / "ref.txt"
    s2w.Trajectory(t, p / 3.0, q).write_tum(est)
    s2w.Trajectory(t, p, q).write_tum(ref)
    return est, ref


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: s2w.PointFilter(sparsify=-1), "sparsify"),
        (lambda: s2w.PointFilter(min_near_support=-3), "min_near_support"),
        (lambda: s2w.PointFilter(cut_first_keyframes=-1), "cut_first_keyframes"),
        (lambda: s2w.PointFilter(seed=-1), "seed"),
        (lambda: s2w.PinholeCamera(500.0, 500.0, 16.0, 12.0, -1, 24), "width"),
        (lambda: s2w.PinholeCamera(500.0, 500.0, 16.0, 12.0, 32, 2**40), "height"),
        (lambda: s2w.PinholeCamera.from_hfov(-640, 480, 60.0), "width"),
        (lambda: s2w.simulate(seed=-1), "seed"),
        (lambda: s2w.simulate(reduced=-2), "reduced"),
        (lambda: s2w.geodetic_to_utm([48.0], [11.0], [500.0], zone=-1), "zone"),
        (lambda: s2w.utm_to_geodetic([[500000.0, 0.0, 0.0]], -32), "zone"),
        (lambda: s2w.utm_to_geodetic([[500000.0, 0.0, 0.0]], 300), "zone"),
    ],
)
def test_negative_integers_name_the_argument(call: Callable[[], object], name: str) -> None:
    with pytest.raises(s2w.InvalidInputError, match=name) as e:
        call()
    assert "integer from 0" in str(e.value)


def test_negative_integers_of_the_fits(tmp_path: Path) -> None:
    est, ref = _traj_files(tmp_path)
    slam, reference = s2w.Trajectory.read_tum(est), s2w.Trajectory.read_tum(ref)
    with pytest.raises(s2w.InvalidInputError, match="window"):
        s2w.align_windowed(slam, reference, window=-1)
    with pytest.raises(s2w.InvalidInputError, match="n_to_align"):
        s2w.align_trajectories(slam, reference, n_to_align=-1)
    with pytest.raises(s2w.InvalidInputError, match="skip_init"):
        s2w.align_trajectories(slam, reference, skip_init=-5)
    # A wrong type keeps Python's TypeError, naming the argument.
    with pytest.raises(TypeError, match="sparsify"):
        s2w.PointFilter(sparsify=1.5)  # type: ignore[arg-type]


def test_shape_errors_say_what_was_given() -> None:
    with pytest.raises(s2w.InvalidInputError) as e:
        s2w.Sim3(rotation=np.eye(4))
    msg = str(e.value)
    assert "(3, 3)" in msg and "(4, 4)" in msg, msg
    with pytest.raises(s2w.InvalidInputError) as e:
        s2w.Sim3.identity().apply(np.zeros(5))
    assert "(5,)" in str(e.value), str(e.value)
    with pytest.raises(s2w.InvalidInputError) as e:
        s2w.Sim3.identity().apply(np.zeros((2, 3, 3)))
    assert "(2, 3, 3)" in str(e.value), str(e.value)
    with pytest.raises(s2w.InvalidInputError) as e:
        s2w.Sim3(translation="abc")
    assert "str" in str(e.value), str(e.value)


def test_text_and_paths_that_are_not_utf8(tmp_path: Path) -> None:
    bad = tmp_path / "latin1.txt"
    bad.write_bytes(b"# caf\xe9\n1 0 0 0 0 0 0 1\n")
    with pytest.raises(s2w.FormatError, match="UTF-8"):
        s2w.Trajectory.read_tum(bad)
    with pytest.raises(s2w.FormatError, match="UTF-8"):
        s2w.read_xyz_text(bad)
    # A file name that is not UTF-8 (surrogate-escaped, as os.listdir gives it).
    odd = os.fsdecode(bytes(tmp_path) + b"/caf\xe9.ply")
    cloud = s2w.PointCloud(np.arange(9, dtype=np.float32).reshape(3, 3))
    cloud.write_ply(odd)
    back = s2w.read_ply(odd)
    assert len(back) == 3
    missing = os.fsdecode(bytes(tmp_path) + b"/none\xff.ply")
    with pytest.raises(s2w.FileError) as e:
        s2w.read_ply(missing)
    assert e.value.errno is not None
    # The console script takes such a path and answers with an exit code.
    code = run_cli(["slam2world", "inspect", missing])
    assert code == 1


def test_text_without_points_is_refused_and_a_ply_declaring_none_is_empty(tmp_path: Path) -> None:
    # Nothing in a text file says it is meant to be empty: a wrong file is the likelier reading.
    empty = tmp_path / "empty.txt"
    empty.write_text("# nothing\n\n")
    with pytest.raises(s2w.FormatError, match="no points"):
        s2w.read_xyz_text(empty)
    # A PLY header that declares no vertices is an empty cloud (what the writers write when
    # every point was dropped), read back as such.
    ply = tmp_path / "empty.ply"
    ply.write_bytes(
        b"ply\nformat binary_little_endian 1.0\nelement vertex 0\n"
        b"property float x\nproperty float y\nproperty float z\nend_header\n"
    )
    assert len(s2w.read_ply(ply)) == 0


def test_sim3_apply_of_a_huge_broadcast_view_raises_memory_error() -> None:
    # Under a 1.5 GiB address-space limit, a 120 M-row view (2.9 GB as a copy).
    script = textwrap.dedent(
        """
        import resource, numpy as np, slam2world as s2w
        resource.setrlimit(resource.RLIMIT_AS, (1536 << 20, 1536 << 20))
        view = np.broadcast_to(np.ones(3), (120_000_000, 3))
        try:
            s2w.Sim3.identity().apply(view)
        except MemoryError as e:
            print("MemoryError", e)
        """
    )
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "MemoryError" in r.stdout and "points" in r.stdout, r.stdout


def test_outputs_of_a_conversion_never_replace_its_input(tmp_path: Path) -> None:
    log = tmp_path / "world.mcap"
    code = run_cli(
        ["slam2world", "simulate", "-o", str(log), "--reduced", "16", "--set", "n_keyframes=6"]
    )
    assert code == 0
    (tmp_path / "world.truth.json").unlink()
    before = log.read_bytes()
    conv = s2w.convert(log)
    with pytest.raises(s2w.FileError, match="is the input"):
        conv.write_all(tmp_path)
    assert log.read_bytes() == before
    with pytest.raises(s2w.FileError, match="output folder is a file"):
        conv.write_all(log)
    out = tmp_path / "out"
    conv.write_all(out)
    assert sorted(p.name for p in out.iterdir()) == [
        "cloud.ply",
        "report.html",
        "report.json",
        "trajectory.txt",
        "world.mcap",
    ]
    assert conv.report["points_non_finite"] == 0


@pytest.mark.slow
def test_ctrl_c_of_the_console_script_stops_the_run_and_keeps_the_outputs(
    tmp_path: Path,
) -> None:
    out = tmp_path / "sim.mcap"
    out.write_bytes(b"previous")
    # The paper-size simulation runs for a while before it writes.
    p = subprocess.Popen(
        [sys.executable, "-m", "slam2world.cli", "simulate", "-o", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    time.sleep(1.5)
    assert p.poll() is None, "the run ended before the signal"
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 130, err
    assert "interrupted by SIGINT" in err, err
    assert "Traceback" not in err, err
    assert out.read_bytes() == b"previous"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["sim.mcap"]
