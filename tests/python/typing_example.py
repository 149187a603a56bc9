"""A typed usage example: mypy --strict checks it (make lint) and pytest runs it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt

import slam2world as s2w


def carry(points: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
    t = s2w.Sim3.from_quaternion([0.0, 0.0, 0.0, 1.0], [1.0, 2.0, 3.0], scale=2.0)
    u: s2w.Sim3 = t @ t.inverse()
    out: npt.NDArray[np.float32] = u.apply(points)
    return out


def test_typing_example() -> None:
    pts = np.ones((4, 3), dtype=np.float32)
    out = carry(pts)
    assert out.dtype == np.float32
    np.testing.assert_allclose(out, pts, rtol=1e-6)


def occupancy(points: npt.NDArray[np.float64]) -> npt.NDArray[np.int8]:
    m = s2w.OccupancyMap(0.1, max_range=10.0)
    free, occupied = m.insert(points, np.zeros(3))
    hit: npt.NDArray[np.float64] | None = m.cast_ray([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], 5.0)
    assert hit is None or hit.shape == (3,)
    assert free + occupied == m.free_centers().shape[0] + m.occupied_centers().shape[0]
    return m.state(points)


def test_occupancy_typing_example() -> None:
    pts = np.array([[1.05, 0.05, 0.05], [0.05, 2.05, 0.05]])
    np.testing.assert_array_equal(occupancy(pts), [1, 1])


def fit(slam: npt.NDArray[np.float64], world: npt.NDArray[np.float64]) -> tuple[float, float]:
    a: s2w.Alignment = s2w.align(slam, world, scale=True, method="horn")
    traj = s2w.Trajectory(np.arange(len(slam), dtype=np.float64), slam)
    ref = s2w.Trajectory(np.arange(len(world), dtype=np.float64), world)
    r: s2w.TrajectoryAlignment = s2w.align_trajectories(traj, ref, max_diff=0.01, n_to_align=None)
    idx_slam, idx_ref = s2w.associate(traj, ref)
    p: npt.NDArray[np.float64] = s2w.scale_factors(slam[idx_slam], world[idx_ref])
    return a.transform.scale, float(r.rmse + p.mean() * 0.0)


def test_typed_alignment() -> None:
    t = np.linspace(0.0, 3.0, 10)
    slam = np.column_stack([np.cos(t), np.sin(t), 0.1 * t])  # a path, not scattered points
    world = s2w.Sim3.from_quaternion([0.0, 0.0, 0.0, 1.0], [1.0, 0.0, 0.0], 2.0).apply(slam)
    s, rmse = fit(slam, world)
    assert abs(s - 2.0) < 1e-12 and rmse < 1e-12


def world_cloud(path: str) -> int:
    cam = s2w.PinholeCamera(100.0, 100.0, 15.5, 11.5, 32, 24)
    idepth = np.full((24, 32), 0.5, dtype=np.float32)
    var = np.full((24, 32), 1e-6, dtype=np.float32)
    kf = s2w.Keyframe(0, 0.0, s2w.Sim3(), cam, idepth, var, None)
    f = s2w.PointFilter(cut_first_keyframes=None)
    world = s2w.Sim3.from_quaternion([0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 1.0], 2.0)
    cloud: s2w.PointCloud = s2w.backproject([kf], f, transform=world)
    pts: npt.NDArray[np.float32] = cloud.points
    cloud.transformed(world.inverse()).write_ply(path)
    back: s2w.PointCloud = s2w.read_ply(path)
    assert back.colors is None and pts.dtype == np.float32
    return len(back)


def test_typed_cloud(tmp_path: Path) -> None:
    assert world_cloud(str(tmp_path / "c.ply")) == 30 * 22


def at_rest_is_degenerate() -> str:
    """Keyframes and IMU of a body at rest: the scale is unobservable."""
    t = 100.0 + np.arange(101, dtype=np.float64) * 0.1
    pos = np.tile([1.0, 2.0, 3.0], (101, 1))
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (101, 1))
    keyframes = s2w.Trajectory(t, pos, quat)
    ti = 99.95 + np.arange(2021, dtype=np.float64) * 0.005
    gyro = np.zeros((2021, 3))
    accel = np.tile([0.0, 0.0, 9.81], (2021, 1))
    imu: s2w.ImuSamples = s2w.ImuSamples(ti, gyro, accel)
    try:
        a: s2w.ImuAlignment = s2w.imu_initialize(keyframes, imu, imu_from_cam=None, gravity=9.81)
    except s2w.DegenerateError as e:
        return str(e)
    g: npt.NDArray[np.float64] = a.gravity_slam
    return f"unexpected answer {a.scale} {g}"


def test_imu_typing_example() -> None:
    assert "unobservable" in at_rest_is_degenerate()


def simulated_experiment() -> tuple[float, float]:
    sim: s2w.Simulation = s2w.simulate(seed=2, reduced=16, n_keyframes=4, scale_drift=0.0)
    fit = s2w.align_trajectories(sim.keyframe_trajectory, sim.reference)
    cloud = s2w.backproject(sim.keyframes, s2w.PointFilter.none(), transform=fit.transform)
    scores: dict[str, dict[str, float]] = s2w.evaluate(sim, cloud.points, fit.transform)
    d: npt.NDArray[np.float64] = s2w.point_distances(sim, cloud.points)
    return scores["transform"]["scale_error"], float(np.median(d))


def test_typed_simulation() -> None:
    scale_error, median = simulated_experiment()
    assert abs(scale_error) < 0.01 and median < 0.05


def georeference(tmp: Path) -> tuple[int, float]:
    fixes = s2w.GnssFixes(
        [0.0, 1.0, 2.0], [48.0, 48.001, 48.002], [11.0, 11.0, 11.0], [500.0, 500.0, 500.0]
    )
    traj, weights, origin = fixes.to_enu("first")
    assert weights is None and len(fixes) == 3
    enu: npt.NDArray[np.float64] = s2w.geodetic_to_enu(fixes.lat, fixes.lon, fixes.alt, origin)
    xyz, zone, hemisphere, epsg = s2w.geodetic_to_utm(fixes.lat, fixes.lon, fixes.alt)
    lat, lon, alt = s2w.utm_to_geodetic(xyz, zone, hemisphere)
    cloud = s2w.PointCloud(enu.astype(np.float32))
    written: int = cloud.write_las(tmp / "map.laz", origin=origin)
    cloud.write_pcd(tmp / "map.pcd")
    assert written == epsg
    return epsg, float(np.max(np.abs(traj.positions - enu)) + np.max(np.abs(lat - fixes.lat)))


def test_geo_typing_example(tmp_path: Path) -> None:
    epsg, err = georeference(tmp_path)
    assert epsg == 32632 and err < 1e-6
