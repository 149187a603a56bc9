"""Raw IMU and the inertial initialisation from Python: synthetic motion with
known derivatives (numpy/scipy), degenerate motion, EuRoC V1_02 real data."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import data_path
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

import slam2world as s2w

G = 9.81


def _rotvec(t: np.ndarray) -> np.ndarray:
    return np.stack(
        [0.3 * np.sin(0.5 * t), 0.25 * np.sin(0.8 * t + 1.0), 0.6 * np.sin(0.3 * t) + 0.2],
        axis=-1,
    )


def _motion(t: np.ndarray, excite: float) -> tuple[np.ndarray, np.ndarray]:
    """Positions and accelerations (world, metres) of a smooth 3-D path."""
    p = np.stack(
        [
            0.3 * t + excite * 1.2 * np.sin(0.9 * t),
            -0.1 * t + excite * 0.8 * np.sin(1.3 * t + 0.4),
            excite * 0.4 * np.sin(0.7 * t + 1.0),
        ],
        axis=-1,
    )
    a = np.stack(
        [
            -excite * 1.2 * 0.81 * np.sin(0.9 * t),
            -excite * 0.8 * 1.69 * np.sin(1.3 * t + 0.4),
            -excite * 0.4 * 0.49 * np.sin(0.7 * t + 1.0),
        ],
        axis=-1,
    )
    return p, a


def _scenario(
    excite: float = 1.0, duration: float = 12.0, seed: int = 0
) -> tuple[s2w.Trajectory, s2w.ImuSamples, s2w.Sim3]:
    """Keyframes (T_slam_cam = T_slam_world · T_world_imu, camera on the IMU)
    at 10 Hz and raw IMU at 200 Hz with EuRoC-grade white noise and biases."""
    rng = np.random.default_rng(seed)
    rate = 200.0
    t = np.arange(int(duration * rate) + 41) / rate - 0.1
    h = 1e-4
    r_minus = Rotation.from_rotvec(_rotvec(t - h))
    r_plus = Rotation.from_rotvec(_rotvec(t + h))
    gyro = (r_minus.inv() * r_plus).as_rotvec() / (2 * h)
    _, acc = _motion(t, excite)
    r = Rotation.from_rotvec(_rotvec(t))
    accel = r.inv().apply(acc - np.array([0.0, 0.0, -G]))
    gyro += np.array([0.004, -0.006, 0.003]) + rng.normal(0, 1.6968e-4 * np.sqrt(rate), gyro.shape)
    accel += np.array([0.05, -0.08, 0.06]) + rng.normal(0, 2e-3 * np.sqrt(rate), accel.shape)
    t0 = 50.0
    imu = s2w.ImuSamples(t0 + t, gyro, accel)

    truth = s2w.Sim3.from_quaternion(
        Rotation.from_rotvec([0.7, -1.1, 0.4]).as_quat(), [2.0, -1.0, 0.5], scale=3.7
    )
    tk = np.arange(int(duration * 10) + 1) / 10.0
    pk, _ = _motion(tk, excite)
    rk = Rotation.from_rotvec(_rotvec(tk))
    slam_from_world = truth.inverse()
    positions = slam_from_world.apply(pk) + rng.normal(0, 0.003 / 3.7, pk.shape)
    orientations = Rotation.from_quat(slam_from_world.quaternion) * rk
    keyframes = s2w.Trajectory(t0 + tk, positions, orientations.as_quat())
    return keyframes, imu, truth


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    c = np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b))
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def test_imu_samples_round_trip_and_validation() -> None:
    t = np.array([0.0, 0.005, 0.01])
    g = np.arange(9.0).reshape(3, 3)
    a = g + 1.0
    imu = s2w.ImuSamples(t, g, a)
    assert len(imu) == 3
    assert_allclose(imu.timestamps, t)
    assert_allclose(imu.gyro, g)
    assert_allclose(imu.accel, a)
    with pytest.raises(s2w.InvalidInputError):
        s2w.ImuSamples(t, g[:2], a)
    with pytest.raises(s2w.InvalidInputError):
        s2w.ImuSamples(t, g[:, :2], a)
    with pytest.raises(s2w.InvalidInputError):
        s2w.ImuSamples(t[::-1].copy(), g, a)


def test_read_euroc(tmp_path: Path) -> None:
    p = tmp_path / "data.csv"
    p.write_text(
        "#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n"
        "1403715523912143104,-0.0007,0.0195,0.0768,9.218,0.302,-3.154\n"
        "1403715523917143040,0.001,0.02,0.07,9.2,0.3,-3.1\n"
    )
    imu = s2w.ImuSamples.read_euroc(p)
    assert len(imu) == 2
    assert imu.timestamps[1] - imu.timestamps[0] == pytest.approx(0.005, abs=1e-6)
    assert_allclose(imu.accel[0], [9.218, 0.302, -3.154])
    p.write_text("1,2,3\n")
    with pytest.raises(s2w.FormatError):
        s2w.ImuSamples.read_euroc(p)
    with pytest.raises(s2w.FileError):
        s2w.ImuSamples.read_euroc(tmp_path / "missing.csv")


def test_scale_gravity_and_biases_from_synthetic_motion() -> None:
    keyframes, imu, truth = _scenario()
    a = s2w.imu_initialize(
        keyframes, imu, keyframe_position_sigma=0.003, keyframe_rotation_sigma=1e-4
    )
    assert abs(a.scale / truth.scale - 1.0) < 0.01
    g_true = truth.inverse().rotation @ np.array([0.0, 0.0, -1.0])
    assert _angle_deg(a.gravity_slam, g_true) < 0.5
    assert np.linalg.norm(a.gravity_slam) == pytest.approx(9.81)
    assert_allclose(a.gyro_bias, [0.004, -0.006, 0.003], atol=5e-4)
    assert a.scale_sigma > 0 and a.gravity_sigma > 0
    assert a.transform.scale == pytest.approx(a.scale)
    # World z against gravity.
    assert_allclose(a.transform.rotation @ a.gravity_slam, [0.0, 0.0, -9.81], atol=1e-9)
    assert a.velocities.shape == (a.diagnostics["n_keyframes"], 3)
    assert a.diagnostics["n_skipped"] > 0  # 10 Hz keyframes, min_interval 0.5 s


def test_gravity_magnitude_is_configurable() -> None:
    keyframes, imu, _ = _scenario()
    a = s2w.imu_initialize(keyframes, imu, gravity=9.80665)
    assert np.linalg.norm(a.gravity_slam) == pytest.approx(9.80665)


def test_constant_velocity_is_degenerate() -> None:
    keyframes, imu, _ = _scenario(excite=0.0)
    with pytest.raises(s2w.DegenerateError, match="constant velocity"):
        s2w.imu_initialize(keyframes, imu)


def test_too_short_and_bad_arguments() -> None:
    keyframes, imu, _ = _scenario(duration=1.0)
    with pytest.raises(s2w.DegenerateError, match="too short"):
        s2w.imu_initialize(keyframes, imu)
    keyframes, imu, _ = _scenario()
    with pytest.raises(s2w.InvalidInputError):
        s2w.imu_initialize(keyframes, imu, gravity=0.0)
    with pytest.raises(s2w.InvalidInputError):
        s2w.imu_initialize(keyframes, imu, imu_from_cam=s2w.Sim3(scale=2.0))
    no_rot = s2w.Trajectory(keyframes.timestamps, keyframes.positions)
    with pytest.raises(s2w.InvalidInputError, match="orientations"):
        s2w.imu_initialize(no_rot, imu)


def test_euroc_v102_agrees_with_the_pose_fit() -> None:
    imu = s2w.ImuSamples.read_euroc(data_path("euroc_v102_imu", "V102.txt"))
    est = s2w.Trajectory.read_tum(data_path("euroc_v102", "V102.txt"))
    gt = s2w.Trajectory.read_euroc(data_path("euroc_v102", "V102_groundtruth.csv"))
    # The estimate (body poses, nearly metric) in an arbitrary SLAM frame and
    # scale; keyframes from 10 s on (the first 10 s are SLAM's start-up).
    slam_from_est = s2w.Sim3.from_quaternion(
        Rotation.from_rotvec([1.2, 0.3, -2.0]).as_quat(), [4.0, -3.0, 7.0], scale=0.2731
    )
    keep = est.timestamps >= est.timestamps[0] + 10.0
    o = est.orientations
    assert o is not None
    cut = s2w.Trajectory(est.timestamps[keep], est.positions[keep], o[keep])
    keyframes = cut.transformed(slam_from_est)
    a = s2w.imu_initialize(keyframes, imu)
    fit = s2w.align_trajectories(keyframes, gt)
    assert abs(a.scale / fit.transform.scale - 1.0) < 0.02
    g_ref = fit.transform.inverse().rotation @ np.array([0.0, 0.0, -1.0])
    assert _angle_deg(a.gravity_slam, g_ref) < 1.0


@pytest.mark.slow
def test_simulation_ten_second_window() -> None:
    """The simulation's keyframes (unknown Sim(3)) and EuRoC-grade raw IMU."""
    sim = s2w.simulate(seed=1, width=32, height=24, gyro_bias=0.01, accel_bias=0.05)
    kf = sim.keyframe_trajectory
    o = kf.orientations
    assert o is not None
    t = kf.timestamps
    keep = (t >= t[0] + 30.0) & (t <= t[0] + 40.0)
    keyframes = s2w.Trajectory(t[keep], kf.positions[keep], o[keep])
    imu = s2w.ImuSamples(sim.imu_timestamps, sim.gyro, sim.accel)
    truth = sim.t_world_slam
    a = s2w.imu_initialize(
        keyframes, imu, keyframe_position_sigma=0.003, keyframe_rotation_sigma=2e-4
    )
    assert abs(a.scale / truth.scale - 1.0) < 0.01
    g_true = truth.inverse().rotation @ np.array([0.0, 0.0, -1.0])
    assert _angle_deg(a.gravity_slam, g_true) < 0.5
    assert_allclose(a.gyro_bias, [0.01, 0.01, 0.01], atol=2e-3)
