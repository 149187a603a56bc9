"""OccupancyMap against OctoMap (octomap-python): files, classification, insertion."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import slam2world
from slam2world import InvalidInputError, OccupancyMap

octomap = pytest.importorskip("octomap")

# Cubes (centre, half edge) on the plane z = 0; the first one's faces lie mid-voxel.
CUBES = [((2.0, 0.0, 0.45), 0.45), ((-2.0, 2.0, 0.75), 0.75), ((0.0, -3.0, 0.4), 0.4)]


def cast_scene(origin: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """First hits of rays with the plane z = 0 and the cubes (slab test)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t_plane = -origin[2] / dirs[:, 2]
        best = np.where(t_plane > 0, t_plane, np.inf)
        for centre, h in CUBES:
            c = np.asarray(centre)
            t1, t2 = (c - h - origin) / dirs, (c + h - origin) / dirs
            near = np.nanmax(np.minimum(t1, t2), axis=1)
            far = np.nanmin(np.maximum(t1, t2), axis=1)
            hit = (near <= far) & (near > 0) & (near < best)
            best = np.where(hit, near, best)
    keep = np.isfinite(best) & (best < 40.0)
    return origin + dirs[keep] * best[keep, None]


def camera_scan(origin: np.ndarray, target: tuple[float, float, float], n: int) -> np.ndarray:
    fwd = np.asarray(target) - origin
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    a, b = np.meshgrid((np.arange(n) + 0.5) / n * 2 - 1, (np.arange(n) + 0.5) / n * 2 - 1)
    d = fwd + a.reshape(-1, 1) * right + b.reshape(-1, 1) * up
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return cast_scene(origin, d)


def scene_scans(n_cams: int = 6, n: int = 100) -> list[tuple[np.ndarray, np.ndarray]]:
    out = []
    for k in range(n_cams):
        a = 2 * np.pi * k / n_cams
        origin = np.array([5.0 * np.cos(a), 5.0 * np.sin(a), 1.5])
        out.append((origin, camera_scan(origin, (0.0, 0.0, 0.3), n)))
    return out


def octomap_leaves(tree: octomap.OcTree) -> dict[tuple[float, float, float, float], bool]:
    """Every leaf of an OctoMap tree: (centre, size) -> occupied."""
    out = {}
    for leaf in tree.begin_leafs():
        c = leaf.getCoordinate()
        key = (round(c[0], 4), round(c[1], 4), round(c[2], 4), round(leaf.getSize(), 4))
        out[key] = bool(tree.isNodeOccupied(leaf))
    return out


def our_leaves(m: OccupancyMap) -> dict[tuple[float, float, float, float], bool]:
    out = {}
    for occupied, (centres, sizes) in ((True, m.occupied_leaves()), (False, m.free_leaves())):
        for c, s in zip(centres, sizes):
            out[(round(c[0], 4), round(c[1], 4), round(c[2], 4), round(s, 4))] = occupied
    return out


@pytest.fixture(scope="module")
def maps() -> tuple[OccupancyMap, octomap.OcTree]:
    """The same scans (10 m max range) in both libraries."""
    ours = OccupancyMap(0.1, max_range=10.0)
    ref = octomap.OcTree(0.1)
    for origin, pts in scene_scans():
        ours.insert(pts, origin)
        ref.insertPointCloud(pts, origin, maxrange=10.0)
    return ours, ref


def test_octomap_reads_our_bt_and_classifies_every_voxel_as_we_do(
    maps: tuple[OccupancyMap, octomap.OcTree], tmp_path: Path
) -> None:
    ours, _ = maps
    path = tmp_path / "map.bt"
    ours.write_bt(path)
    tree = octomap.OcTree(0.1)
    assert tree.readBinary(str(path).encode())
    theirs = octomap_leaves(tree)
    assert len(theirs) > 1000
    # Each of OctoMap's leaves (pruned ones cover 2^k voxels) has our state at its centre.
    centres = np.array([k[:3] for k in theirs])
    expected = np.array([1 if v else 0 for v in theirs.values()], dtype=np.int8)
    np.testing.assert_array_equal(ours.state(centres), expected)
    # And the voxel counts per state agree, so no voxel is known to only one side.
    n_occ = sum(round(k[3] / 0.1) ** 3 for k, v in theirs.items() if v)
    n_free = sum(round(k[3] / 0.1) ** 3 for k, v in theirs.items() if not v)
    assert n_occ == len(ours.occupied_centers())
    assert n_free == len(ours.free_centers())


