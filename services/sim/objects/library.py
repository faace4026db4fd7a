"""`ObjectSet`: the object library the sim draws from, procedural and/or imported.

A set is an ordered, named tuple of `ObjectAsset`s; `stable_table` pads the per-object
stable poses into dense arrays for batched placement.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hamnet.sim.objects.asset import ObjectAsset
from hamnet.sim.objects.build import procedural_asset
from hamnet.sim.objects.cache import ObjectCache
from hamnet.sim.objects.config import ObjectLibraryConfig
from hamnet.sim.objects.importer import import_folder


def default_cache(config: ObjectLibraryConfig) -> ObjectCache | None:
    """The cache `config` asks for, or None when caching is off."""
    return ObjectCache(config.resolved_cache_dir()) if config.use_cache else None


@dataclass(frozen=True, eq=False)
class StableTable:
    """Stable poses of N objects padded to the largest count K."""

    orientations: np.ndarray
    """(N, K, 4) wxyz; padding repeats the object's first orientation."""
    probabilities: np.ndarray
    """(N, K) share of drops; 0 for padding, so it can weight sampling directly."""
    planar_radii: np.ndarray
    """(N, K) m; padding repeats the first."""
    resting_heights: np.ndarray
    """(N, K) m; padding repeats the first."""
    counts: np.ndarray
    """(N,) number of real poses per object."""


@dataclass(frozen=True, eq=False)
class ObjectSet:
    """An ordered collection of objects with unique names."""

    assets: tuple[ObjectAsset, ...]

    def __post_init__(self) -> None:
        names = [a.name for a in self.assets]
        if len(set(names)) != len(names):
            raise ValueError("object names in a set must be unique")

    @classmethod
    def procedural(
        cls,
        count: int,
        seed: int = 0,
        config: ObjectLibraryConfig | None = None,
        cache: ObjectCache | None = None,
    ) -> ObjectSet:
        """`count` procedural objects from `seed`, cycling through `config.shapes.kinds`.

        Object i depends only on (seed, i), so a larger set extends a smaller one.
        `cache` defaults to the folder `config` names (none if `config.use_cache` is off).
        """
        config = config or ObjectLibraryConfig()
        cache = cache if cache is not None else default_cache(config)
        kinds = config.shapes.kinds
        return cls(
            tuple(
                procedural_asset(kinds[i % len(kinds)], seed, i, config, cache)
                for i in range(count)
            )
        )

    @classmethod
    def from_folder(
        cls,
        folder: Path,
        config: ObjectLibraryConfig | None = None,
        cache: ObjectCache | None = None,
    ) -> ObjectSet:
        """Every mesh file under `folder` (see `importer.import_folder`)."""
        config = config or ObjectLibraryConfig()
        cache = cache if cache is not None else default_cache(config)
        return cls(tuple(import_folder(Path(folder), config, cache)))

    def __add__(self, other: ObjectSet) -> ObjectSet:
        return ObjectSet(self.assets + other.assets)

    def __len__(self) -> int:
        return len(self.assets)

    def __iter__(self) -> Iterator[ObjectAsset]:
        return iter(self.assets)

    def __getitem__(self, key: int | str) -> ObjectAsset:
        if isinstance(key, str):
            for asset in self.assets:
                if asset.name == key:
                    return asset
            raise KeyError(key)
        return self.assets[key]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(a.name for a in self.assets)

    @property
    def radii(self) -> np.ndarray:
        """(N,) bounding radius of each object, m."""
        return np.array([a.radius for a in self.assets])

    def stable_table(self) -> StableTable:
        """Stable poses of all objects as dense arrays, padded to the largest count."""
        counts = np.array([len(a.stable.probabilities) for a in self.assets])  # (N,)
        slots = np.arange(counts.max())[None, :]  # (1, K)
        real = slots < counts[:, None]  # (N, K)
        index = np.where(real, slots, 0)  # (N, K): padding points at the first pose

        def take(field: str) -> np.ndarray:
            return np.stack([getattr(a.stable, field)[i] for a, i in zip(self.assets, index)])

        return StableTable(
            orientations=take("orientations"),
            probabilities=np.where(real, take("probabilities"), 0.0),
            planar_radii=take("planar_radii"),
            resting_heights=take("resting_heights"),
            counts=counts,
        )
