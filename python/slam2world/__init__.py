"""slam2world: the map of a monocular SLAM system, made metric and gravity-aligned.

Conventions: metres and seconds; ``T_a_b`` maps frame-b coordinates into frame a
(``p_a = s R p_b + t``); quaternions are ``(x, y, z, w)``.
"""

from slam2world._slam2world import (
    Alignment,
    DegenerateError,
    FileError,
    FormatError,
    InvalidInputError,
    Keyframe,
    PinholeCamera,
    PointCloud,
    PointFilter,
    Sim3,
    Slam2WorldError,
    Trajectory,
    TrajectoryAlignment,
    __version__,
    align,
    align_trajectories,
    associate,
    backproject,
    read_ply,
    read_xyz_text,
    scale_factors,
)

__all__ = [
    "Alignment",
    "DegenerateError",
    "FileError",
    "FormatError",
    "InvalidInputError",
    "Keyframe",
    "PinholeCamera",
    "PointCloud",
    "PointFilter",
    "Sim3",
    "Slam2WorldError",
    "Trajectory",
    "TrajectoryAlignment",
    "__version__",
    "align",
    "align_trajectories",
    "associate",
    "scale_factors",
    "backproject",
    "read_ply",
    "read_xyz_text",
]
