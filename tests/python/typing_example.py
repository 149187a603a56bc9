"""A typed usage example: mypy --strict checks it (make lint) and pytest runs it."""

from __future__ import annotations

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
