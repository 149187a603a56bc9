"""Backprojection against a plain-numpy reference of the LSD-SLAM viewer, PLY files,
point-cloud transforms, and errors at the Python boundary."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
from cloud_reference import (
    RefFilter,
    RefKeyframe,
    reference_loop,
    reference_vectorised,
)
from conftest import data_path

import slam2world as sw

W, H = 24, 18


def random_sim3(rng: np.random.Generator, scale: float) -> sw.Sim3:
    q = rng.normal(size=4)
    return sw.Sim3.from_quaternion(q, rng.uniform(-3, 3, size=3), scale)


def make_keyframe(
    rng: np.random.Generator,
    kf_id: int,
    scale: float,
    *,
    variance: bool = True,
    color: bool = True,
    w: int = W,
    h: int = H,
) -> tuple[sw.Keyframe, RefKeyframe]:
    """A smooth inverse-depth surface with noise, holes, negative and NaN values,
    and variances spread across the viewer's thresholds."""
    yy, xx = np.mgrid[0:h, 0:w]
    idepth = 1.0 + 0.2 * np.sin(xx / 6.0) + 0.1 * np.cos(yy / 5.0)
    idepth = idepth + rng.normal(0, 0.005, size=(h, w))
    # Holes in blobs (as semi-dense maps have) and a few isolated ones.
    blobs = np.sin(xx / 2.5 + rng.uniform(0, 6)) * np.sin(yy / 2.0 + rng.uniform(0, 6)) > 0.6
    u = rng.random((h, w))
    idepth[blobs | (u < 0.04)] = 0.0
    idepth[(u >= 0.04) & (u < 0.06)] = -0.3
    idepth[h // 2, w // 3] = np.nan
    idepth = idepth.astype(np.float32)
    var = (10.0 ** rng.uniform(-6, -2, size=(h, w))).astype(np.float32) if variance else None
    col = rng.integers(0, 256, size=(h, w, 3), dtype=np.uint8) if color else None
    pose = random_sim3(rng, scale)
    cam = sw.PinholeCamera(30.0 + kf_id, 28.0, w / 2 - 0.5, h / 2 + 0.25, w, h)
    kf = sw.Keyframe(kf_id, 0.1 * kf_id, pose, cam, idepth, var, col)
    ref = RefKeyframe(
        id=kf_id,
        pose=pose.matrix(),
        scale=pose.scale,
        fx=cam.fx,
        fy=cam.fy,
        cx=cam.cx,
        cy=cam.cy,
        idepth=idepth,
        idepth_var=var,
        color=col,
    )
    return kf, ref


def make_set(
    seed: int, n: int = 9, *, color: bool = True, variance: bool = True
) -> tuple[list[sw.Keyframe], list[RefKeyframe]]:
    rng = np.random.default_rng(seed)
    scales = [0.5, 1.0, 3.0, 12.0, 30.0]
    pairs = [
        make_keyframe(rng, 100 + i, scales[i % len(scales)], color=color, variance=variance)
        for i in range(n)
    ]
    return [p[0] for p in pairs], [p[1] for p in pairs]


def to_sw(f: RefFilter) -> sw.PointFilter:
    return sw.PointFilter(
        scaled_depth_var=f.scaled_depth_var,
        abs_depth_var=f.abs_depth_var,
        min_near_support=f.min_near_support,
        sparsify=f.sparsify,
        cut_first_keyframes=f.cut_first_keyframes,
        skip_border=f.skip_border,
        seed=f.seed,
    )


def assert_same_points(got: npt.NDArray[np.float32], want: npt.NDArray[np.float64]) -> None:
    assert got.shape == want.shape
    err = np.linalg.norm(got.astype(np.float64) - want, axis=1)
    tol = 1e-6 * np.maximum(np.linalg.norm(want, axis=1), 1e-3)
    assert np.all(err <= tol), f"max relative error {np.max(err / tol) * 1e-6:.3g}"


FILTERS = {
    "default": RefFilter(),
    "none": RefFilter(
        scaled_depth_var=np.inf,
        abs_depth_var=np.inf,
        min_near_support=0,
        cut_first_keyframes=None,
        skip_border=False,
    ),
    "tight_abs": RefFilter(scaled_depth_var=1e-2, abs_depth_var=2e-3, min_near_support=4),
    "sparse_borders": RefFilter(
        sparsify=3, seed=7, min_near_support=3, cut_first_keyframes=None, skip_border=False
    ),
    "cut0": RefFilter(cut_first_keyframes=0, min_near_support=6, seed=3, sparsify=2),
}


@pytest.mark.parametrize("name", sorted(FILTERS))
@pytest.mark.parametrize("color", [True, False])
@pytest.mark.parametrize("world", [False, True])
def test_backproject_matches_viewer_reference(name: str, color: bool, world: bool) -> None:
    kfs, refs = make_set(11, color=color)
    f = FILTERS[name]
    t = random_sim3(np.random.default_rng(5), 2.7) if world else None
    cloud = sw.backproject(kfs, to_sw(f), transform=t)
    pts, cols, ids = reference_loop(refs, f, None if t is None else t.matrix())
    assert len(cloud) == len(pts) > 0
    assert_same_points(cloud.points, pts)
    np.testing.assert_array_equal(cloud.keyframe_ids, ids)
    if color:
        assert cloud.colors is not None and cols is not None
        np.testing.assert_array_equal(cloud.colors, cols)
    else:
        assert cloud.colors is None


def test_every_rule_removes_points() -> None:
    """Turning each rule off on the reference must change the count: the synthetic
    keyframes exercise every rule, so the comparison above tests each of them."""
    _, refs = make_set(11)
    base = RefFilter(scaled_depth_var=1e-3, abs_depth_var=2e-3, min_near_support=4, sparsify=2)
    n = len(reference_loop(refs, base)[0])
    off = {
        "scaled": RefFilter(**{**base.__dict__, "scaled_depth_var": np.inf}),
        "abs": RefFilter(**{**base.__dict__, "abs_depth_var": np.inf}),
        "support": RefFilter(**{**base.__dict__, "min_near_support": 0}),
        "sparsify": RefFilter(**{**base.__dict__, "sparsify": 1}),
        "cut": RefFilter(**{**base.__dict__, "cut_first_keyframes": None}),
        "border": RefFilter(**{**base.__dict__, "skip_border": False}),
    }
    for rule, f in off.items():
        m = len(reference_loop(refs, f)[0])
        assert m > n, rule
        assert len(sw.backproject(make_set(11)[0], to_sw(f))) == m, rule


def test_keyframes_without_variance_skip_the_variance_rules() -> None:
    kfs, refs = make_set(4, n=3, variance=False)
    f = RefFilter(cut_first_keyframes=None)
    cloud = sw.backproject(kfs, to_sw(f))
    pts, _, _ = reference_loop(refs, f)
    assert_same_points(cloud.points, pts)
    interior = [np.sum(r.idepth[1:-1, 1:-1] > 0) for r in refs]
    assert len(cloud) == sum(interior)


def test_vectorised_reference_agrees() -> None:
    """The numpy peer of the benchmark computes the same point set."""
    kfs, refs = make_set(21, n=10)
    t = random_sim3(np.random.default_rng(2), 0.8)
    for f in [RefFilter(), RefFilter(sparsify=3, seed=5, min_near_support=5)]:
        cloud = sw.backproject(kfs, to_sw(f), transform=t)
        pts, ids = reference_vectorised(refs, f, t.matrix())
        assert len(cloud) == len(pts) > 0
        assert_same_points(cloud.points, pts)
        np.testing.assert_array_equal(cloud.keyframe_ids, ids)


def test_per_keyframe_transforms() -> None:
    kfs, refs = make_set(8, n=4)
    rng = np.random.default_rng(1)
    ts = [random_sim3(rng, s) for s in (1.0, 2.0, 0.5, 4.0)]
    f = RefFilter(cut_first_keyframes=None)
    cloud = sw.backproject(kfs, to_sw(f), transforms=ts)
    want = np.concatenate(
        [reference_loop([r], f, t.matrix())[0] for r, t in zip(refs, ts)]  # noqa: B905
    )
    assert_same_points(cloud.points, want)
    with pytest.raises(sw.InvalidInputError):
        sw.backproject(kfs, to_sw(f), transforms=ts[:2])
    with pytest.raises(sw.InvalidInputError):
        sw.backproject(kfs, to_sw(f), transform=ts[0], transforms=ts)


def test_filter_defaults_and_none() -> None:
    d = sw.PointFilter()
    assert (d.scaled_depth_var, d.abs_depth_var) == (pytest.approx(1e-3), pytest.approx(1e-1))
    assert (d.min_near_support, d.sparsify, d.cut_first_keyframes, d.skip_border) == (
        7,
        1,
        5,
        True,
    )
    n = sw.PointFilter.none()
    assert n.cut_first_keyframes is None and not n.skip_border and n != d
    kfs, _ = make_set(3, n=2)
    cloud = sw.backproject(kfs, sw.PointFilter.none())
    positive = sum(int(np.sum(k.idepth > 0)) for k in kfs)
    assert len(cloud) == positive
    # filter=None means the defaults: the first six keyframes are dropped.
    assert len(sw.backproject(kfs)) == 0


def test_grey_colour_and_shape_errors() -> None:
    cam = sw.PinholeCamera(10.0, 10.0, 2.0, 1.5, 4, 3)
    grey = np.arange(12, dtype=np.uint8).reshape(3, 4)
    kf = sw.Keyframe(0, 0.0, sw.Sim3(), cam, np.ones((3, 4)), None, grey)
    assert kf.color is not None
    np.testing.assert_array_equal(kf.color[..., 1], grey)
    cloud = sw.backproject([kf], sw.PointFilter.none())
    assert cloud.colors is not None
    np.testing.assert_array_equal(cloud.colors[:, 0], grey.ravel())
    with pytest.raises(sw.InvalidInputError, match="idepth"):
        sw.Keyframe(0, 0.0, sw.Sim3(), cam, np.ones((4, 3)))
    with pytest.raises(sw.InvalidInputError, match="color"):
        sw.Keyframe(0, 0.0, sw.Sim3(), cam, np.ones((3, 4)), None, grey.astype(np.float32))
    with pytest.raises(sw.InvalidInputError, match="sparsify"):
        sw.PointFilter(sparsify=0)
    with pytest.raises(sw.InvalidInputError):
        sw.PinholeCamera(-1.0, 1.0, 0.0, 0.0, 4, 3)
    with pytest.raises(sw.InvalidInputError, match="Keyframe"):
        sw.backproject([kf, "x"])  # type: ignore[list-item]


def test_point_cloud_transformed_and_read_only() -> None:
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(1000, 3)).astype(np.float32)
    cols = rng.integers(0, 256, size=(1000, 3), dtype=np.uint8)
    c = sw.PointCloud(pts, cols, np.arange(1000))
    t = random_sim3(rng, 3.5)
    out = c.transformed(t)
    m = t.matrix()
    want = pts.astype(np.float64) @ m[:3, :3].T + m[:3, 3]
    assert out.points.dtype == np.float32
    np.testing.assert_allclose(out.points, want, rtol=1e-6, atol=1e-5)
    assert out.colors is c.colors and out.keyframe_ids is c.keyframe_ids
    np.testing.assert_array_equal(out.points, t.apply(pts))
    with pytest.raises(ValueError):
        out.points[0, 0] = 1.0
    with pytest.raises(sw.InvalidInputError):
        sw.PointCloud(pts[:, :2])
    with pytest.raises(sw.InvalidInputError):
        sw.PointCloud(pts, cols[:10])
    assert sw.PointCloud(pts).keyframe_ids.tolist() == [-1] * 1000


