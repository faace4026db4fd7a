"""Evaluating one policy in this process: build its environments once, then play every
suite's episodes in batches (`play`), recording a few and collecting the skills' embeddings
when asked. The sim, perception, input builder and safety filter are the trainer's
in-process cores (`hamnet.trainer.collection`), so what is measured is what was trained.
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

import numpy as np

from hamnet.evaluation.config import EvalConfig
from hamnet.evaluation.episode_plan import Slot, domain_slots, planned, procedural_slots, seed_of
from hamnet.evaluation.episode_view import EpisodeView
from hamnet.evaluation.play import Embeddings, Labels, play
from hamnet.evaluation.records import PROCEDURAL, EpisodeRecord
from hamnet.evaluation.skills import SkillSteps
from hamnet.messages.robot_state import Observation
from hamnet.perception.config import student_clouds
from hamnet.policy.policy import Policy
from hamnet.safety.config import with_profile
from hamnet.sim.domains import DOMAIN_NAMES
from hamnet.trainer.collection.rollout_worker import RolloutWorker
from hamnet.trainer.collection.sources import build_workers, frozen_encoder
from hamnet.trainer.runners.run_config import RunConfig, stage_sim

log = logging.getLogger(__name__)

SKILL_ARCHITECTURES = ("hamnet", "student")
"""Architectures with a modulation embedding z_tau to analyse."""


def worker_for(policy: Policy, config: EvalConfig, stage: str) -> RolloutWorker:
    """Up to `config.num_envs` environments of `stage` with perception as `policy` reads it (a
    student's clouds as the cameras see them) on the shipped frozen encoder, and the safety
    filter of `config.safety_profile`."""
    most = max(config.episodes_per_domain, config.procedural_episodes)  # in one suite
    envs = min(config.num_envs, most)  # no environment stepped for nothing
    sim = dataclasses.replace(stage_sim(stage), num_envs=envs, seed=seed_of(config.seed))
    run = RunConfig(stage=stage, sim=sim, architecture=policy.architecture)
    clouds = None if policy.config.privileged else student_clouds()
    encoder = frozen_encoder(run) if policy.config.clouds else None
    safety = with_profile(config.safety_profile)
    (worker,), _ = build_workers(run, groups=1, clouds=clouds, encoder=encoder, safety=safety)
    return worker


def start(worker: RolloutWorker, config: EvalConfig, slots: list[Slot], batch: int) -> Observation:
    """Start `slots` (one batch of one suite) in the worker's environments."""
    env = worker.env
    if slots[0].suite == PROCEDURAL:  # the stage's own draws, on a held-out seed per batch
        return env.reset(seed=seed_of(config.seed, len(DOMAIN_NAMES), batch))
    return env.start_planned(planned(slots, env.num_envs))


def evaluate_policy(
    policy: Policy, config: EvalConfig, stage: str, recordings: Path | None = None
) -> tuple[list[EpisodeRecord], SkillSteps | None]:
    """Every episode of `config.suites` played by `policy`; with `recordings`, the first
    `config.record` episodes of each suite as `.rrd` files there; the skills' steps when
    `config.skills` and the policy has a modulation embedding."""
    worker = worker_for(policy, config, stage)
    env, size = worker.env, worker.env.num_envs
    names = [entry.name for entry in env.library.objects]
    embeddings = (
        Embeddings() if config.skills and policy.architecture in SKILL_ARCHITECTURES else None
    )
    records: list[EpisodeRecord] = []
    for suite in config.suites:
        slots = (
            procedural_slots(config)
            if suite == PROCEDURAL
            else domain_slots(config, suite, len(names))
        )
        for batch, first in enumerate(range(0, len(slots), size)):
            chunk = slots[first : first + size]
            started = start(worker, config, chunk, batch)
            objects = env.object_index[: len(chunk)]
            labels = Labels(
                [slot.suite for slot in chunk],
                [names[int(entry)] for entry in objects],
                [slot.pair for slot in chunk],
                [slot.init for slot in chunk],
            )
            shown = max(0, min(config.record - first, len(chunk))) if recordings else 0
            view = (
                EpisodeView(
                    env,
                    list(range(shown)),
                    [recordings / f"{suite}_{first + k}.rrd" for k in range(shown)],
                )
                if shown
                else None
            )
            played = play(
                policy,
                worker,
                started,
                labels,
                config.env_transitions,
                first_episode=len(records),
                embeddings=embeddings,
                frame=None if view is None else view.frame,
            )
            if view is not None:
                view.close()
            records += played
            rate = np.mean([record.success for record in played])
            log.info(
                "%s: %d of %d episodes played, success %.3f in this batch",
                suite,
                first + len(chunk),
                len(slots),
                rate,
            )
    return records, None if embeddings is None else skill_steps(embeddings, records)


def skill_steps(embeddings: Embeddings, records: list[EpisodeRecord]) -> SkillSteps:
    """The collected embeddings with their episodes' suites."""
    episode = np.concatenate(embeddings.episode).astype(np.int64)
    return SkillSteps(
        embeddings=np.concatenate(embeddings.rows).astype(np.float32),
        episode=episode,
        step=np.concatenate(embeddings.step).astype(np.int64),
        suite=np.array([records[i].suite for i in episode]),
    )
