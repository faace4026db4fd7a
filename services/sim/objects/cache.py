"""On-disk cache of built objects, so decomposition and stable-pose drops run once per object.

An entry is one `.npz` file (no pickle) named by a SHA-256 key of everything the result
depends on: the input geometry or file bytes, the build settings and `CACHE_VERSION`.
Entries are written to a temporary file and renamed, so concurrent sim workers sharing the
folder never read half an entry. The folder is a cache: deleting it only costs time.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import tempfile
from pathlib import Path

import numpy as np

from hamnet.sim.objects.asset import ObjectAsset, StablePoses
from hamnet.sim.objects.mesh import Mesh

CACHE_VERSION = 1
"""Bump when a change to the build would change cached results."""


def cache_key(*items: object) -> str:
    """SHA-256 hex key of byte strings, strings and dataclass configs, in order."""
    digest = hashlib.sha256(f"hamnet-objects-v{CACHE_VERSION}".encode())
    for item in items:
        if dataclasses.is_dataclass(item) and not isinstance(item, type):
            item = json.dumps(dataclasses.asdict(item), sort_keys=True, default=str)
        data = item if isinstance(item, bytes) else str(item).encode()
        digest.update(len(data).to_bytes(8, "little") + data)
    return digest.hexdigest()


def _pack(asset: ObjectAsset) -> dict[str, np.ndarray]:
    return {
        "name": np.array(asset.name),
        "source": np.array(asset.source),
        "vertices": asset.mesh.vertices,
        "faces": asset.mesh.faces,
        "part_vertices": np.concatenate([p.vertices for p in asset.parts]),
        "part_vertex_counts": np.array([len(p.vertices) for p in asset.parts]),
        "part_faces": np.concatenate([p.faces for p in asset.parts]),
        "part_face_counts": np.array([len(p.faces) for p in asset.parts]),
        "volume": np.array(asset.volume),
        "unit_inertia": asset.unit_inertia,
        **{
            f"stable_{f.name}": getattr(asset.stable, f.name)
            for f in dataclasses.fields(StablePoses)
        },
    }


def _unpack(data: dict[str, np.ndarray]) -> ObjectAsset:
    vertex_splits = np.cumsum(data["part_vertex_counts"])[:-1]
    face_splits = np.cumsum(data["part_face_counts"])[:-1]
    parts = tuple(
        Mesh(v, f)
        for v, f in zip(
            np.split(data["part_vertices"], vertex_splits),
            np.split(data["part_faces"], face_splits),
        )
    )
    stable = StablePoses(
        **{f.name: data[f"stable_{f.name}"] for f in dataclasses.fields(StablePoses)}
    )
    return ObjectAsset(
        name=str(data["name"]),
        mesh=Mesh(data["vertices"], data["faces"]),
        parts=parts,
        volume=float(data["volume"]),
        unit_inertia=data["unit_inertia"],
        stable=stable,
        source=str(data["source"]),
    )


class ObjectCache:
    """A folder of built objects by key, counting hits and misses."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root)
        self.hits = 0
        """Lookups answered from disk."""
        self.misses = 0
        """Lookups that found nothing (the caller then builds and stores)."""

    def path(self, key: str) -> Path:
        return self.root / key[:2] / f"{key}.npz"

    def load(self, key: str) -> ObjectAsset | None:
        """The entry under `key`, or None (a corrupt entry counts as missing)."""
        path = self.path(key)
        try:
            with np.load(path, allow_pickle=False) as data:
                asset = _unpack(dict(data))
        except (OSError, ValueError, KeyError):
            self.misses += 1
            return None
        self.hits += 1
        return asset

    def store(self, key: str, asset: ObjectAsset) -> None:
        """Write the entry atomically (temporary file, then rename)."""
        path = self.path(key)
        path.parent.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
        try:
            with os.fdopen(handle, "wb") as file:
                np.savez(file, **_pack(asset))
            os.replace(temporary, path)
        except BaseException:
            Path(temporary).unlink(missing_ok=True)
            raise
