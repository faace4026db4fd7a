"""Planned episodes for evaluation: which domain, object, pose pair and arm start each
environment gets, reproducible from seeds (paper, Sec. "Simulated Benchmark": "for each
domain and object pair, we sample 5 stable initial- and goal-poses and 128 random
collision-free robot initializations").

A pair seed fixes the scene (the fixture's shift and friction), the start and goal poses and
the object's physics; an init seed fixes the arm's start alone, so one pair is played from
many arm starts. `VectorEnv.start_planned` plays a plan. Shapes: B planned environments.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from hamnet.sim.domains.registry import DOMAIN_NAMES, domain_builder
from hamnet.sim.placement import PlacementConfig
from hamnet.sim.task_config import TaskConfig


@dataclass(frozen=True, eq=False)
class EpisodePlan:
    """B planned episodes, one row per environment."""

    domain: np.ndarray
    """(B,) int index into `DOMAIN_NAMES`; rows may differ."""
    object_index: np.ndarray
    """(B,) int entry of the environment's object library (`VectorEnv.library`)."""
    pair_seed: np.ndarray
    """(B,) int seed of the scene, the start and goal poses and the object's physics."""
    init_seed: np.ndarray
    """(B,) int seed of the arm's start (random, collision-free)."""

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            values = np.asarray(getattr(self, field.name))
            if values.ndim != 1 or not np.issubdtype(values.dtype, np.integer):
                raise ValueError(f"{field.name} must be a (B,) integer array")
            if len(values) != len(np.asarray(self.domain)) or np.any(values < 0):
                raise ValueError(f"{field.name} must hold B values >= 0, as domain does")
            object.__setattr__(self, field.name, values.astype(np.int64))
        if np.any(self.domain >= len(DOMAIN_NAMES)):
            raise ValueError(f"domain indexes DOMAIN_NAMES ({len(DOMAIN_NAMES)} domains)")

    @classmethod
    def named(
        cls,
        domains: Sequence[str],
        object_index: Sequence[int],
        pair_seed: Sequence[int],
        init_seed: Sequence[int],
    ) -> EpisodePlan:
        """A plan whose domains are given by name.

        Raises:
            ValueError: a name is no domain.
        """
        for name in domains:
            domain_builder(name)
        index = np.array([DOMAIN_NAMES.index(name) for name in domains], dtype=np.int64)
        return cls(index, np.asarray(object_index), np.asarray(pair_seed), np.asarray(init_seed))

    def __len__(self) -> int:
        return len(self.domain)


def pair_placement(task: TaskConfig) -> PlacementConfig:
    """The placement of a domain's start and goal: the default (paper) placement, whatever
    the stage's curriculum says (the easy stage keeps the goal's orientation and pushes
    15-25 cm, which a benchmark pair must not and a cabinet shelf cannot hold), with the
    separations raised to `task`'s success thresholds (0.05 m and 0.1 rad by default) and
    both required, as the paper's benchmark keeps "sufficient separation in both position
    and orientation" (appendix "Details on the Simulation Benchmark")."""
    placement = PlacementConfig()
    return dataclasses.replace(
        placement,
        min_position_separation=max(placement.min_position_separation, task.success_radius),
        min_orientation_separation=max(placement.min_orientation_separation, task.success_angle),
        require_both_separations=True,
    )
