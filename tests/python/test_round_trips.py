"""Every writer's output for 0, 1 and 2 elements, read back by the project's reader and by an
independent one: points (PLY by plyfile, LAS by laspy, PCD by pypcd4), poses (TUM by evo) and
occupancy leaves (.bt and .ot by OctoMap)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import slam2world as sw

SIZES = (0, 1, 2)


def points(n: int) -> np.ndarray:
    return np.array([[1.5, -2.0, 3.25], [0.0, 1e3, -7.0]], dtype=np.float32)[:n].reshape(n, 3)


def colors(n: int) -> np.ndarray:
    return np.array([[10, 20, 30], [255, 0, 1]], dtype=np.uint8)[:n].reshape(n, 3)


@pytest.mark.parametrize("n", SIZES)
def test_ply_of_n_points(tmp_path: Path, n: int) -> None:
    plyfile = pytest.importorskip("plyfile")
    path = tmp_path / "cloud.ply"
    sw.PointCloud(points(n), colors(n)).write_ply(path)
    back = sw.read_ply(path)
    assert len(back) == n
    np.testing.assert_array_equal(back.points, points(n))
    assert back.colors is not None
    np.testing.assert_array_equal(back.colors, colors(n))
    v = plyfile.PlyData.read(str(path))["vertex"]
    assert v.count == n
    np.testing.assert_array_equal(
        np.stack([v["x"], v["y"], v["z"]], axis=1).reshape(n, 3), points(n)
    )


@pytest.mark.parametrize("n", SIZES)
def test_las_of_n_points(tmp_path: Path, n: int) -> None:
    laspy = pytest.importorskip("laspy")
    path = tmp_path / "cloud.las"
    epsg = sw.PointCloud(points(n)).write_las(path, origin=(48.1, 11.5, 520.0))
    assert epsg == 32632  # WGS 84 / UTM zone 32N
    las = laspy.read(path)
    assert len(las.points) == n
    got = np.stack([las.x, las.y, las.z], axis=1).reshape(n, 3)
    if n:
        # UTM of the origin's zone: metres east and north near the origin; the tangent plane
        # rises above the ellipsoid by d^2 / 2R away from the origin.
        assert 600e3 < got[0, 0] < 800e3 and 5.2e6 < got[0, 1] < 5.4e6
        p = points(n).astype(np.float64)
        rise = (p[:, 0] ** 2 + p[:, 1] ** 2) / (2 * 6.371e6)
        np.testing.assert_allclose(got[:, 2] - 520.0, p[:, 2] + rise, atol=2e-3)
    if n == 2:
        # The grid's scale is within 1e-3 of one near the origin.
        want = np.linalg.norm(points(n)[1, :2] - points(n)[0, :2])
        assert np.linalg.norm(got[1, :2] - got[0, :2]) == pytest.approx(want, rel=1e-3)


@pytest.mark.parametrize("n", SIZES)
def test_pcd_of_n_points(tmp_path: Path, n: int) -> None:
    pypcd4 = pytest.importorskip("pypcd4")
    path = tmp_path / "cloud.pcd"
    sw.PointCloud(points(n)).write_pcd(path)
    pc = pypcd4.PointCloud.from_path(path)
    assert pc.points == n
    np.testing.assert_array_equal(pc.numpy(("x", "y", "z")).reshape(n, 3), points(n))


def poses(n: int) -> sw.Trajectory:
    t = np.array([0.5, 1.25])[:n]
    p = np.array([[1.0, 2.0, 3.0], [-4.0, 5.5, 0.0]])[:n].reshape(n, 3)
    q = np.array([[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, np.sqrt(0.5), np.sqrt(0.5)]])[:n].reshape(n, 4)
    return sw.Trajectory(t, p, q)


@pytest.mark.parametrize("n", (1, 2))
def test_tum_of_n_poses(tmp_path: Path, n: int) -> None:
    file_interface = pytest.importorskip("evo.tools.file_interface")
    path = tmp_path / "poses.txt"
    poses(n).write_tum(path)
    back = sw.Trajectory.read_tum(path)
    assert len(back) == n
    np.testing.assert_array_equal(back.timestamps, poses(n).timestamps)
    np.testing.assert_array_equal(back.positions, poses(n).positions)
    traj = file_interface.read_tum_trajectory_file(str(path))
    np.testing.assert_array_equal(traj.timestamps, poses(n).timestamps)
    np.testing.assert_array_equal(traj.positions_xyz, poses(n).positions)


def test_tum_of_no_poses_is_not_written(tmp_path: Path) -> None:
    # Nothing in a TUM file declares it empty: evo and read_tum both refuse one without rows,
    # so the writer refuses to make one and leaves nothing behind.
    file_interface = pytest.importorskip("evo.tools.file_interface")
    empty = tmp_path / "empty.txt"
    empty.write_text("# timestamp tx ty tz qx qy qz qw\n")
    with pytest.raises(sw.FormatError, match="no poses"):
        sw.Trajectory.read_tum(empty)
    with pytest.raises(file_interface.FileInterfaceException):
        file_interface.read_tum_trajectory_file(str(empty))
    with pytest.raises(sw.InvalidInputError, match="no poses to write"):
        poses(0).write_tum(tmp_path / "poses.txt")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty.txt"]


def leaves(n: int) -> sw.OccupancyMap:
    """A map of n leaves: none, one occupied voxel, a free voxel beside an occupied one."""
    m = sw.OccupancyMap(0.1)
    if n == 1:
        m.insert([[0.05, 0.05, 0.05]], [0.05, 0.05, 0.05])
    elif n == 2:
        m.insert([[0.15, 0.05, 0.05]], [0.05, 0.05, 0.05])
    assert m.num_leaf_nodes == n
    return m


@pytest.mark.parametrize("n", SIZES)
def test_octree_of_n_leaves(tmp_path: Path, n: int) -> None:
    octomap = pytest.importorskip("octomap")
    ours = leaves(n)
    bt = tmp_path / "map.bt"
    ours.write_bt(bt)
    back = sw.read_bt(bt)
    assert back.num_leaf_nodes == n
    np.testing.assert_array_equal(back.occupied_centers(), ours.occupied_centers())
    np.testing.assert_array_equal(back.free_centers(), ours.free_centers())
    ot = tmp_path / "map.ot"
    ours.write_ot(ot)
    for tree in (octomap.OcTree(str(bt).encode()), octomap.OcTree.read(str(ot).encode())):
        assert tree.getNumLeafNodes() == n
        occupied = [tree.isNodeOccupied(leaf) for leaf in tree.begin_leafs()] if n else []
        assert sorted(occupied) == [False] * (n - 1) + [True] * min(n, 1)
