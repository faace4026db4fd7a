"""Where objects may stand in a procedural scene: the surface profile along each table axis
and the flat cells of the 5 x 5 grid the two axes' segments make.

Consumes the plate elevations and segment edges of `scene_parameters.Interior` (moved to
the world frame by `scene.sample_scenes`); produces the profile and region arrays of a
`SceneBatch`, which `placement` draws object poses from. The surface elevation is
max(profile_x(x), profile_y(y)) because a plate strip spans the whole table across the
other axis. Shapes: B environments, R = 25 regions.
"""

from __future__ import annotations

import numpy as np

from hamnet.sim.scene_parameters import interleave

NUM_REGIONS = 25
"""Regions: the 5 x 5 grid of segments (plate, ramp, plate, ramp, plate) of the two axes."""


def profile(height: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lowest and highest elevation (B, 2, 5) of each segment, from plate heights (B, 2, 3)."""
    ramp_low = np.minimum(height[..., :-1], height[..., 1:])  # (B, 2, 2)
    ramp_high = np.maximum(height[..., :-1], height[..., 1:])
    return interleave(height, ramp_low), interleave(height, ramp_high)


def regions(
    edges: np.ndarray, low: np.ndarray, high: np.ndarray, table_top: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The 5 x 5 grid cells of the two axes' segments and which of them are flat.

    A cell's surface is max(profile_x, profile_y), so it spans
    [max(low_x, low_y), max(high_x, high_y)]: it is flat where the two ends agree, e.g. a
    plate crossing a plate, or a plate standing above a crossing ramp.

    Args:
        edges: (B, 2, 6) world coordinate of the segment boundaries along x and y, m.
        low, high: (B, 2, 5) lowest and highest elevation of each segment (`profile`), m.
        table_top: (B,) world z of the table top, m.
    Returns:
        lo, hi (B, R, 2) the cells' xy corners, m; z (B, R) world z of their top, m; flat
        (B, R) bool, a horizontal face with some area.
    """
    num_envs = len(table_top)
    lo = np.stack(np.broadcast_arrays(edges[:, 0, :-1, None], edges[:, 1, None, :-1]), axis=-1)
    hi = np.stack(np.broadcast_arrays(edges[:, 0, 1:, None], edges[:, 1, None, 1:]), axis=-1)
    cell_low = np.maximum(low[:, 0, :, None], low[:, 1, None, :])  # (B, 5, 5)
    cell_high = np.maximum(high[:, 0, :, None], high[:, 1, None, :])  # (B, 5, 5)
    area = np.prod(hi - lo, axis=-1)  # (B, 5, 5), m^2
    flat = (cell_low == cell_high) & (area > 0)
    z = table_top[:, None, None] + cell_high
    return (
        lo.reshape(num_envs, NUM_REGIONS, 2),
        hi.reshape(num_envs, NUM_REGIONS, 2),
        z.reshape(num_envs, NUM_REGIONS),
        flat.reshape(num_envs, NUM_REGIONS),
    )
