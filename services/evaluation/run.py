"""Evaluating one policy: build its environments once, then play every suite's episodes in
batches, recording a few and collecting the skills' embeddings when asked.

In this process (the default) the sim, perception, input builder and safety filter are the
trainer's in-process cores (`hamnet.trainer.collection`), so what is measured is what was
trained; with `--stack` perception, the policy and the safety filter run as services and
this process is their sim (`stack`). Either way the same batches of the same episodes are
played and booked alike (`outcomes`).
"""

from __future__ import annotations

import dataclasses
import logging
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hamnet.evaluation.config import EvalConfig
from hamnet.evaluation.episode_plan import Slot, domain_slots, planned, procedural_slots, seed_of
from hamnet.evaluation.episode_view import EpisodeView
from hamnet.evaluation.outcomes import Labels
from hamnet.evaluation.play import Embeddings, play
from hamnet.evaluation.records import PROCEDURAL, EpisodeRecord
from hamnet.evaluation.skills import SkillSteps
from hamnet.evaluation.stack import EvalShell, service_commands, services, stack_identity
from hamnet.messages.robot_state import Observation
from hamnet.perception.config import student_clouds
from hamnet.policy.policy import Policy
from hamnet.runtime.service import Service
from hamnet.runtime.transport import TransportConfig
from hamnet.safety.config import with_profile
from hamnet.sim.domains import DOMAIN_NAMES
from hamnet.sim.env import VectorEnv
from hamnet.trainer.collection.rollout_worker import RolloutWorker
from hamnet.trainer.collection.sources import build_workers, frozen_encoder
from hamnet.trainer.runners.run_config import RunConfig, stage_sim

log = logging.getLogger(__name__)

SKILL_ARCHITECTURES = ("hamnet", "student")
"""Architectures with a modulation embedding z_tau to analyse."""


@dataclass(frozen=True)
class Batch:
    """Episodes started in the environments, the first len(labels.suite) of them counted."""

    started: Observation
    labels: Labels
    first: int
    """Index of the batch's first episode within its suite."""
    view: EpisodeView | None
    """The recording of its first episodes, if any."""


def run_config(policy: Policy, config: EvalConfig, stage: str) -> RunConfig:
    """Up to `config.num_envs` environments of `stage` for `policy`."""
    most = max(config.episodes_per_domain, config.procedural_episodes)  # in one suite
    envs = min(config.num_envs, most)  # no environment stepped for nothing
    sim = dataclasses.replace(stage_sim(stage), num_envs=envs, seed=seed_of(config.seed))
    return RunConfig(
        stage=stage,
        sim=sim,
        architecture=policy.architecture,
        action_space=policy.config.action_space,
    )


def worker_for(policy: Policy, config: EvalConfig, stage: str) -> RolloutWorker:
    """The environments with perception as `policy` reads it (a student's clouds as the
    cameras see them) on the shipped frozen encoder, and the safety filter of
    `config.filter_profile`."""
    run = run_config(policy, config, stage)
    clouds = None if policy.config.privileged else student_clouds()
    encoder = frozen_encoder(run) if policy.config.clouds else None
    safety = with_profile(config.filter_profile)
    (worker,), _ = build_workers(run, groups=1, clouds=clouds, encoder=encoder, safety=safety)
    return worker


def suite_slots(config: EvalConfig, library_size: int) -> dict[str, list[Slot]]:
    """Every suite's planned episodes, in `config.suites` order."""
    return {
        suite: procedural_slots(config)
        if suite == PROCEDURAL
        else domain_slots(config, suite, library_size)
        for suite in config.suites
    }


def batches(
    env: VectorEnv, config: EvalConfig, plan: dict[str, list[Slot]], recordings: Path | None
) -> Iterator[Batch]:
    """The episodes of `plan`, started batch after batch in `env`; with `recordings`, the
    first `config.record` of each suite drawn into `.rrd` files there."""
    names = [entry.name for entry in env.library.objects]
    for suite, slots in plan.items():
        for batch, first in enumerate(range(0, len(slots), env.num_envs)):
            chunk = slots[first : first + env.num_envs]
            started = start(env, config, chunk, batch)
            labels = Labels(
                [slot.suite for slot in chunk],
                [names[int(entry)] for entry in env.object_index[: len(chunk)]],
                [slot.pair for slot in chunk],
                [slot.init for slot in chunk],
            )
            shown = max(0, min(config.record - first, len(chunk))) if recordings else 0
            paths = [recordings / f"{suite}_{first + k}.rrd" for k in range(shown)]
            view = EpisodeView(env, list(range(shown)), paths) if shown else None
            yield Batch(started, labels, first, view)