def test_ply_round_trip_and_plyfile(tmp_path: Path) -> None:
    plyfile = pytest.importorskip("plyfile")
    kfs, _ = make_set(6, n=8)
    cloud = sw.backproject(kfs)
    assert cloud.colors is not None
    path = tmp_path / "cloud.ply"
    cloud.write_ply(path)
    data = plyfile.PlyData.read(str(path))
    assert not data.text and data.byte_order == "<"
    v = data["vertex"]
    assert v.count == len(cloud)
    assert [p.name for p in v.properties] == ["x", "y", "z", "red", "green", "blue"]
    assert [v.data.dtype[k].str for k in range(6)] == ["<f4"] * 3 + ["|u1"] * 3
    np.testing.assert_array_equal(np.stack([v["x"], v["y"], v["z"]], axis=1), cloud.points)
    np.testing.assert_array_equal(np.stack([v["red"], v["green"], v["blue"]], axis=1), cloud.colors)
    back = sw.read_ply(path)
    np.testing.assert_array_equal(back.points, cloud.points)
    np.testing.assert_array_equal(back.colors, cloud.colors)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cloud.ply"]

    # plyfile writes ascii and big-endian files with double coordinates; we read them.
    rows = np.array(
        [(1.5, -2.0, 3.25, 10, 20, 30), (0.0, 1e3, -7.0, 255, 0, 1)],
        dtype=[
            ("x", ">f8"),
            ("y", ">f8"),
            ("z", ">f8"),
            ("red", "u1"),
            ("green", "u1"),
            ("blue", "u1"),
        ],
    )
    for text in (True, False):
        p = tmp_path / f"peer_{text}.ply"
        el = plyfile.PlyElement.describe(rows, "vertex")
        plyfile.PlyData([el], text=text, byte_order=">").write(str(p))
        c = sw.read_ply(p)
        np.testing.assert_array_equal(c.points, [[1.5, -2.0, 3.25], [0.0, 1e3, -7.0]])
        assert c.colors is not None
        np.testing.assert_array_equal(c.colors, [[10, 20, 30], [255, 0, 1]])


