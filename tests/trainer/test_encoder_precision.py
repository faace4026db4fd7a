"""The run's `encoder_precision` reaches every perception it builds: the rollout workers'
(training and held-out evaluation) and both seats of a DAgger worker, whose student keeps
the cameras' view of the clouds."""

from __future__ import annotations

import dataclasses

import pytest

from hamnet.policy.registry import build
from hamnet.sim.stages import stage_config
from hamnet.trainer.collection.dagger_worker import build_dagger_worker
from hamnet.trainer.collection.sources import build_workers
from hamnet.trainer.runners.run_config import RunConfig


@pytest.mark.parametrize("precision", ["float32", "bfloat16"])
def test_every_perception_of_a_run_runs_its_encoder_at_the_runs_precision(precision: str) -> None:
    sim = stage_config("easy", num_envs=2, num_objects=2, nthread=1)
    config = RunConfig(sim=sim, encoder_precision=precision)
    bfloat16 = precision == "bfloat16"
    workers, _ = build_workers(config, groups=2)
    assert [worker.perception.bfloat16 for worker in workers] == [bfloat16, bfloat16]
    student = dataclasses.replace(config, architecture="student")
    seats = build_dagger_worker(student, build("hamnet", seed=0)).seats
    assert {role: seat.perception.bfloat16 for role, seat in seats.items()} == {
        "teacher": bfloat16,
        "student": bfloat16,
    }
    assert seats["student"].perception.config.visibility == "cameras"
    assert seats["teacher"].perception.config.visibility == "full"
