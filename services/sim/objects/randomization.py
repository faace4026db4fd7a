"""Per-episode randomization of object size, mass, friction and restitution.

The paper gives no object ranges (only table friction, U(0.2, 0.6), in its scene table);
the defaults are the authors' released training configuration for HAMnet:

- size: the object's bounding radius (largest distance from its centre) ~ U(0.05, 0.10) m
  (`min_scale`/`max_scale`, applied as radius / object radius);
- mass ~ U(0.1, 0.5) kg (`min_mass`/`max_mass`; their code then passes (max, max), so it
  trains at 0.5 kg: set `mass=(0.5, 0.5)` to reproduce that);
- friction ~ U(0.2, 1.0) and restitution ~ U(0.0, 0.2) (their scene's defaults);
- the robot's (hand's) friction ~ U(1.0, 1.5) (`min_hand_friction`/`max_hand_friction`,
  rss_train.yaml:106-107).

Inertia follows from mass and scaled shape at uniform density (`ObjectAsset.unit_inertia`).
MuJoCo has no restitution coefficient: `spec.restitution_solref` maps it onto `solref`.
MuJoCo combines the friction of two geoms by taking the larger one; PhysX, the authors'
engine, averages them (its default combine mode: their code never sets another, and
ham/src/ham/env/common.py:19-27 and 120-133 only set per-shape coefficients).
`max_rule_frictions` picks per-geom values whose maxima are those averages.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def _check_range(name: str, bounds: tuple[float, float], low: float, high: float = np.inf) -> None:
    if not low <= bounds[0] <= bounds[1] <= high:
        raise ValueError(f"{name} must satisfy {low} <= lo <= hi <= {high}, got {bounds}")


@dataclass(frozen=True)
class ObjectRandomization:
    """Ranges of the object's physical parameters, each drawn uniformly per episode."""

    radius: tuple[float, float] | None = (0.05, 0.10)
    """Bounding radius the object is scaled to, m (authors' code); None: use `scale`."""
    scale: tuple[float, float] = (1.0, 1.0)
    """Scale factor on the library size, used when `radius` is None."""
    mass: tuple[float, float] = (0.1, 0.5)
    """Object mass, kg."""
    friction: tuple[float, float] = (0.2, 1.0)
    """Sliding friction coefficient of the object's geoms."""
    restitution: tuple[float, float] = (0.0, 0.2)
    """Coefficient of restitution of the object's contacts."""
    hand_friction: tuple[float, float] = (1.0, 1.5)
    """Friction coefficient of the robot's geoms (the authors' hand, rss_train.yaml:106-107),
    averaged with the object's in a contact as PhysX does (`max_rule_frictions`)."""

    def __post_init__(self) -> None:
        if self.radius is not None:
            _check_range("radius", self.radius, 1e-3)
        _check_range("scale", self.scale, 1e-3)
        _check_range("mass", self.mass, 1e-3)
        _check_range("friction", self.friction, 0.0)
        _check_range("restitution", self.restitution, 0.0, 0.99)
        _check_range("hand_friction", self.hand_friction, 0.0)


@dataclass(frozen=True, eq=False)
class ObjectPhysics:
    """Sampled parameters, one row per environment."""

    scale: np.ndarray
    """(B,) uniform scale applied to the library object."""
    mass: np.ndarray
    """(B,) kg."""
    friction: np.ndarray
    """(B,) sliding friction coefficient."""
    restitution: np.ndarray
    """(B,) coefficient of restitution."""


def sample_physics(
    config: ObjectRandomization, rng: np.random.Generator, object_radius: np.ndarray
) -> ObjectPhysics:
    """Draw physical parameters for a batch of objects.

    Args:
        config: the ranges.
        rng: source of randomness.
        object_radius: (B,) bounding radius of each environment's library object, m.
    Returns:
        One row of parameters per environment.
    """
    object_radius = np.asarray(object_radius, dtype=np.float64)  # (B,)
    batch = object_radius.shape
    if config.radius is not None:
        scale = rng.uniform(*config.radius, size=batch) / object_radius  # (B,)
    else:
        scale = rng.uniform(*config.scale, size=batch)  # (B,)
    return ObjectPhysics(
        scale=scale,
        mass=rng.uniform(*config.mass, size=batch),
        friction=rng.uniform(*config.friction, size=batch),
        restitution=rng.uniform(*config.restitution, size=batch),
    )


def max_rule_frictions(
    hand: np.ndarray, obj: np.ndarray, scene: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-geom sliding frictions under MuJoCo's max rule that reproduce PhysX's averages.

    With the object's geoms at 0, the robot's at (h + o) / 2 and the scene's at (o + s) / 2,
    MuJoCo's max(a, b) gives robot-object contacts (h + o) / 2 and object-scene contacts
    (o + s) / 2: the authors' effective coefficients. Robot-scene contacts get
    max((h + o) / 2, (o + s) / 2) instead of (h + s) / 2 (about (o - s) / 2 more): the arm
    only brushes the scene.

    Args:
        hand, obj, scene: (K,) sampled coefficients of the robot, the object and the scene.
    Returns:
        (K,) each: the robot's, the object's and the scene's geom friction.
    """
    return (hand + obj) / 2, np.zeros_like(obj), (obj + scene) / 2