def test_lsd_slam_viewer_pc_ply(tmp_path: Path) -> None:
    """The viewer's `pc.ply`: x y z intensity floats and one stray byte at the end."""
    pts = np.array([[0.1, 0.2, 0.3, 0.0], [1.0, 2.0, 3.0, 1.0], [-1, -2, -3, 0.2]], np.float32)
    header = (
        "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
        "property float y\nproperty float z\nproperty float intensity\nend_header\n"
    )
    p = tmp_path / "pc.ply"
    p.write_bytes(header.encode() + pts.astype("<f4").tobytes() + b"\xff")
    c = sw.read_ply(p)
    np.testing.assert_array_equal(c.points, pts[:, :3])
    assert c.colors is not None
    np.testing.assert_array_equal(c.colors[:, 0], [0, 255, 51])


def test_file_errors(tmp_path: Path) -> None:
    with pytest.raises(sw.FileError):
        sw.read_ply(tmp_path / "missing.ply")
    bad = tmp_path / "bad.ply"
    bad.write_bytes(
        b"ply\nformat binary_little_endian 1.0\nelement vertex 5\n"
        b"property float x\nproperty float y\nproperty float z\nend_header\n\0\0"
    )
    with pytest.raises(sw.FormatError, match="5 vertices"):
        sw.read_ply(bad)
    txt = tmp_path / "m.txt"
    txt.write_text("1 2 3\n4 five 6\n")
    with pytest.raises(sw.FormatError, match=":2:"):
        sw.read_xyz_text(txt)
    with pytest.raises(sw.FileError):
        sw.PointCloud(np.zeros((1, 3))).write_ply(tmp_path / "no" / "such" / "x.ply")


