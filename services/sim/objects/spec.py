"""Adding objects to a `mujoco.MjSpec`: a free body, one collision geom per convex part.

MuJoCo collides a mesh geom through its convex hull, so a non-convex object is given as its
convex parts; the watertight surface becomes an optional visual geom that never collides.
The body's inertia is set explicitly from the exact surface (uniform density), because
overlapping parts would count their shared volume twice. Mesh assets are named after the
object and added once, so many bodies of one object share them.
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from hamnet.sim.objects.asset import ObjectAsset
from hamnet.sim.objects.mesh import Mesh

COLLISION_GROUP = 3
"""Geom group of the convex parts (hidden in the viewer by default)."""
VISUAL_GROUP = 1
"""Geom group of the visual surface."""
DEFAULT_FRICTION = (0.7, 0.005, 0.0001)
"""Sliding, torsional, rolling friction of an object geom (MuJoCo's defaults but sliding)."""


def restitution_solref(restitution: np.ndarray, timeconst: float = 0.02) -> np.ndarray:
    """MuJoCo `solref` (timeconst, dampratio) giving a coefficient of restitution.

    A contact behaves as a damped spring; a half oscillation with damping ratio zeta
    rebounds with e = exp(-pi zeta / sqrt(1 - zeta^2)), so zeta = -ln e / sqrt(pi^2 + ln^2 e).
    e = 0 gives zeta = 1 (MuJoCo's default, no bounce).

    Args:
        restitution: (B,) coefficients in [0, 1).
        timeconst: contact time constant, s (MuJoCo keeps it >= 2 timesteps).
    Returns:
        (B, 2) solref rows.
    """
    e = np.clip(np.asarray(restitution, dtype=np.float64), 1e-9, 1.0 - 1e-9)  # (B,)
    log_e = np.log(e)
    zeta = np.where(e <= 1e-9, 1.0, -log_e / np.sqrt(np.pi**2 + log_e**2))  # (B,)
    return np.stack([np.full_like(zeta, timeconst), zeta], axis=-1)


def full_inertia(inertia: np.ndarray) -> list[float]:
    """A (3, 3) inertia tensor as MuJoCo's `fullinertia` (ixx, iyy, izz, ixy, ixz, iyz)."""
    return [float(inertia[i, j]) for i, j in ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))]


def _mesh_asset(spec: mujoco.MjSpec, name: str, mesh: Mesh) -> str:
    if spec.mesh(name) is None:
        spec.add_mesh(name=name, uservert=mesh.vertices.ravel(), userface=mesh.faces.ravel())
    return name


def add_convex_body(
    spec: mujoco.MjSpec,
    name: str,
    parts: Sequence[Mesh],
    unit_inertia: np.ndarray,
    mass: float,
    *,
    mesh_prefix: str,
    visual: Mesh | None = None,
    friction: Sequence[float] = DEFAULT_FRICTION,
    solref: Sequence[float] = (0.02, 1.0),
    pos: Sequence[float] = (0.0, 0.0, 0.0),
    quat: Sequence[float] = (1.0, 0.0, 0.0, 0.0),
    contype: int = 1,
    conaffinity: int = 1,
) -> mujoco.MjsBody:
    """Add a free body made of convex parts, its origin at the centre of mass.

    Args:
        spec: the model being built.
        name: body name (the free joint is `name`/free).
        parts: convex pieces in the body frame, m.
        unit_inertia: (3, 3) inertia per kg about the origin, m^2.
        mass: kg.
        mesh_prefix: mesh assets are `mesh_prefix`/part<j> and `mesh_prefix`/visual; bodies
            with the same prefix share them.
        visual: surface for rendering (never collides), or None for none.
        friction, solref: contact parameters of every part.
        pos, quat: initial pose in the world (wxyz).
        contype, conaffinity: MuJoCo collision bitmasks of the parts.
    Returns:
        The new body.
    """
    body = spec.worldbody.add_body(name=name, pos=list(pos), quat=list(quat))
    body.add_freejoint(name=f"{name}/free")
    inertia = mass * unit_inertia  # (3, 3), kg m^2
    body.explicitinertial = True
    body.mass = mass
    body.ipos = [0.0, 0.0, 0.0]
    body.fullinertia = full_inertia(inertia)
    for j, part in enumerate(parts):
        body.add_geom(
            name=f"{name}/part{j}",
            type=mujoco.mjtGeom.mjGEOM_MESH,
            meshname=_mesh_asset(spec, f"{mesh_prefix}/part{j}", part),
            friction=list(friction),
            solref=list(solref),
            contype=contype,
            conaffinity=conaffinity,
            group=COLLISION_GROUP,
        )
    if visual is not None:
        body.add_geom(
            name=f"{name}/visual",
            type=mujoco.mjtGeom.mjGEOM_MESH,
            meshname=_mesh_asset(spec, f"{mesh_prefix}/visual", visual),
            contype=0,
            conaffinity=0,
            density=0.0,
            group=VISUAL_GROUP,
        )
    return body


def add_object(
    spec: mujoco.MjSpec,
    asset: ObjectAsset,
    name: str,
    *,
    scale: float = 1.0,
    mass: float = 0.3,
    friction: float = DEFAULT_FRICTION[0],
    restitution: float = 0.0,
    timeconst: float = 0.02,
    pos: Sequence[float] = (0.0, 0.0, 0.0),
    quat: Sequence[float] = (1.0, 0.0, 0.0, 0.0),
    visual: bool = True,
) -> mujoco.MjsBody:
    """Add a library object as a free body.

    Args:
        spec: the model being built.
        asset: the object.
        name: body name, unique in the model.
        scale: uniform scale of the geometry (per-episode size randomization).
        mass: kg; the inertia follows from the scaled shape at uniform density.
        friction: sliding friction of the object's geoms.
        restitution: coefficient of restitution, mapped onto `solref` (see `restitution_solref`).
        timeconst: contact time constant, s.
        pos, quat: initial pose (wxyz); e.g. a stable orientation at its resting height.
        visual: also add the surface as a non-colliding visual geom.
    Returns:
        The new body (its free joint is `name`/free).
    """
    shaped = asset.scaled(scale)
    solref = restitution_solref(np.array([restitution]), timeconst)[0]
    return add_convex_body(
        spec,
        name,
        shaped.parts,
        shaped.unit_inertia,
        mass,
        mesh_prefix=f"{asset.name}@{scale:.6g}",
        visual=shaped.mesh if visual else None,
        friction=(friction, *DEFAULT_FRICTION[1:]),
        solref=solref,
        pos=pos,
        quat=quat,
    )
