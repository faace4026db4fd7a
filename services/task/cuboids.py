"""The cuboid slots of a procedural scene: every scene has the same 16, in this order, so a
MuJoCo model keeps one box geom per slot, a SceneDescription carries (B, 16) arrays, and
perception finds the table in slot `TABLE`.
"""

from __future__ import annotations

CUBOID_NAMES = (
    "table",
    "plate_x0",
    "plate_x1",
    "plate_x2",
    "ramp_x0",
    "ramp_x1",
    "plate_y0",
    "plate_y1",
    "plate_y2",
    "ramp_y0",
    "ramp_y1",
    "wall_front",
    "wall_back",
    "wall_right",
    "wall_left",
    "ceiling",
)
"""Slot names: planar plates run near to far (x) and right to left (y); the front wall faces
the robot (-x), the right wall is at -y."""
NUM_CUBOIDS = len(CUBOID_NAMES)
"""N: cuboid slots per scene."""
TABLE = 0
"""The table's slot."""
