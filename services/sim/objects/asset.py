"""One library object: its surface, convex parts, inertia and stable resting orientations.

Pure data plus derived quantities; `build.py` makes assets, `spec.py` puts them into MuJoCo,
and placement reads the stable orientations (a resting pose is a stable orientation
composed with any yaw, with the centre at the resting height above the support).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hamnet.sim.objects.mesh import Mesh, sample_surface


@dataclass(frozen=True, eq=False)
class StablePoses:
    """Resting orientations of an object on a horizontal plane, most probable first."""

    orientations: np.ndarray
    """(K, 4) wxyz, yaw-free: the smallest rotation taking the object's down direction to -z."""
    probabilities: np.ndarray
    """(K,) share of random drops that came to rest this way (sums to <= 1)."""
    planar_radii: np.ndarray
    """(K,) largest horizontal distance from the centre to the object resting this way, m;
    the margin placement keeps from walls and plate edges."""
    resting_heights: np.ndarray
    """(K,) height of the centre above the support plane when resting this way, m."""

    def scaled(self, scale: float) -> StablePoses:
        return StablePoses(
            self.orientations,
            self.probabilities,
            self.planar_radii * scale,
            self.resting_heights * scale,
        )


@dataclass(frozen=True, eq=False)
class ObjectAsset:
    """A rigid object, in a frame at its centre of mass."""

    name: str
    """Unique id in its set, e.g. `box-s0-0003` or the stem of an imported file."""
    mesh: Mesh
    """Watertight surface (visual mesh, object cloud)."""
    parts: tuple[Mesh, ...]
    """Convex pieces MuJoCo collides with; exact for procedural shapes, CoACD for imports."""
    volume: float
    """Volume enclosed by `mesh`, m^3."""
    unit_inertia: np.ndarray
    """(3, 3) inertia per kg about the centre of mass at uniform density, m^2."""
    stable: StablePoses
    """Stable resting orientations."""
    source: str
    """Where it came from: `procedural:<kind>` or the imported file's path."""

    @property
    def orientations(self) -> np.ndarray:
        """(K, 4) stable orientations, wxyz."""
        return self.stable.orientations

    @property
    def planar_radii(self) -> np.ndarray:
        """(K,) planar radius per stable orientation, m."""
        return self.stable.planar_radii

    @property
    def resting_heights(self) -> np.ndarray:
        """(K,) resting height per stable orientation, m."""
        return self.stable.resting_heights

    @property
    def bbox(self) -> np.ndarray:
        """(2, 3) axis-aligned bounding box in the object frame: min and max corner, m."""
        return self.mesh.bounds

    @property
    def radius(self) -> float:
        """Largest distance from the centre of mass to the surface, m (the authors' object size)."""
        return float(np.linalg.norm(self.mesh.vertices, axis=1).max())

    def scaled(self, scale: float) -> ObjectAsset:
        """The same object scaled uniformly (orientations and probabilities are unchanged)."""
        if scale == 1.0:
            return self
        return ObjectAsset(
            name=self.name,
            mesh=self.mesh.scaled(scale),
            parts=tuple(p.scaled(scale) for p in self.parts),
            volume=self.volume * scale**3,
            unit_inertia=self.unit_inertia * scale**2,
            stable=self.stable.scaled(scale),
            source=self.source,
        )

    def sample_surface(self, count: int, rng: np.random.Generator) -> np.ndarray:
        """(N, 3) points uniform over the surface, object frame, m (the object cloud)."""
        return sample_surface(self.mesh, count, rng)
