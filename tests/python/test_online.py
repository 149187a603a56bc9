"""Online conversion from Python: ``convert(..., grid=...)`` writes nav2's files (read by
Pillow and PyYAML) and a grid channel (read by the ``mcap`` package); ``Session`` fed a
simulated run in time order; ``slam2world follow`` on a log that a writer process (the
``mcap`` package's writer) appends in real time, every sampled output file complete."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import slam2world as s2w

PIL = pytest.importorskip("PIL.Image")
yaml = pytest.importorskip("yaml")
mcap_reader = pytest.importorskip("mcap.reader")


@pytest.fixture(scope="module")
def log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The paper's run reduced 4x (live frames, keyframes, graph, reference)."""
    path = tmp_path_factory.mktemp("sim") / "sim.mcap"
    argv = ["slam2world", "simulate", "-o", str(path), "--reduced", "4", "--seed", "3"]
    assert s2w._slam2world.run_cli(argv) == 0
    return path


@pytest.mark.slow
def test_convert_grid_writes_map_server_files_and_a_grid_channel(log: Path, tmp_path: Path) -> None:
    conv = s2w.convert(log, skip_init="auto", octree_resolution=0.1, grid=(0.25, 0.75))
    g = conv.grid
    assert g is not None and g.width > 0 and g.height > 0
    assert conv.report["grid"]["width"] == g.width
    conv.write_all(tmp_path)
    img = PIL.open(tmp_path / "map.pgm")
    assert img.size == (g.width, g.height) and img.mode == "L"
    px = np.asarray(img)
    assert set(np.unique(px)) <= {0, 205, 254}
    # Row 0 of the image is the grid's top row (highest y).
    occupied = np.flipud(g.probability) >= 0.5
    assert np.array_equal(px == 0, occupied)
    meta = yaml.safe_load((tmp_path / "map.yaml").read_text())
    # Exactly the fields map_server documents.
    assert set(meta) == {
        "image",
        "mode",
        "resolution",
        "origin",
        "negate",
        "occupied_thresh",
        "free_thresh",
    }
    assert meta["image"] == "map.pgm" and meta["mode"] == "trinary" and meta["negate"] == 0
    assert meta["resolution"] == pytest.approx(g.resolution)
    assert meta["origin"] == pytest.approx([g.origin[0], g.origin[1], 0.0])
    height = np.load(tmp_path / "map_height.npy")
    assert height.shape == (g.height, g.width)
    with open(tmp_path / "world.mcap", "rb") as f:
        summary = mcap_reader.make_reader(f).get_summary()
    assert summary is not None
    grids = [c for c in summary.channels.values() if c.topic == "/slam2world/grid"]
    assert len(grids) == 1
    assert summary.schemas[grids[0].schema_id].name == "foxglove.Grid"
    # Without an octree a grid is refused, with the reason.
    with pytest.raises(s2w.Slam2WorldError, match="octree"):
        s2w.convert(log, grid=(0.0, 1.0))


def _feed(s: s2w.Session, sim: s2w.Simulation, reference: Any) -> list[dict[str, Any]]:
    """Pushes the simulated run in time order, the reference through ``reference``,
    then finishes; the timing of every keyframe push."""
    events: list[tuple[float, int, int]] = []
    rt = sim.reference_timestamps
    ft, fp, fq = sim.slam_timestamps, sim.slam_positions, sim.slam_orientations
    assert fq is not None
    keyframes = sim.keyframes
    events += [(float(t), 0, i) for i, t in enumerate(rt)]
    events += [(float(t), 1, i) for i, t in enumerate(ft)]
    events += [(float(t), 2, i) for i, t in enumerate(sim.keyframe_timestamps)]
    events.sort()
    timings = []
    for _, kind, i in events:
        if kind == 0:
            reference(i)
        elif kind == 1:
            s.push_frame(float(ft[i]), s2w.Sim3.from_quaternion(fq[i], fp[i], 1.0))
        else:
            timings.append(s.push_keyframe(keyframes[i]))
    s.finish()
    return timings


