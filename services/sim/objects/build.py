"""Building library objects: geometry in, `ObjectAsset` out, through the on-disk cache.

The expensive steps (CoACD, the stable-pose drops) run only on a cache miss. A procedural
object is keyed by its generated geometry, so the key follows the generator's output rather
than its code; an object that never rests stably is replaced by the next draw of its seed.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from functools import partial

import numpy as np

from hamnet.sim.objects.asset import ObjectAsset
from hamnet.sim.objects.cache import ObjectCache, cache_key
from hamnet.sim.objects.config import ObjectLibraryConfig
from hamnet.sim.objects.mesh import Mesh, unit_inertia
from hamnet.sim.objects.shapes import generate
from hamnet.sim.objects.stability import UnstableObjectError, find_stable_poses

MAX_ATTEMPTS = 8
"""Draws tried per procedural object before giving up on it."""


def finish(
    name: str, mesh: Mesh, parts: tuple[Mesh, ...], source: str, config: ObjectLibraryConfig
) -> ObjectAsset:
    """Complete an object centred at its centre of mass: inertia, volume, stable poses."""
    inertia = unit_inertia(mesh)
    stable = find_stable_poses(mesh, parts, inertia, config.stability)
    return ObjectAsset(name, mesh, parts, mesh.volume, inertia, stable, source)


def cached(
    cache: ObjectCache | None, key: str, build: Callable[[], ObjectAsset], name: str, source: str
) -> ObjectAsset:
    """The entry under `key` (with this `name` and `source`), or `build()` stored under `key`.

    Entries are keyed by content, so a renamed or moved file still hits.
    """
    if cache is not None:
        hit = cache.load(key)
        if hit is not None:
            return dataclasses.replace(hit, name=name, source=source)
    asset = build()
    if cache is not None:
        cache.store(key, asset)
    return asset


def procedural_asset(
    kind: str, seed: int, index: int, config: ObjectLibraryConfig, cache: ObjectCache | None
) -> ObjectAsset:
    """Object `index` of the procedural set drawn from `seed`; it depends on nothing else.

    Raises:
        UnstableObjectError: `MAX_ATTEMPTS` draws all failed to rest stably.
    """
    name, source = f"{kind}-s{seed}-{index:04d}", f"procedural:{kind}"
    for attempt in range(MAX_ATTEMPTS):
        shape = generate(kind, np.random.default_rng([seed, index, attempt]), config.shapes)
        key = cache_key(
            shape.mesh.vertices.tobytes(),
            shape.mesh.faces.tobytes(),
            *(p.vertices.tobytes() for p in shape.parts),
            config.stability,
        )
        build = partial(finish, name, shape.mesh, shape.parts, source, config)
        try:
            return cached(cache, key, build, name, source)
        except UnstableObjectError:
            continue
    raise UnstableObjectError(f"{name}: no stable draw in {MAX_ATTEMPTS} attempts")
