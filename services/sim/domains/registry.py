"""The nine benchmark domains by name (paper, Sec. "Simulated Benchmark in Realistic
Domains": cabinet, top of cabinet, sink, basket, drawer, grill, circular bin, suitcase and
flat), each a builder with the signature of `scene.sample_scenes`."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from hamnet.sim.domains import containers, furniture
from hamnet.sim.scene import SceneBatch
from hamnet.sim.scene_config import SceneConfig

SceneBuilder = Callable[[np.random.Generator, np.ndarray, SceneConfig | None], SceneBatch]
"""(rng, object_height (B,), config) -> B scenes, as `scene.sample_scenes`."""

DOMAIN_BUILDERS: dict[str, SceneBuilder] = {
    "cabinet": furniture.cabinet,
    "cabinet_top": furniture.cabinet_top,
    "sink": containers.sink,
    "basket": containers.basket,
    "drawer": furniture.drawer,
    "grill": containers.grill,
    "circular_bin": containers.circular_bin,
    "suitcase": containers.suitcase,
    "flat": furniture.flat,
}
"""Each domain's builder, in the order of the paper's Table tab:real-result."""

DOMAIN_NAMES = tuple(DOMAIN_BUILDERS)
"""The domains' names; an `EpisodePlan` refers to a domain by its index here."""


def domain_builder(name: str) -> SceneBuilder:
    """The builder of domain `name`.

    Raises:
        ValueError: `name` is no domain; the message lists them.
    """
    if name not in DOMAIN_BUILDERS:
        raise ValueError(f"unknown domain {name!r}: choose one of {', '.join(DOMAIN_NAMES)}")
    return DOMAIN_BUILDERS[name]
