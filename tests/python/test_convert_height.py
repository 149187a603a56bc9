"""`convert` with no second sensor: the ground plane of the SLAM cloud and the cameras' known
height give `T_world_slam` (`--camera-height`, Python `camera_height=`). On the EuRoC V1_01
ORB-SLAM2 map read as a trajectory with its cloud (heights from the ground truth: the first
keyframe's, then a `stamp height` file), against the Sim(3) fit to the ground truth; beside a
reference, the report compares the two; a simulated LSD-SLAM log with no reference and no IMU
converts from the CLI; bad heights are refused with the reason."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import data_path

import slam2world as sw
from slam2world._slam2world import run_cli


def v101_heights(tmp_path: Path) -> tuple[Path, Path, Path, sw.Sim3, np.ndarray]:
    """The map's files, the ground-truth fit, and a `stamp height` file of each keyframe's height
    over the floor (found once in the map aligned by the ground-truth fit)."""
    d = data_path("euroc_v101_orbslam2_map")
    kf_path = d / "KeyFrameTrajectory_TUM_Format.txt"
    gt_path = d / "V1_01_easy_original.txt"
    kf = sw.Trajectory.read_tum(kf_path)
    gt = sw.Trajectory.read_tum(gt_path)
    fit = sw.align_trajectories(kf, gt).transform
    floor = sw.ground_plane(fit.apply(np.loadtxt(d / "MapPoints.txt")), kf.transformed(fit))
    # The ground truth's span, a little beyond the keyframes' where it ends first.
    stamps = np.clip(kf.timestamps, gt.timestamps[0], gt.timestamps[-1])
    heights = gt.interpolate(stamps).positions[:, 2] + floor.offset / floor.normal[2]
    file = tmp_path / "heights.txt"
    np.savetxt(file, np.c_[kf.timestamps, heights], fmt="%.9f", header="stamp height")
    return kf_path, d / "MapPoints.txt", file, fit, heights


def test_the_camera_height_converts_v101_to_the_ground_truths_scale(tmp_path: Path) -> None:
    kf_path, cloud, file, fit, heights = v101_heights(tmp_path)
    rotation = fit.matrix()[:3, :3] / fit.scale
    for given in (f"first:{heights[0]}", file):
        c = sw.convert(kf_path, cloud=cloud, camera_height=given)
        g = c.report["prior"]
        t = c.transform
        up = np.asarray(g["up"])
        assert up @ g["plane"]["normal"] == pytest.approx(1.0, abs=1e-12)
        gravity = np.degrees(np.arccos(np.clip((rotation @ up)[2], -1, 1)))
        print(
            f"V1_01 convert, {g['camera_height']['kind']}: plane {g['plane']['inliers']} of "
            f"{g['plane']['n_points']}, scale {t.scale / fit.scale - 1:+.4%}, "
            f"gravity {gravity:.3f} deg"
        )
        assert g["used_for_transform"] and g["scale"] == t.scale
        assert g["scale_from"] == "camera_height" and g["up_from"] == "ground_plane"
        assert abs(t.scale / fit.scale - 1) < 0.03 and gravity < 1.5
        # The world: z up along the plane's normal, the first camera at its given height.
        first = t.apply(sw.Trajectory.read_tum(kf_path).positions[:1])[0]
        assert first[:2] == pytest.approx([0, 0], abs=1e-9)
        assert first[2] == pytest.approx(heights[0], abs=0.05)
        assert len(g["heights"]) == 74 and c.report["fit"] is None
        # The scale's stated sigma: the plane's (jackknife and band) and the heights' scatter,
        # and the given height's own. These heights are the body's (the IMU's) from the ground
        # truth, and the camera sits 2 cm under it (along the body's x, which points up): known
        # to about 2 cm. So given, the sigma covers the error. (The normal's sigma is no bar for
        # the gravity error here: the motion capture's z need not be the floor's normal to 0.4°.)
        err = t.scale / fit.scale - 1
        wide = sw.convert(kf_path, cloud=cloud, camera_height=given, camera_height_sigma=0.02)
        w = wide.report["prior"]
        print(
            f"  scale sigma {w['scale_sigma']:.4%} (ground {g['scale_sigma_ground']:.4%}), "
            f"normal sigma {g['plane']['tilt_sigma_deg']:.3f} deg"
        )
        assert 0 < g["scale_sigma"] == g["scale_sigma_ground"] < 0.02
        assert abs(err) <= 3 * w["scale_sigma"]
        assert g["plane"]["tilt_sigma_deg"] > 0
        assert w["camera_height_sigma"] == 0.02 and wide.transform.scale == t.scale
        stated = 0.02 / (heights[0] if isinstance(given, str) else np.median(heights))
        assert w["scale_sigma"] == pytest.approx(np.hypot(g["scale_sigma"], stated), rel=0.02)


def test_beside_a_reference_the_report_compares_the_prior(tmp_path: Path) -> None:
    kf_path, cloud, file, fit, _ = v101_heights(tmp_path)
    gt = data_path("euroc_v101_orbslam2_map", "V1_01_easy_original.txt")
    c = sw.convert(kf_path, cloud=cloud, reference=gt, camera_height=file)
    g = c.report["prior"]
    assert not g["used_for_transform"]
    assert c.transform.scale == pytest.approx(fit.scale, rel=1e-6)  # the reference sets it
    assert g["scale_vs_sensor"] == pytest.approx(g["scale"] / c.transform.scale - 1, rel=1e-9)
    assert abs(g["scale_vs_sensor"]) < 0.03 and g["up_vs_sensor_deg"] < 1.5


def test_bad_heights_are_refused_with_the_reason(tmp_path: Path) -> None:
    kf_path, cloud, file, _, _ = v101_heights(tmp_path)
    with pytest.raises(sw.InvalidInputError, match="positive number"):
        sw.convert(kf_path, cloud=cloud, camera_height=-1.2)
    short = tmp_path / "short.txt"
    short.write_text("\n".join(file.read_text().splitlines()[:20]) + "\n")
    with pytest.raises(sw.InvalidInputError, match="outside the heights' span"):
        sw.convert(kf_path, cloud=cloud, camera_height=short)
    bad = tmp_path / "bad.txt"
    bad.write_text("1.0 1.2\n0.5 1.3\n")
    with pytest.raises(sw.FormatError, match=r"bad.txt:2: stamps must increase"):
        sw.convert(kf_path, cloud=cloud, camera_height=bad)
    with pytest.raises(sw.InvalidInputError, match="give the height too"):
        sw.convert(kf_path, cloud=cloud, camera_height_sigma=0.05)
    with pytest.raises(sw.InvalidInputError, match="camera_height_sigma"):
        sw.convert(kf_path, cloud=cloud, camera_height=1.2, camera_height_sigma=-0.1)
    # A trajectory without its cloud has no ground to find.
    with pytest.raises(sw.InvalidInputError, match="reference"):
        sw.convert(kf_path, cloud=None)


@pytest.fixture(scope="module")
def no_sensor_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A simulated ground vehicle's LSD-SLAM log (camera at 1.2 m) with no reference and no IMU,
    its truth beside it (`g.truth.json`)."""
    log = tmp_path_factory.mktemp("nosensor") / "g.mcap"
    heights = ["camera_height=1.2", "height_loop=0", "height_slow=0", "look_height=0.6"]
    sets = [a for h in heights for a in ("--set", h)]
    args = ["simulate", "-o", str(log), "--reduced", "4", "--no-reference", "--no-imu", *sets]
    assert run_cli(["slam2world", *args]) == 0
    return log


