"""DROID-SLAM reconstruction folders written with numpy as DROID-SLAM's
``save_reconstruction`` writes them (``disps`` at 1/8 and ``disps_up`` at full
resolution), read back to the keyframes they were made from."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

import slam2world as s2w

N, H8, W8 = 8, 6, 8  # keyframes; disparity grid at 1/8 resolution
K8 = np.array([7.0, 7.5, 3.9, 2.8], dtype=np.float32)  # fx fy cx cy at 1/8


def rot_y(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def cam_to_world(i: int) -> tuple[np.ndarray, np.ndarray]:
    """Camera i: rotation and centre (T_world_cam), looking at the plane z = 5."""
    return rot_y(0.01 * i), np.array([0.05 * i, 0.02, 0.0])


def quat_xyzw(r: np.ndarray) -> np.ndarray:
    w = np.sqrt(max(0.0, 1 + np.trace(r))) / 2
    return np.array(
        [
            (r[2, 1] - r[1, 2]) / (4 * w),
            (r[0, 2] - r[2, 0]) / (4 * w),
            (r[1, 0] - r[0, 1]) / (4 * w),
            w,
        ]
    )


def plane_disparity(i: int, k: np.ndarray, h: int, w: int) -> np.ndarray:
    r, c = cam_to_world(i)
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    rays = np.stack([(xs - k[2]) / k[0], (ys - k[3]) / k[1], np.ones_like(xs)], axis=-1) @ r.T
    depth = (5.0 - c[2]) / rays[..., 2]
    return (1.0 / depth).astype(np.float32)


def write_folder(path: Path, r: int) -> np.ndarray:
    """The five arrays; disparities at 1/r of the image. Returns the images (BGR)."""
    path.mkdir(parents=True, exist_ok=True)
    big_h, big_w = 8 * H8, 8 * W8
    h, w = big_h // r, big_w // r
    k = K8.astype(np.float64) * (8 / r)
    poses = []
    for i in range(N):
        rot, centre = cam_to_world(i)
        rcw = rot.T  # world-to-camera, as lietorch stores it
        poses.append(np.concatenate([-rcw @ centre, quat_xyzw(rcw)]))
    rng = np.random.default_rng(4)
    images = rng.integers(0, 255, size=(N, 3, big_h, big_w), dtype=np.uint8)
    np.save(path / "tstamps.npy", np.arange(N, dtype=np.float32) * 3)
    np.save(path / "images.npy", images)
    np.save(path / "poses.npy", np.array(poses, dtype=np.float32))
    np.save(path / "disps.npy", np.stack([plane_disparity(i, k, h, w) for i in range(N)]))
    np.save(path / "intrinsics.npy", np.tile(K8, (N, 1)))
    return images


@pytest.mark.parametrize("r", [8, 1])
def test_folder_reads_back_to_its_keyframes(tmp_path: Path, r: int) -> None:
    images = write_folder(tmp_path, r)
    rec = s2w.read_droid(tmp_path)
    assert (rec.downsample, rec.image_size, len(rec)) == (r, (8 * H8, 8 * W8), N)
    kfs = rec.keyframes
    for i, kf in enumerate(kfs):
        assert (kf.id, kf.timestamp) == (i, 3.0 * i)
        # Poses inverted: the camera centre is the known one (float32 storage).
        rot, centre = cam_to_world(i)
        assert_allclose(kf.pose.translation, centre, atol=1e-6)
        assert_allclose(kf.pose.rotation, rot, atol=1e-6)
        cam = kf.camera
        assert (cam.width, cam.height) == (8 * W8 // r, 8 * H8 // r)
        assert_allclose([cam.fx, cam.fy, cam.cx, cam.cy], K8 * (8 / r), rtol=1e-6)
        assert kf.idepth.shape == (8 * H8 // r, 8 * W8 // r)
        # Colour: RGB of the BGR image at the grid's sample points (DROID's 3::8).
        off = (r - 1) // 2
        want = images[i][::-1, off::r, off::r].transpose(1, 2, 0)
        assert np.array_equal(kf.color, want)
    # Backprojected with no filter, every pixel lies on the plane z = 5.
    cloud = s2w.backproject(kfs, s2w.PointFilter.none())
    assert len(cloud.points) == N * kfs[0].idepth.size
    assert_allclose(cloud.points[:, 2], 5.0, atol=1e-4)


def test_consistency_filter_drops_an_inconsistent_keyframe(tmp_path: Path) -> None:
    write_folder(tmp_path, 8)
    kfs = s2w.read_droid(tmp_path).keyframes
    bad = kfs[4]
    kfs[4] = s2w.Keyframe(
        bad.id, bad.timestamp, bad.pose, bad.camera, bad.idepth * 1.3, color=bad.color
    )
    counts = s2w.depth_consistency_counts(kfs, threshold=0.05)
    assert [c.shape for c in counts] == [(H8, W8)] * N and counts[0].dtype == np.uint32
    assert (counts[4] >= 2).sum() == 0
    assert (counts[1] >= 2).mean() > 0.5
    kept = s2w.filter_consistent(kfs, threshold=0.05, min_disparity_ratio=0.0)
    assert np.all(kept[4].idepth == 0)
    assert np.array_equal(kept[1].idepth > 0, counts[1] >= 2)


def test_bad_folders_raise(tmp_path: Path) -> None:
    write_folder(tmp_path, 8)
    np.save(tmp_path / "poses.npy", np.zeros((N, 6), dtype=np.float32))
    with pytest.raises(s2w.FormatError, match=r"poses.npy.*\(8, 7\)"):
        s2w.read_droid(tmp_path)
    write_folder(tmp_path, 8)
    np.save(tmp_path / "images.npy", np.zeros((N, 3, 8 * H8, 8 * W8), dtype=np.float32))
    with pytest.raises(s2w.FormatError, match="uint8"):
        s2w.read_droid(tmp_path)
    write_folder(tmp_path, 8)
    np.save(tmp_path / "disps.npy", np.ones((N, 5, 7), dtype=np.float32))
    with pytest.raises(s2w.FormatError, match="whole number"):
        s2w.read_droid(tmp_path)
    write_folder(tmp_path, 8)
    np.save(tmp_path / "tstamps.npy", np.arange(N, dtype=np.complex64))
    with pytest.raises(s2w.FormatError, match="dtype"):
        s2w.read_droid(tmp_path)
    raw = (tmp_path / "intrinsics.npy").read_bytes()
    np.save(tmp_path / "tstamps.npy", np.arange(N, dtype=np.float32))
    (tmp_path / "intrinsics.npy").write_bytes(raw[:-4])
    with pytest.raises(s2w.FormatError, match="byte 128: data"):
        s2w.read_droid(tmp_path)
    (tmp_path / "intrinsics.npy").unlink()
    with pytest.raises(s2w.FormatError, match="missing intrinsics.npy"):
        s2w.read_droid(tmp_path)