@pytest.mark.slow
def test_session_in_time_order() -> None:
    sim = s2w.simulate(seed=3, reduced=4)
    s = s2w.Session(stable_hold=1.0)
    assert s.transform() is None and s.map() is None
    assert s.state()["stage"] == "waiting"
    rt, rp, rq = sim.reference_timestamps, sim.reference_positions, sim.reference_orientations
    assert rq is not None
    timings = _feed(
        s, sim, lambda i: s.push_reference(float(rt[i]), rp[i].tolist(), rq[i].tolist())
    )
    for timing in timings:
        assert set(timing) == {"fit_s", "backproject_s", "insert_s", "inserted", "rebuilt"}
    st = s.state()
    assert st["stage"] == "stable" and st["keyframes"] == len(sim.keyframes)
    t = s.transform()
    assert t is not None
    assert t.scale == pytest.approx(sim.t_world_slam.scale, rel=0.05)
    cov = s.transform_covariance()
    assert cov is not None and cov.shape == (7, 7)
    m = s.map()
    assert m is not None and m.num_nodes > 0
    g = s.grid(0.25, 0.75)
    assert g.width > 0
    with pytest.raises(s2w.Slam2WorldError, match="not both"):
        s.push_fix(1.0, 47.0, 8.0, 400.0)
    with pytest.raises(s2w.Slam2WorldError, match="time order"):
        s.push_reference(0.0, [0.0, 0.0, 0.0])


@pytest.mark.slow
def test_session_with_gnss_fixes_fits_in_enu_at_the_first_fix() -> None:
    """Fixes (10 Hz, WGS84 by pymap3d from the reference positions in an ENU frame)
    instead of reference poses: the world frame is ENU at the first fix, and the
    transform is the pose session's moved by that fix (the two ENU frames, metres
    apart, differ by a rotation of micro-radians)."""
    pm = pytest.importorskip("pymap3d")
    sim = s2w.simulate(seed=3, reduced=4)
    rt, rp, rq = sim.reference_timestamps, sim.reference_positions, sim.reference_orientations
    assert rq is not None
    poses = s2w.Session(stable_hold=1.0)
    _feed(poses, sim, lambda i: poses.push_reference(float(rt[i]), rp[i].tolist(), rq[i].tolist()))
    lat, lon, alt = pm.enu2geodetic(rp[:, 0], rp[:, 1], rp[:, 2], 47.37, 8.54, 410.0)
    cov = np.diag([0.01, 0.01, 0.04])
    fixes = s2w.Session(stable_hold=1.0)

    def fix(i: int) -> None:
        if i % 20 == 0:
            fixes.push_fix(float(rt[i]), float(lat[i]), float(lon[i]), float(alt[i]), cov)
        if i == 40:
            fixes.push_fix(float(rt[i]) + 1e-3, 0.0, 0.0, 0.0, has_fix=False)

    _feed(fixes, sim, fix)
    st = fixes.state()
    assert st["fixes"] == len(range(0, len(rt), 20)) and st["fixes_dropped"] == 1
    assert st["enu_origin"] == pytest.approx((lat[0], lon[0], alt[0]), abs=1e-12)
    a, b = fixes.transform(), poses.transform()
    assert a is not None and b is not None
    assert a.scale == pytest.approx(b.scale, rel=2e-3)
    # ENU at the first fix: the pose session's world shifted by the first position.
    pts = np.array([k.pose.translation for k in sim.keyframes])
    assert np.abs(a.apply(pts) - (b.apply(pts) - rp[0])).max() < 0.05
    with pytest.raises(s2w.Slam2WorldError, match="not both"):
        fixes.push_reference(1e6, [0.0, 0.0, 0.0])
    with pytest.raises(s2w.Slam2WorldError, match="origin"):
        s2w.Session(origin="mean")