@pytest.mark.slow
def test_octomap_reads_our_ot_with_the_same_tree(
    maps: tuple[OccupancyMap, octomap.OcTree], tmp_path: Path
) -> None:
    ours, _ = maps
    path = tmp_path / "map.ot"
    ours.write_ot(path)
    tree = octomap.OcTree.read(str(path).encode())
    assert tree.size() == ours.num_nodes
    assert tree.getNumLeafNodes() == ours.num_leaf_nodes
    theirs = octomap_leaves(tree)
    assert theirs == our_leaves(ours)
    # The log-odds survive: OctoMap's probability at a few leaves equals ours.
    centres = np.array([k[:3] for k in list(theirs)[:: max(1, len(theirs) // 200)]])
    probs = [tree.search(c).getOccupancy() for c in centres]
    np.testing.assert_allclose(ours.occupancy(centres), probs, rtol=1e-6)


@pytest.mark.slow
def test_same_scans_through_octomap_insert_point_cloud_agree(
    maps: tuple[OccupancyMap, octomap.OcTree], tmp_path: Path
) -> None:
    ours, ref = maps
    theirs, mine = octomap_leaves(ref), our_leaves(ours)
    # Voxel-weighted agreement over the union of both maps' leaves.
    voxels = {k: round(k[3] / 0.1) ** 3 for k in set(theirs) | set(mine)}
    agree = sum(n for k, n in voxels.items() if theirs.get(k) == mine.get(k))
    total = sum(voxels.values())
    disagreeing = [k for k in voxels if theirs.get(k) != mine.get(k)]
    assert agree / total >= 0.999, f"{total - agree} of {total} voxels differ: {disagreeing[:10]}"
    # In fact the trees are the same node for node: the .ot files are equal bytes.
    ref.write(str(tmp_path / "ref.ot").encode())
    ours.write_ot(tmp_path / "ours.ot")
    assert (tmp_path / "ref.ot").read_bytes() == (tmp_path / "ours.ot").read_bytes()
    assert ref.writeBinary(str(tmp_path / "ref.bt").encode())
    ours.write_bt(tmp_path / "ours.bt")
    assert (tmp_path / "ref.bt").read_bytes() == (tmp_path / "ours.bt").read_bytes()


def test_bt_round_trip_in_python(maps: tuple[OccupancyMap, octomap.OcTree], tmp_path: Path) -> None:
    ours, _ = maps
    ours.write_bt(tmp_path / "a.bt")
    back = slam2world.read_bt(tmp_path / "a.bt")
    assert back.resolution == pytest.approx(0.1)
    # Same voxels per state; the order differs where the file's tree is pruned further.
    for got, want in (
        (back.occupied_centers(), ours.occupied_centers()),
        (back.free_centers(), ours.free_centers()),
    ):
        np.testing.assert_array_equal(got[np.lexsort(got.T)], want[np.lexsort(want.T)])
    also = OccupancyMap.read_bt(str(tmp_path / "a.bt"))
    assert also.num_nodes == back.num_nodes


def test_cube_scene_occupied_free_and_planner_queries(
    maps: tuple[OccupancyMap, octomap.OcTree],
) -> None:
    ours, _ = maps
    probe = np.array(
        [
            [1.55, 0.05, 0.55],  # face of cube 0 seen from the cameras
            [2.45, 0.05, 0.55],  # opposite face
            [1.05, 0.05, 0.55],  # in front of it
            [3.05, 0.05, 0.55],
            [2.05, 0.05, 0.45],  # inside: never observed
        ]
    )
    np.testing.assert_array_equal(ours.state(probe), [1, 1, 0, 0, -1])
    occ = ours.occupancy(probe)
    assert occ[0] > 0.5 and occ[2] < 0.5 and np.isnan(occ[4])
    assert not ours.segment_is_free([1.0, 0.0, 0.6], [3.0, 0.0, 0.6])
    assert ours.segment_is_free([1.0, 1.2, 0.6], [3.0, 1.2, 0.6])
    assert not ours.segment_is_free([1.0, 1.2, 0.6], [3.0, 1.2, 0.6], radius=0.8)
    assert ours.collides_sphere([1.3, 0.0, 0.6], 0.3)
    assert not ours.collides_sphere([1.0, 0.0, 0.6], 0.3)
    assert ours.collides_box([2.0, 0.8, 0.6], [0.2, 0.4, 0.2])
    assert not ours.collides_box([2.0, 1.2, 0.6], [0.2, 0.2, 0.2])
    hit = ours.cast_ray([0.05, 0.05, 0.55], [1.0, 0.0, 0.0], max_range=10.0)
    assert hit is not None
    np.testing.assert_allclose(hit, [1.55, 0.05, 0.55], atol=1e-9)
    assert ours.cast_ray([0.05, 1.25, 0.55], [1.0, 0.0, 0.0], 3.0, ignore_unknown=True) is None


def test_keyframe_insertion_equals_scan_by_scan() -> None:
    scans = scene_scans(3, 40)
    a = OccupancyMap(0.1)
    for origin, pts in scans:
        a.insert(pts, origin)
    b = OccupancyMap(0.1)
    points = np.concatenate([p for _, p in scans])
    ids = np.concatenate([np.full(len(p), k) for k, (_, p) in enumerate(scans)])  # int64
    b.insert_keyframes(points, ids, {k: o for k, (o, _) in enumerate(scans)})
    np.testing.assert_array_equal(a.occupied_centers(), b.occupied_centers())
    assert a.num_nodes == b.num_nodes


def test_float32_and_float64_points_give_the_same_map() -> None:
    origin, pts = scene_scans(1, 40)[0]
    a, b = OccupancyMap(0.1), OccupancyMap(0.1)
    free, occupied = a.insert(pts.astype(np.float32), origin)
    assert free > 0 and occupied > 0
    b.insert(pts, origin)
    assert a.num_nodes == b.num_nodes and a.num_leaf_nodes == b.num_leaf_nodes
    assert a.memory_bytes > 0
    c = OccupancyMap(0.1)
    c.insert(np.asfortranarray(pts.astype(np.float32)), origin)  # read by rows, not columns
    np.testing.assert_array_equal(c.occupied_centers(), a.occupied_centers())


def test_bad_input_is_rejected() -> None:
    m = OccupancyMap(0.1)
    with pytest.raises(InvalidInputError):
        m.insert(np.zeros((4, 2)), [0, 0, 0])
    with pytest.raises(InvalidInputError):
        m.insert(np.array([[0.0, np.nan, 1.0]]), [0, 0, 0])
    with pytest.raises(InvalidInputError):
        m.insert(np.zeros((4, 3)), [0, 0])
    with pytest.raises(InvalidInputError):
        OccupancyMap(-0.1)
    with pytest.raises(InvalidInputError):
        OccupancyMap(0.1, prob_hit=1.5)
    with pytest.raises(InvalidInputError):
        m.collides_sphere([0, 0, 0], 0.0)
    with pytest.raises(InvalidInputError):
        m.cast_ray([0, 0, 0], [0, 0, 0])
    with pytest.raises(slam2world.FileError):
        slam2world.read_bt("/nonexistent/dir/map.bt")


def test_unreadable_bt_is_a_format_error(tmp_path: Path) -> None:
    p = tmp_path / "bad.bt"
    p.write_bytes(b"# Octomap OcTree binary file\nid OcTree\nsize 9\nres 0.1\ndata\n\x03")
    with pytest.raises(slam2world.FormatError):
        slam2world.read_bt(p)
