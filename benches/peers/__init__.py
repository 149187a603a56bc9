"""Rows of ``benches/compare.py``, one module per area.

Each module registers its rows with :func:`benches.peers.registry.register`;
``compare.py`` imports them all and runs them in one process.
"""

AREAS = ("align", "transform", "backproject", "octree", "mcap", "rosbag")
