"""Which episodes an evaluation plays: per domain, objects of the stage's library, pose
pairs and robot initialisations, each seeded from the evaluation's seed alone, so two
policies (or two runs) play exactly the same episodes.

A pair's seed fixes the domain's scene, the start and goal poses and the object's physics;
an init's seed fixes only the arm's start (`hamnet.sim.domains.EpisodePlan`). Procedural
episodes are the stage's own draws on held-out seeds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hamnet.evaluation.config import EvalConfig
from hamnet.evaluation.records import PROCEDURAL
from hamnet.sim.domains import DOMAIN_NAMES, EpisodePlan

EVAL_SEED_OFFSET = 7_000_003
"""Added to `--seed` for every seed an evaluation draws: a prime far from the trainer's
worker strides (100,003) and its held-out offset (1,000,003), so no training run and no
trainer evaluation saw these episodes."""


@dataclass(frozen=True)
class Slot:
    """One planned episode."""

    suite: str
    object_index: int
    """Entry of the stage's sized object library (procedural: drawn by the stage)."""
    pair: int
    init: int
    pair_seed: int
    init_seed: int


def seed_of(*parts: int) -> int:
    """A 32-bit seed of the evaluation seed and an episode's indices, independent for every
    distinct tuple (numpy's SeedSequence hashing)."""
    return int(np.random.SeedSequence([EVAL_SEED_OFFSET, *parts]).generate_state(1)[0])


def domain_slots(config: EvalConfig, suite: str, library_size: int) -> list[Slot]:
    """Every episode of benchmark domain `suite`: objects x pairs x inits."""
    domain = DOMAIN_NAMES.index(suite)
    rng = np.random.default_rng(seed_of(config.seed, domain))
    count = min(config.objects, library_size)
    objects = rng.choice(library_size, size=count, replace=False)
    return [
        Slot(
            suite,
            int(entry),
            pair,
            init,
            seed_of(config.seed, domain, int(entry), pair),
            seed_of(config.seed, domain, int(entry), pair, init),
        )
        for entry in objects
        for pair in range(config.pairs)
        for init in range(config.inits)
    ]


def procedural_slots(config: EvalConfig) -> list[Slot]:
    """The procedural suite's episodes: as many as one domain plays unless set."""
    count = config.procedural_episodes or config.episodes_per_domain
    return [Slot(PROCEDURAL, -1, episode, 0, 0, 0) for episode in range(count)]


def planned(slots: list[Slot], num_envs: int) -> EpisodePlan:
    """The plan of `slots` for `num_envs` environments, the last slot repeated to fill
    the batch (those environments' episodes are played and not counted)."""
    filled = slots + [slots[-1]] * (num_envs - len(slots))
    return EpisodePlan.named(
        [slot.suite for slot in filled],
        [slot.object_index for slot in filled],
        [slot.pair_seed for slot in filled],
        [slot.init_seed for slot in filled],
    )
