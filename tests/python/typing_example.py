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
