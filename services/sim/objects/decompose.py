"""Convex decomposition of a closed mesh, so MuJoCo collides with its real shape.

MuJoCo replaces every mesh geom by its convex hull, which would fill a mug's handle or an
L's corner. A convex mesh is kept as one part; any other goes through CoACD
(collision-aware approximate convex decomposition, the tool the authors used on
DexGraspNet), and each returned piece is re-hulled so it is exactly convex and outward-facing.
"""

from __future__ import annotations

import coacd
import numpy as np

from hamnet.sim.objects.config import DecompositionConfig
from hamnet.sim.objects.mesh import Mesh, convex_hull, is_convex


def decompose(mesh: Mesh, config: DecompositionConfig) -> tuple[Mesh, ...]:
    """Convex parts whose union approximates the solid bounded by `mesh`.

    Args:
        mesh: closed surface, m.
        config: CoACD settings.
    Returns:
        One part (the hull) for a convex mesh, else at most `config.max_parts` CoACD parts.
    """
    if is_convex(mesh):
        return (convex_hull(mesh.vertices),)
    coacd.set_log_level("error")
    pieces = coacd.run_coacd(
        coacd.Mesh(mesh.vertices, mesh.faces),
        threshold=config.threshold,
        max_convex_hull=config.max_parts,
        max_ch_vertex=config.max_part_vertices,
        seed=config.seed,
    )
    return tuple(convex_hull(np.asarray(vertices, dtype=np.float64)) for vertices, _ in pieces)
