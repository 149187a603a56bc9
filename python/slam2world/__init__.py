"""slam2world: the map of a monocular SLAM system, made metric and gravity-aligned.

Conventions: metres and seconds; ``T_a_b`` maps frame-b coordinates into frame a
(``p_a = s R p_b + t``); quaternions are ``(x, y, z, w)``.
"""

from slam2world._slam2world import (
    DegenerateError,
    FileError,
    FormatError,
    InvalidInputError,
    OccupancyMap,
    Sim3,
    Slam2WorldError,
    __version__,
    read_bt,
)

__all__ = [
    "DegenerateError",
    "FileError",
    "FormatError",
    "InvalidInputError",
    "OccupancyMap",
    "Sim3",
    "Slam2WorldError",
    "__version__",
    "read_bt",
]