def test_orbslam_map_points_read() -> None:
    path = data_path("euroc_v101_orbslam2_map", "MapPoints.txt")
    c = sw.read_xyz_text(path)
    assert len(c) == 6300
    want = np.loadtxt(path, dtype=np.float64)
    np.testing.assert_allclose(c.points, want, rtol=1e-6)


def test_orbslam_map_points_in_the_vicon_frame(tmp_path: Path) -> None:
    """EuRoC V1_01: the 6300 ORB-SLAM2 map points, carried by the Sim(3) of the keyframe
    trajectory onto the ground truth, put the floor level (normal within 3 degrees of z)
    at z ~ 0, and the points between floor and ceiling; the PLY keeps them exactly."""
    folder = "euroc_v101_orbslam2_map"
    est = sw.Trajectory.read_tum(data_path(folder, "KeyFrameTrajectory_TUM_Format.txt"))
    gt = sw.Trajectory.read_tum(data_path(folder, "V1_01_easy_original.txt"))
    fit = sw.align_trajectories(est, gt)
    assert fit.transform.scale == pytest.approx(1.0081319980644732, abs=1e-6)
    cloud = sw.read_xyz_text(data_path(folder, "MapPoints.txt")).transformed(fit.transform)
    p = cloud.points.astype(np.float64)
    # Floor: a plane through the lowest 40 % of points, refitted on those within 5 cm.
    sel = p[p[:, 2] <= np.quantile(p[:, 2], 0.4)]
    for _ in range(6):
        c = sel.mean(axis=0)
        n = np.linalg.svd(sel - c)[2][2]
        n = n if n[2] > 0 else -n
        sel = p[np.abs((p - c) @ n) < 0.05]
    tilt = np.degrees(np.arccos(min(1.0, n[2])))
    assert tilt < 3.0
    assert abs(float(c @ n)) < 0.1
    assert len(sel) > 1500
    inside = (p[:, 2] > -0.3) & (p[:, 2] < 3.0)
    assert inside.mean() >= 0.99
    out = tmp_path / "world.ply"
    cloud.write_ply(out)
    np.testing.assert_array_equal(sw.read_ply(out).points, cloud.points)
