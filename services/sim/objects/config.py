"""Configuration of the object library: shape sizes, convex decomposition, stable-pose search.

One frozen `ObjectLibraryConfig` gathers the parts; every default runs on a CPU laptop. The
per-episode physics randomization has its own config, `ObjectRandomization`, in
`randomization.py`, because the sim samples it at every reset while this one is read once
when the library is built.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

SHAPE_KINDS = ("box", "cylinder", "superellipsoid", "polytope", "l_shape", "t_shape", "mug")
"""Every procedural shape kind, in the order a procedural set cycles through them."""


@dataclass(frozen=True)
class ShapeConfig:
    """Sizes of procedural shapes and of imported meshes."""

    extent: tuple[float, float] = (0.04, 0.20)
    """Range of every side of an object's bounding box, m. 4 cm is about the thinnest
    object a paddle still pushes reliably; 20 cm matches the authors' largest bounding
    radius (0.1 m) and stays well inside the FR3's reach around a plate."""
    kinds: tuple[str, ...] = SHAPE_KINDS
    """Shape kinds a procedural set cycles through (object i gets kinds[i % len(kinds)])."""
    cylinder_sections: int = 32
    """Facets around a cylinder; also the mug's body."""
    superellipsoid_subdivisions: int = 2
    """Icosphere subdivisions before projecting onto a superellipsoid (2: 162 vertices)."""
    superellipsoid_exponents: tuple[float, float] = (0.3, 1.6)
    """Range of both superellipsoid exponents; below 2 the shape stays convex (0: a box,
    1: an ellipsoid)."""
    polytope_points: tuple[int, int] = (8, 24)
    """Range of random points whose convex hull makes a polytope."""

    def __post_init__(self) -> None:
        low, high = self.extent
        if not 0 < 2 * low <= high:
            # Compounds need room for two parts side by side within one bounding box.
            raise ValueError(f"extent must satisfy 0 < 2 * low <= high, got {self.extent}")
        unknown = set(self.kinds) - set(SHAPE_KINDS)
        if unknown or not self.kinds:
            raise ValueError(f"kinds must be a non-empty subset of {SHAPE_KINDS}")
        low_e, high_e = self.superellipsoid_exponents
        if not 0.1 <= low_e <= high_e < 2.0:
            raise ValueError("superellipsoid exponents must lie in [0.1, 2) to stay convex")
        if not 4 <= self.polytope_points[0] <= self.polytope_points[1]:
            raise ValueError("a polytope needs at least 4 points")


@dataclass(frozen=True)
class DecompositionConfig:
    """Convex decomposition of non-convex meshes with CoACD (compounds use their exact parts)."""

    threshold: float = 0.05
    """CoACD concavity threshold, relative to the mesh's size; lower gives more parts."""
    max_parts: int = 16
    """Most convex parts per object; MuJoCo's collision cost grows with each."""
    max_part_vertices: int = 64
    """Most vertices per convex part (CoACD's max_ch_vertex)."""
    seed: int = 0
    """CoACD's random seed, so decompositions are reproducible."""

    def __post_init__(self) -> None:
        if not 0 < self.threshold <= 1 or self.max_parts < 1 or self.max_part_vertices < 4:
            raise ValueError("need 0 < threshold <= 1, max_parts >= 1, max_part_vertices >= 4")


@dataclass(frozen=True)
class StabilityConfig:
    """Search for stable resting orientations by dropping the object on a plane in MuJoCo."""

    drops: int = 64
    """Drops from uniformly random orientations, simulated together in one model."""
    drop_gap: float = 0.01
    """Height of the object's lowest point above the plane at release, m."""
    settle_time: float = 2.0
    """Simulated time per drop, s."""
    rest_window: float = 0.5
    """A drop counts only if it kept its orientation during this last part of the drop, s."""
    rest_angle: float = 0.02
    """A drop has come to rest if its down direction moved less than this during the rest
    window, rad. Orientation drift, not speed: faceted bottoms make MuJoCo contacts
    chatter with tiny amplitude, and spinning about the vertical keeps the pose."""
    cluster_angle: float = 0.2
    """Two rests are one orientation when their down directions differ by less, rad."""
    min_probability: float = 0.04
    """Orientations reached by a smaller share of the resting drops are dropped."""
    max_orientations: int = 16
    """Most stable orientations kept per object (the most probable first)."""
    check_tilt: float = 0.02
    """Each kept orientation must come back after being released tilted by this much, rad."""
    check_frictions: tuple[float, ...] = (0.2, 1.0)
    """Sliding frictions the tilted releases are repeated at: the ends of the per-episode
    object friction range, since soft contacts at a coarse timestep topple some poses at
    high friction only."""
    stable_angle: float = 0.1
    """Largest drift of the down direction for a released orientation to count as stable."""
    timestep: float = 0.0125
    """MuJoCo timestep of drops and checks, s: the sim's step (80 Hz), so kept poses are
    stable at the step they will be simulated at (finer steps are more forgiving)."""
    friction: float = 0.6
    """Sliding friction between object and plane during the drops (mid-range)."""
    rolling_friction: float = 0.001
    """Rolling friction during the drops, m. Point contacts on rounded or faceted bottoms
    otherwise keep rocking and rolling for seconds; it cannot hold a centre of mass more
    than this far beyond the support, and the tilt check runs without it."""
    seed: int = 0
    """Seed of the drop orientations and check tilts."""

    def __post_init__(self) -> None:
        if self.drops < 1 or self.max_orientations < 1:
            raise ValueError("drops and max_orientations must be >= 1")
        if not 0 < self.rest_window < self.settle_time:
            raise ValueError("need 0 < rest_window < settle_time")
        if not 0 <= self.min_probability < 1:
            raise ValueError("min_probability must lie in [0, 1)")


def default_cache_dir() -> Path:
    """Where built objects are cached: `$HAMNET_CACHE/objects`, else ~/.cache/hamnet/objects."""
    root = os.environ.get("HAMNET_CACHE")
    base = Path(root) if root else Path.home() / ".cache" / "hamnet"
    return base / "objects"


@dataclass(frozen=True)
class ObjectLibraryConfig:
    """How the object library is built: shapes, decomposition, stable poses and cache."""

    shapes: ShapeConfig = field(default_factory=ShapeConfig)
    """Procedural shape kinds and the size range shared with imported meshes."""
    decomposition: DecompositionConfig = field(default_factory=DecompositionConfig)
    """CoACD settings for non-convex imported meshes."""
    stability: StabilityConfig = field(default_factory=StabilityConfig)
    """Stable-orientation search by dropping."""
    cache_dir: Path | None = None
    """Folder of cached objects; None: `default_cache_dir()` at build time."""
    use_cache: bool = True
    """Read and write the cache; off, every object is recomputed and nothing is written."""

    def resolved_cache_dir(self) -> Path:
        """The cache folder in use (the configured one or the default)."""
        return self.cache_dir if self.cache_dir is not None else default_cache_dir()