WRITER = textwrap.dedent(
    """
    import sys, time
    from mcap.reader import make_reader
    from mcap.writer import Writer
    src, dst = sys.argv[1], sys.argv[2]
    with open(src, "rb") as f:
        r = make_reader(f)
        msgs = [(s, c, m) for s, c, m in r.iter_messages(log_time_order=True)]
    with open(dst, "wb") as out:
        w = Writer(out, use_chunking=False)
        w.start(profile="ros1")
        schemas, chans = {}, {}
        t0 = msgs[0][2].log_time
        wall0 = time.monotonic()
        for s, c, m in msgs:
            if s.id not in schemas:
                schemas[s.id] = w.register_schema(s.name, s.encoding, s.data)
            if c.id not in chans:
                chans[c.id] = w.register_channel(c.topic, c.message_encoding, schemas[s.id])
            # Real time: each message when its log time comes.
            wait = (m.log_time - t0) * 1e-9 - (time.monotonic() - wall0)
            if wait > 0:
                out.flush()
                time.sleep(wait)
            w.add_message(chans[c.id], m.log_time, m.data, m.publish_time)
        w.finish()
    """
)


@pytest.mark.slow
def test_follow_a_growing_log_every_sample_complete(tmp_path: Path) -> None:
    src = tmp_path / "src.mcap"
    # Long enough to leave three keyframes or more after the start-up cut.
    argv = ["slam2world", "simulate", "-o", str(src), "--reduced", "8", "--seed", "2"]
    assert s2w._slam2world.run_cli(argv) == 0
    growing, out = tmp_path / "live.mcap", tmp_path / "out"
    writer = subprocess.Popen([sys.executable, "-c", WRITER, str(src), str(growing)])
    follow = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "slam2world.cli",
            "follow",
            str(growing),
            "-o",
            str(out),
            "--stable-hold",
            "0.3",
            "--idle-timeout",
            "5",
            "--grid",
            "0.25",
            "0.75",
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    samples = 0
    while follow.poll() is None:
        for p in sorted(out.glob("*")) if out.exists() else []:
            if p.name.startswith("."):
                continue  # a temporary file of the set being written
            data = p.read_bytes()
            if p.name == "report.json":
                json.loads(data)
            elif p.name == "map.yaml":
                assert yaml.safe_load(data)["mode"] == "trinary"
            elif p.name == "map.pgm":
                PIL.open(p).load()
            elif p.name == "world.mcap":
                with open(p, "rb") as f:
                    assert mcap_reader.make_reader(f).get_summary() is not None
            elif p.name == "map.bt":
                assert data.startswith(b"# Octomap OcTree binary file")
                s2w.OccupancyMap.read_bt(p)
            samples += 1
        time.sleep(0.05)
    writer.wait(timeout=30)
    stdout, _ = follow.communicate(timeout=30)
    assert follow.returncode == 0, stdout
    assert writer.returncode == 0
    assert samples > 10
    lines = [ln for ln in stdout.splitlines() if ln.startswith("keyframe ")]
    assert len(lines) >= 5, stdout
    assert all(" stage " in ln and " latency " in ln for ln in lines)
    # The end state equals the batch conversion of the finished log.
    report = json.loads((out / "report.json").read_text())
    assert report["finished"] and report["end"] == "end of log"
    conv = s2w.convert(growing, skip_init="auto", octree_resolution=0.1, octree_max_range=10.0)
    t = conv.report["t_world_slam"]
    assert report["t_world_slam"]["scale"] == pytest.approx(t["scale"], rel=1e-9)
    assert np.allclose(report["t_world_slam"]["translation"], t["translation"], atol=1e-9)
    assert conv.octree is not None
    conv.octree.write_bt(tmp_path / "batch.bt")
    assert (out / "map.bt").read_bytes() == (tmp_path / "batch.bt").read_bytes()
