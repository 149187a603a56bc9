"""Metric scale and gravity with no second sensor: the ground plane of the EuRoC V1_01 ORB-SLAM2
map and the camera heights the ground truth gives (only the first one, then one per keyframe),
against the Sim(3) fit to the ground truth; a table top beside the floor passed over, and
refusals when the floor is missing (with or without a table top taken for it)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import data_path

import slam2world as sw

FACTOR = 0.37  # the map's units made arbitrary


def v101() -> tuple[np.ndarray, sw.Trajectory, sw.Trajectory]:
    d = data_path("euroc_v101_orbslam2_map")
    points = np.loadtxt(d / "MapPoints.txt")
    kf = sw.Trajectory.read_tum(d / "KeyFrameTrajectory_TUM_Format.txt")
    gt = sw.Trajectory.read_tum(d / "V1_01_easy_original.txt")
    return points, kf, gt


def test_the_floor_and_the_camera_height_give_the_ground_truths_scale_and_gravity() -> None:
    points, kf, gt = v101()
    fit = sw.align_trajectories(kf, gt).transform
    # The setup: the floor found once in the map aligned by the ground-truth fit, and each
    # keyframe's height the body's ground-truth height over it.
    floor = sw.ground_plane(fit.apply(points), kf.transformed(fit))
    assert np.degrees(np.arccos(floor.normal[2])) < 1.0
    inside = (kf.timestamps >= gt.timestamps[0]) & (kf.timestamps <= gt.timestamps[-1])
    stamps = kf.timestamps[inside]
    heights = gt.interpolate(stamps).positions[:, 2] + floor.offset / floor.normal[2]
    # The method sees only the map, in arbitrary units, and the heights.
    cams = sw.Trajectory(stamps, FACTOR * kf.positions[inside], kf.orientations[inside])
    plane = sw.ground_plane(FACTOR * points, cams)
    assert plane.inliers > len(points) / 3 and plane.cameras_above == 1.0
    assert plane.below < 0.05 and plane.runner_up is None
    truth = fit.scale / FACTOR
    rotation = fit.matrix()[:3, :3] / fit.scale
    gravity = np.degrees(np.arccos(np.clip((rotation @ plane.normal)[2], -1, 1)))
    first = sw.metric_from_height(plane, cams, heights[0], first=True)
    over_time = sw.metric_from_height(plane, cams, heights)
    print(
        f"V1_01: plane {plane.inliers} of {plane.n_points} points, spread {plane.spread:.4f}, "
        f"gravity {gravity:.3f} deg; scale from the first height {first.scale / truth - 1:+.4%}, "
        f"from every height {over_time.scale / truth - 1:+.4%} (rms {over_time.height_rms:.3f} m)"
    )
    assert gravity < 1.5
    for m in (first, over_time):
        assert abs(m.scale / truth - 1) < 0.03
    # The metric frame: z up within the same angle, the first camera at its height over the origin.
    z = m.transform.matrix()[:3, :3].T[:, 2]  # the world's z in the SLAM frame, times the scale
    assert np.degrees(np.arccos(np.clip(z @ plane.normal / np.linalg.norm(z), -1, 1))) < 1e-9
    c0 = first.transform.apply(cams.positions[:1])[0]
    assert np.allclose(c0, [0, 0, heights[0]], rtol=0, atol=1e-9)


def room(*, floor: bool, table: bool) -> tuple[np.ndarray, sw.Trajectory]:
    """Walls, an optional floor and table top, cameras at 1.2 m looking ahead around a circle."""
    rng = np.random.default_rng(3)
    u = lambda s, n: rng.uniform(-s, s, n)  # noqa: E731
    n = 3000
    parts = [
        np.c_[5 + u(0.01, n), u(5, n), 1.5 + u(1.5, n)],
        np.c_[u(5, n), 5 + u(0.01, n), 1.5 + u(1.5, n)],
    ]
    if floor:
        parts.append(np.c_[u(5, n), u(5, n), u(0.01, n)])
    if table:
        parts.append(np.c_[u(4.2, n), u(4.2, n), 0.75 + u(0.01, n)])
    a = np.arange(40) * 0.15
    ahead = np.c_[-np.sin(a), np.cos(a), 0 * a]
    down = np.tile([0.0, 0.0, -1.0], (40, 1))
    r = np.stack([np.cross(down, ahead), down, ahead], axis=2)
    from scipy.spatial.transform import Rotation

    cams = sw.Trajectory(
        a, np.c_[2 * np.cos(a), 2 * np.sin(a), 1.2 + 0 * a], Rotation.from_matrix(r).as_quat()
    )
    return np.vstack(parts), cams


@pytest.mark.parametrize(
    ("floor", "table", "needle"),
    [(False, False, "no plane"), (False, True, "under the plane")],
)
def test_no_floor_or_a_competing_table_is_refused(floor: bool, table: bool, needle: str) -> None:
    points, cams = room(floor=floor, table=table)
    with pytest.raises(sw.DegenerateError, match=needle):
        sw.ground_plane(points, cams)


@pytest.mark.parametrize("table", [False, True])
def test_a_room_with_a_floor_is_measured(table: bool) -> None:
    points, cams = room(floor=True, table=table)
    plane = sw.ground_plane(points, cams)
    assert np.degrees(np.arccos(plane.normal[2])) < 0.2
    assert abs(plane.offset) < 0.01  # the floor at z = 0, not the table top at 0.75 m
    if table:
        assert plane.runner_up is not None and plane.runner_up[1] == pytest.approx(0.75, abs=0.02)
    m = sw.metric_from_height(plane, cams, 1.2)
    assert m.scale == pytest.approx(1.0, rel=0.01)
    with pytest.raises(sw.InvalidInputError):
        sw.metric_from_height(plane, cams, -1.0)
    with pytest.raises(sw.InvalidInputError):
        sw.metric_from_height(plane, cams, [1.2, 1.2])


def test_a_known_distance_scales_v101_and_its_flight_is_no_planar_motion() -> None:
    points, kf, gt = v101()
    fit = sw.align_trajectories(kf, gt).transform
    inside = (kf.timestamps >= gt.timestamps[0]) & (kf.timestamps <= gt.timestamps[-1])
    stamps = kf.timestamps[inside]
    cams = sw.Trajectory(stamps, FACTOR * kf.positions[inside], kf.orientations[inside])
    truth = fit.scale / FACTOR
    # Two keyframes far apart, their distance measured on the ground truth (the body's centres:
    # the camera sits a few centimetres off, turning with it).
    body = gt.interpolate(stamps).positions
    far = int(np.argmax(np.linalg.norm(cams.positions - cams.positions[0], axis=1)))
    metres = float(np.linalg.norm(body[far] - body[0]))
    scale = sw.scale_from_distance(cams, 0, far, metres)
    print(f"V1_01: keyframes 0 and {far}, {metres:.3f} m apart: scale {scale / truth - 1:+.4%}")
    assert abs(scale / truth - 1) < 0.02
    # The known distance and the floor's normal make the frame; the first camera over the
    # origin, at the height given.
    plane = sw.ground_plane(FACTOR * points, cams)
    frame = sw.level_frame(plane.normal, cams, scale, first_height=1.0)
    assert np.allclose(frame.apply(cams.positions[:1])[0], [0, 0, 1.0], atol=1e-9)
    assert frame.scale == scale
    # A flying camera does not ride in one plane.
    with pytest.raises(sw.DegenerateError, match="do not ride in one plane"):
        sw.planar_motion(cams)
    with pytest.raises(sw.InvalidInputError, match="same place"):
        sw.scale_from_distance(cams, 3, 3, 1.0)


def test_planar_motion_finds_up_from_cameras_circling_at_one_height() -> None:
    _, cams = room(floor=True, table=False)
    p = sw.planar_motion(cams)
    assert p.normal @ [0, 0, 1] > 1 - 1e-12 and p.rms < 1e-9 and p.n == 40
    no_orientations = sw.Trajectory(cams.timestamps, cams.positions)
    with pytest.raises(sw.InvalidInputError, match="no orientations"):
        sw.planar_motion(no_orientations)


def test_the_height_profile_scales_each_window_and_says_why_one_has_none() -> None:
    points, cams = room(floor=True, table=False)
    # Each point seen from its nearest camera; the floor points under the circle only.
    owner = np.argmin(
        np.linalg.norm(points[:, None, :2] - cams.positions[None, :, :2], axis=2), axis=1
    )
    p = sw.height_profile(points, owner, cams, 1.2, 10)
    assert list(p["first"]) == [0, 5, 10, 15, 20, 25, 30] and p["last"][-1] == 39
    assert np.allclose(p["scale"], 1.0, rtol=0.02) and p["reason"] == [None] * 7
    # Without the floor points under the last cameras, their window has no scale.
    seen = ~((owner >= 30) & (points[:, 2] < 0.1))
    q = sw.height_profile(points[seen], owner[seen], cams, 1.2, 10)
    assert np.isnan(q["scale"][-1]) and q["reason"][-1] is not None
    assert not np.isnan(q["scale"][0])
    with pytest.raises(sw.InvalidInputError):
        sw.height_profile(points, owner[:-1], cams, 1.2, 10)
