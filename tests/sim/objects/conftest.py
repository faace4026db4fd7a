"""Fixtures: one small procedural set per session, cached in a pytest temporary folder."""

from __future__ import annotations

from pathlib import Path

import pytest

from hamnet.sim.objects import ObjectCache, ObjectLibraryConfig, ObjectSet
from hamnet.sim.objects.config import SHAPE_KINDS


@pytest.fixture(autouse=True)
def isolated_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Nothing a test builds may land in the user's real cache."""
    monkeypatch.setenv("HAMNET_CACHE", str(tmp_path / "hamnet-cache"))


@pytest.fixture(scope="session")
def library_config(tmp_path_factory: pytest.TempPathFactory) -> ObjectLibraryConfig:
    return ObjectLibraryConfig(cache_dir=tmp_path_factory.mktemp("objects-cache"))


@pytest.fixture(scope="session")
def one_of_each(library_config: ObjectLibraryConfig) -> ObjectSet:
    """One object of every procedural kind (seed 0)."""
    cache = ObjectCache(library_config.resolved_cache_dir())
    return ObjectSet.procedural(len(SHAPE_KINDS), seed=0, config=library_config, cache=cache)
