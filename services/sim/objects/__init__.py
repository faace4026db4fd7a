"""The object library: procedural and imported rigid objects ready for MuJoCo and placement.

Stands in for DexGraspNet (not available offline). Each `ObjectAsset` carries a watertight
surface centred at its centre of mass, convex parts for MuJoCo, inertia, and the stable
resting orientations the paper precomputes by dropping (with planar radius and resting height
per orientation). `ObjectSet` builds N objects from a seed and/or imports a folder of meshes,
caching the expensive results on disk; `add_object` puts one into a `mujoco.MjSpec`;
`sample_physics` draws per-episode size, mass, friction and restitution.
"""

from hamnet.sim.objects.asset import ObjectAsset, StablePoses
from hamnet.sim.objects.cache import ObjectCache
from hamnet.sim.objects.config import (
    DecompositionConfig,
    ObjectLibraryConfig,
    ShapeConfig,
    StabilityConfig,
    default_cache_dir,
)
from hamnet.sim.objects.library import ObjectSet, StableTable
from hamnet.sim.objects.mesh import Mesh, sample_surface
from hamnet.sim.objects.randomization import ObjectPhysics, ObjectRandomization, sample_physics
from hamnet.sim.objects.spec import add_object, restitution_solref
from hamnet.sim.objects.stability import UnstableObjectError

__all__ = [
    "DecompositionConfig",
    "Mesh",
    "ObjectAsset",
    "ObjectCache",
    "ObjectLibraryConfig",
    "ObjectPhysics",
    "ObjectRandomization",
    "ObjectSet",
    "ShapeConfig",
    "StabilityConfig",
    "StablePoses",
    "StableTable",
    "UnstableObjectError",
    "add_object",
    "default_cache_dir",
    "restitution_solref",
    "sample_physics",
    "sample_surface",
]
