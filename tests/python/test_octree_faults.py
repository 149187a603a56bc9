"""OccupancyMap faults from issue 17, from Python: a ray whose f32 length underflows
(the tracer never returned), a tiny .bt whose one leaf is 2^45 voxels, 8 threads
inserting into one map, negative or huge integers."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest

import slam2world as s2w


def returns(f: Callable[[], Any], seconds: float = 60.0) -> Any:
    """Runs f on a daemon thread; fails when it has not returned in `seconds` (a hang
    guard far above the real run time, not a timing test)."""
    out: list[Any] = []
    errors: list[BaseException] = []

    def run() -> None:
        try:
            out.append(f())
        except BaseException as e:  # noqa: BLE001 - re-raised below
            errors.append(e)

    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(seconds)
    assert not t.is_alive(), f"did not return within {seconds} s"
    if errors:
        raise errors[0]
    return out[0]


@pytest.mark.parametrize("max_range", [None, 10.0])
def test_a_ray_of_1e30_metres_returns(max_range: float | None) -> None:
    m = s2w.OccupancyMap(0.1, max_range=max_range)
    free, occupied = returns(lambda: m.insert([[-1e-30, 1e-30, 0.0]], [0.0, 0.0, 0.0]))
    assert (free, occupied) == (1, 1)
    assert m.state([[-0.05, 0.05, 0.05], [0.05, 0.05, 0.05]]).tolist() == [1, 0]
    k = s2w.OccupancyMap(0.1, max_range=max_range)
    pts = np.array([[-1e-30, 1e-30, 0.0], [1e-40, 0.0, -1e-40], [0.0, 0.0, 0.0]])
    returns(lambda: k.insert_keyframes(pts, [1, 1, 2], {1: [0, 0, 0], 2: [1e-39, 0, 0]}))
    assert k.state([[-0.05, 0.05, 0.05]]).tolist() == [1]


def _one_leaf_bt(path: Path) -> None:
    # The root's child 0 an occupied leaf at depth 1 (2^15 voxels an edge).
    path.write_bytes(b"# Octomap OcTree binary file\nid OcTree\nsize 2\nres 0.1\ndata\n\x02\x00")


def test_a_tiny_bt_is_counted_not_expanded(tmp_path: Path) -> None:
    path = tmp_path / "one_leaf.bt"
    _one_leaf_bt(path)
    m = s2w.read_bt(path)
    assert m.count_occupied() == 2**45
    with pytest.raises(s2w.InvalidInputError, match=r"35184372088832 items exceed the limit"):
        returns(m.occupied_centers)
    assert m.free_centers().shape == (0, 3)
    centres, sizes = m.occupied_leaves()
    np.testing.assert_allclose(centres, [[-1638.4, -1638.4, -1638.4]])
    np.testing.assert_allclose(sizes, [3276.8])
    # The grid is bounded as well: 2^30 cells at 0.1 m, 8 x 8 at 409.6 m.
    with pytest.raises(s2w.InvalidInputError, match="1073741824"):
        m.grid(-1.0, -0.5)
    g = m.grid(-1.0, -0.5, resolution=409.6)
    assert (g.width, g.height) == (8, 8)
    assert bool(g.occupied().all())


def _scan(i: int) -> tuple[np.ndarray[Any, Any], list[float]]:
    """Scan i: points on a wall 10*i metres along x (disjoint voxels per scan)."""
    rng = np.random.default_rng(i)
    pts = rng.uniform(-1.0, 1.0, size=(3000, 3))
    pts[:, 0] = 2.0
    pts[:, 0] += 10.0 * i
    return pts, [10.0 * i, 0.0, 0.0]


def test_eight_threads_inserting_queue_for_the_map() -> None:
    shared = s2w.OccupancyMap(0.1)
    barrier = threading.Barrier(8)
    results: list[tuple[int, int]] = []
    errors: list[BaseException] = []

    def insert(i: int) -> None:
        pts, origin = _scan(i)
        barrier.wait()
        try:
            for _ in range(3):
                results.append(shared.insert(pts, origin))
                shared.state(pts[:10])
        except BaseException as e:  # noqa: BLE001 - asserted below
            errors.append(e)

    threads = [threading.Thread(target=insert, args=(i,)) for i in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    assert not any(t.is_alive() for t in threads)
    assert errors == []
    assert len(results) == 24
    sequential = s2w.OccupancyMap(0.1)
    for _ in range(3):
        for i in range(8):
            sequential.insert(*_scan(i))
    assert shared == sequential
    assert shared.num_nodes == sequential.num_nodes > 1000
    assert shared != s2w.OccupancyMap(0.1)


def test_integer_arguments_name_themselves() -> None:
    m = s2w.OccupancyMap(0.1)
    m.insert([[0.5, 0.0, 0.0]], [0.0, 0.0, 0.0])
    with pytest.raises(s2w.InvalidInputError, match="max_voxels.*-1"):
        m.occupied_centers(max_voxels=-1)
    with pytest.raises(s2w.InvalidInputError, match="max_voxels.*out of range"):
        m.free_centers(max_voxels=2**200)
    with pytest.raises(s2w.InvalidInputError, match="max_voxels.*int"):
        m.free_centers(max_voxels=1.5)  # type: ignore[arg-type]
    with pytest.raises(s2w.InvalidInputError, match="max_cells.*-5"):
        m.grid(0.0, 1.0, max_cells=-5)
    with pytest.raises(s2w.InvalidInputError, match="origins.*int32"):
        m.insert_keyframes([[1.0, 0.0, 0.0]], [1], {2**40: [0, 0, 0]})
    with pytest.raises(s2w.InvalidInputError, match="keyframe_ids"):
        m.insert_keyframes([[1.0, 0.0, 0.0]], [2**40], {1: [0, 0, 0]})
    assert m.occupied_centers(max_voxels=1).shape == (1, 3)
    with pytest.raises(s2w.InvalidInputError, match="1 items exceed the limit of 0"):
        m.occupied_centers(max_voxels=0)