def start(env: VectorEnv, config: EvalConfig, slots: list[Slot], batch: int) -> Observation:
    """Start `slots` (one batch of one suite) in `env`."""
    if slots[0].suite == PROCEDURAL:  # the stage's own draws, on a held-out seed per batch
        return env.reset(seed=seed_of(config.seed, len(DOMAIN_NAMES), batch))
    return env.start_planned(planned(slots, env.num_envs))


def played(
    env: VectorEnv,
    config: EvalConfig,
    recordings: Path | None,
    play_batch: Callable[[Batch, int], list[EpisodeRecord]],
) -> list[EpisodeRecord]:
    """The records of every batch, each played by `play_batch(batch, episodes played
    before it)`, with a progress line after each batch: the suite's and the whole
    evaluation's episodes, the success rate so far, the rate and the time left."""
    plan = suite_slots(config, len(env.library.objects))
    total, started = sum(len(slots) for slots in plan.values()), time.monotonic()
    records: list[EpisodeRecord] = []
    for batch in batches(env, config, plan, recordings):
        records += play_batch(batch, len(records))
        if batch.view is not None:
            batch.view.close()
        suite = batch.labels.suite[0]
        rate = len(records) / (time.monotonic() - started)
        log.info(
            "%s: %d of %d episodes; %d of %d in all, success so far %.3f, %.1f episodes/s, "
            "about %.0f min left",
            suite,
            batch.first + len(batch.labels.suite),
            len(plan[suite]),
            len(records),
            total,
            sum(record.success for record in records) / len(records),
            rate,
            (total - len(records)) / rate / 60,
        )
    return records


def evaluate_policy(
    policy: Policy, config: EvalConfig, stage: str, recordings: Path | None = None
) -> tuple[list[EpisodeRecord], SkillSteps | None]:
    """Every episode of `config.suites` played by `policy` in this process; the skills'
    steps when `config.skills` and the policy has a modulation embedding."""
    worker = worker_for(policy, config, stage)
    skills = config.skills and policy.architecture in SKILL_ARCHITECTURES
    embeddings = Embeddings() if skills else None

    def play_batch(batch: Batch, before: int) -> list[EpisodeRecord]:
        return play(
            policy,
            worker,
            batch.started,
            batch.labels,
            config.env_transitions,
            first_episode=before,  # the embeddings' episode ids: lines of the records
            embeddings=embeddings,
            frame=None if batch.view is None else batch.view.frame,
        )

    records = played(worker.env, config, recordings, play_batch)
    return records, None if embeddings is None else skill_steps(embeddings, records)


def evaluate_on_stack(
    weights: str, policy: Policy, config: EvalConfig, stage: str, recordings: Path | None = None
) -> list[EpisodeRecord]:
    """Every episode of `config.suites` played by `policy` (checkpoint or shipped name
    `weights`) served by `hamnet policy`, its perception and its safety filter as services,
    this process their sim; the services log to `config.out / "logs"`."""
    env = VectorEnv(run_config(policy, config, stage).sim)
    transport = TransportConfig(namespace=f"eval{uuid.uuid4().hex[:8]}")
    commands = service_commands(weights, policy, config.filter_profile, transport)
    with (
        services(commands, config.out / "logs"),
        Service(stack_identity(), transport) as service,
    ):
        shell = EvalShell(service, env)

        def play_batch(batch: Batch, _: int) -> list[EpisodeRecord]:
            shell.frame = None if batch.view is None else batch.view.frame
            return shell.play(batch.started, batch.labels)

        return played(env, config, recordings, play_batch)


def skill_steps(embeddings: Embeddings, records: list[EpisodeRecord]) -> SkillSteps:
    """The collected embeddings with their episodes' suites."""
    episode = np.concatenate(embeddings.episode).astype(np.int64)
    return SkillSteps(
        embeddings=np.concatenate(embeddings.rows).astype(np.float32),
        episode=episode,
        step=np.concatenate(embeddings.step).astype(np.int64),
        suite=np.array([records[i].suite for i in episode]),
    )