@pytest.mark.slow
def test_a_log_with_no_second_sensor_converts_from_the_cli(
    no_sensor_log: Path, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    log = no_sensor_log
    out = tmp_path / "o"
    capfd.readouterr()
    assert run_cli(["slam2world", "convert", str(log), "-o", str(out)]) == 1
    assert "camera_height" in capfd.readouterr().err
    args = ["convert", str(log), "-o", str(out), "--camera-height", "1.2"]
    assert run_cli(["slam2world", *args, "--camera-height-sigma", "0.02"]) == 0
    assert "scale from the camera height, up from the ground plane" in capfd.readouterr().out
    report = json.loads((out / "report.json").read_text())
    truth = json.loads(log.with_suffix(".truth.json").read_text())["t_world_slam"]
    scale = report["t_world_slam"]["scale"]
    assert report["prior"]["used_for_transform"] and "imu" not in report
    assert abs(scale / truth["scale"] - 1) < 0.01
    # The scale along the run: every window's within 2 % of the truth (no drift here).
    windows = [w for w in report["prior"]["profile"] if w["scale"] is not None]
    assert report["prior"]["camera_height_sigma"] == 0.02
    assert report["prior"]["scale_sigma"] > 0.02 / 1.2
    assert len(windows) >= 2 and windows[-1]["last"] == len(report["prior"]["heights"]) - 1
    for w in windows:
        assert abs(w["scale"] / truth["scale"] - 1) < 0.02, w
    # The world's z is the truth's: the cloud's floor at 0 m.
    floor = sw.read_ply(out / "cloud.ply").points
    assert abs(np.percentile(floor[:, 2], 5)) < 0.05
    # A ground robot with no cloud needed: up from its cameras' plane, scored against the truth;
    # the scale from two keyframes at the distance the truth puts them (the keyframes are exact
    # but for their noise, so the scale is the truth's to that noise).
    kf = sw.read_mcap(log).keyframes
    slam_distance = float(np.linalg.norm(kf[20].pose.translation - kf[5].pose.translation))
    metres = truth["scale"] * slam_distance
    stamp = f"{kf[20].timestamp:.6f}"  # the second pose by its stamp
    args = ["convert", str(log), "-o", str(tmp_path / "p"), "--planar-motion"]
    # The first end as a map point (the camera centre's SLAM coordinates) gives the same.
    centre = ",".join(repr(float(v)) for v in kf[5].pose.translation)
    assert run_cli(["slam2world", *args, "--known-distance", centre, stamp, str(metres)]) == 0
    p = json.loads((tmp_path / "p" / "report.json").read_text())["prior"]
    assert p["known_distance"]["poses"] == [None, 20]
    assert p["scale"] == pytest.approx(truth["scale"], rel=1e-6)
    assert run_cli(["slam2world", *args, "--known-distance", "5", stamp, str(metres)]) == 0
    p = json.loads((tmp_path / "p" / "report.json").read_text())["prior"]
    assert p["up_from"] == "planar_motion" and p["scale_from"] == "known_distance"
    assert p["known_distance"]["poses"] == [5, 20] and p["plane"] is None
    assert p["scale"] == pytest.approx(truth["scale"], rel=1e-6)
    rotation = np.asarray(truth["matrix"])[:3, :3] / truth["scale"]
    gravity = np.degrees(np.arccos(np.clip((rotation @ np.asarray(p["up"]))[2], -1, 1)))
    assert gravity < 1.0 and p["planar_motion"]["tilt_bound_deg"] < 1.0
    capfd.readouterr()
    assert run_cli(["slam2world", *args]) == 1  # "up" alone
    assert "give the scale too" in capfd.readouterr().err
    # A bad value is a usage error (clap's exit code 2) with the reason.
    assert (
        run_cli(["slam2world", "convert", str(log), "-o", str(out), "--camera-height", "-1"]) == 2
    )
    assert "positive number of metres" in capfd.readouterr().err


def test_a_known_distance_scales_v101_by_index_or_stamp_and_its_flight_is_no_planar_motion(
    tmp_path: Path,
) -> None:
    kf_path, cloud, _, fit, _ = v101_heights(tmp_path)
    kf = sw.Trajectory.read_tum(kf_path)
    gt = sw.Trajectory.read_tum(data_path("euroc_v101_orbslam2_map", "V1_01_easy_original.txt"))
    # A keyframe inside the ground truth's span and the one farthest from it.
    a = 3
    b = int(np.argmax(np.linalg.norm(kf.positions - kf.positions[a], axis=1)))
    body = gt.interpolate(kf.timestamps[[a, b]]).positions
    metres = float(np.linalg.norm(body[1] - body[0]))
    for pose_b in (b, float(kf.timestamps[b])):
        c = sw.convert(kf_path, cloud=cloud, known_distance=(a, pose_b, metres))
        p = c.report["prior"]
        assert p["known_distance"]["poses"] == [a, b] and p["scale_from"] == "known_distance"
        print(
            f"V1_01, keyframes {a} and {b} {metres:.3f} m apart: "
            f"{c.transform.scale / fit.scale - 1:+.4%}"
        )
        assert abs(c.transform.scale / fit.scale - 1) < 0.03
    # Two map points (SLAM coordinates, as a viewer of the map shows them), the distance the
    # ground-truth fit puts them apart: the fit's scale, whichever end is a point or a pose.
    points = np.loadtxt(cloud)
    i, j = 10, int(np.argmax(np.linalg.norm(points - points[10], axis=1)))
    apart = float(np.linalg.norm(fit.apply(points[[i]])[0] - fit.apply(points[[j]])[0]))
    c = sw.convert(kf_path, cloud=cloud, known_distance=(tuple(points[i]), points[j], apart))
    d = c.report["prior"]["known_distance"]
    assert d["poses"] == [None, None] and d["ends"][1] == pytest.approx(points[j], abs=1e-12)
    assert c.transform.scale == pytest.approx(fit.scale, rel=1e-9)
    pose_to_point = float(
        np.linalg.norm(fit.apply(kf.positions[[a]])[0] - fit.apply(points[[j]])[0])
    )
    c = sw.convert(kf_path, cloud=cloud, known_distance=(a, list(points[j]), pose_to_point))
    assert c.report["prior"]["known_distance"]["poses"] == [a, None]
    assert c.transform.scale == pytest.approx(fit.scale, rel=1e-9)
    with pytest.raises(sw.InvalidInputError, match="finite"):
        sw.convert(kf_path, cloud=cloud, known_distance=(a, (0.0, np.nan, 1.0), metres))
    with pytest.raises(sw.InvalidInputError, match="not among"):
        sw.convert(kf_path, cloud=cloud, known_distance=(a, 500, metres))
    with pytest.raises(sw.DegenerateError, match="do not ride in one plane"):
        sw.convert(kf_path, cloud=cloud, known_distance=(a, b, metres), planar_motion=True)
    with pytest.raises(sw.InvalidInputError, match="give the scale too"):
        sw.convert(kf_path, cloud=cloud, planar_motion=True)


@pytest.mark.slow
def test_a_long_run_refits_the_ground_on_a_sample_until_the_end() -> None:
    """Before the end a ground refit weighs every k-th point (at most 100 000, so that a refit
    does not hold up a keyframe for long); at the end all of them. A run at half size has about
    150 000: the last refit before the end is within a per mille of the end's."""
    import re

    sim = sw.simulate(
        reduced=2,
        seed=5,
        camera_height=1.2,
        height_loop=0.0,
        height_slow=0.0,
        look_height=0.6,
    )
    session = sw.Session(camera_height=1.2)
    for kf in sim.keyframes:
        session.push_keyframe(kf)
    counted = re.compile(r"of (\d+) points")
    before = session.transform()
    found = counted.search(session.state()["reason"])
    assert found is not None
    sampled = int(found.group(1))
    session.finish()
    after = session.transform()
    found = counted.search(session.state()["reason"])
    assert found is not None
    every = int(found.group(1))
    assert before is not None and after is not None
    assert every > 100_000 >= sampled
    assert before.scale == pytest.approx(after.scale, rel=1e-3)


@pytest.mark.slow
def test_the_session_scales_as_soon_as_the_ground_is_seen_and_ends_on_the_batch(
    no_sensor_log: Path, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    keyframes = sw.read_mcap(no_sensor_log).keyframes
    session = sw.Session(camera_height=1.2)
    stable_at = None
    for i, kf in enumerate(keyframes):
        session.push_keyframe(kf)
        if stable_at is None and session.transform() is not None:
            stable_at = i
            assert session.state()["stage"] == "stable"
            assert "ground plane" in session.state()["reason"]
    # The viewer's filter drops the first five keyframes' points: a few more and the floor is
    # supported, long before the end.
    assert stable_at is not None and stable_at < len(keyframes) // 2
    session.finish()
    batch = sw.convert(no_sensor_log, camera_height=1.2).transform
    online = session.transform()
    assert online is not None and online.scale == pytest.approx(batch.scale, rel=1e-12)
    np.testing.assert_allclose(online.matrix(), batch.matrix(), rtol=0, atol=1e-9)
    with pytest.raises(sw.InvalidInputError, match="batch convert"):
        sw.Session(camera_height=str(tmp_path / "heights.txt"))
    # follow: the same from the command line.
    out = tmp_path / "f"
    args = ["follow", str(no_sensor_log), "-o", str(out), "--camera-height", "1.2"]
    assert run_cli(["slam2world", *args]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["stage"] == "stable"
    assert report["t_world_slam"]["scale"] == pytest.approx(batch.scale, rel=1e-12)
