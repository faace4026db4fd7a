"""Every schedule follows one counter, env_transitions (hamnet.runtime.counter): a trainer's
Schedule message reaches the sim and the safety service as the same number, and what each
consumer computes from it (sim: the curriculum; safety: xi and eps_x; policy: the log std)
equals reference functions written here from the authors' rules, which count vectorized steps
of 1024 environments (ham/scripts/train.py:563-570, ham/scripts/env_wrappers.py:1118-1216,
paper line 756 with N_s = 1024, N_t = 2e6).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from hamnet.fr3.limits import Q_HOME
from hamnet.policy.config import LOG_STD_AUTHORS
from hamnet.policy.policy import log_std_at
from hamnet.policy.registry import build, with_changes
from hamnet.policy.serving import PolicyLoopConfig
from hamnet.policy.shell import PolicyShell
from hamnet.proto.trainer_pb2 import Schedule
from hamnet.runtime.codec import encode
from hamnet.runtime.counter import AUTHORS_NUM_ENVS, UNIT
from hamnet.runtime.service import ServiceIdentity
from hamnet.safety import shell as safety_shell
from hamnet.safety.config import with_profile
from hamnet.safety.pipeline import SafetyCore
from hamnet.sim import shell as sim_shell
from hamnet.sim.curriculum import CurriculumConfig, curriculum_values
from tests.policy.wire import announcement
from tests.scripted import ScriptedService, wire

VECTORIZED_STEPS = (0, 1_000, 100_000, 1_953_125, 2_000_000)
"""Counters in the authors' unit; 1_953_125 x 1024 = 2e9 transitions, 2e6 ends their run."""


def scheduled(seed: int | None = None):
    """The MLP baseline with the authors' log-std schedule (the default log std is learned)."""
    return build("mlp", with_changes("mlp", log_std=LOG_STD_AUTHORS), seed=seed)


def authors_log_std(steps: int) -> float:
    """train.py:563-570: minus 0.000367 after each vectorized step k with k % 1024 == 0."""
    return -0.4 - 0.000367 * math.ceil(steps / 1024)


def authors_anneal(steps: int, start: float, end: float) -> float:
    """Paper line 756: one factor (end/start)^(N_s/N_t) per N_s = 1024 steps, N_t = 2e6."""
    return start * (end / start) ** min((steps // 1024) * 1024 / 2e6, 1.0)


def authors_curriculum_share(steps: int) -> float:
    """env_wrappers.py:1128 total_scale_step 2e6: share of the curriculum done."""
    return min(steps / 2e6, 1.0)


def test_the_unit_is_named_once_and_is_the_schedule_field() -> None:
    assert UNIT == "env_transitions"
    assert [f.name for f in Schedule.DESCRIPTOR.fields] == ["header", UNIT]


@pytest.mark.parametrize("steps", VECTORIZED_STEPS)
def test_sim_safety_and_policy_agree_at_the_counter(steps: int) -> None:
    counter = steps * AUTHORS_NUM_ENVS  # env_transitions
    message = wire(Schedule(env_transitions=counter))
    assert sim_shell.decode_schedule(message) == safety_shell.decode_schedule(message) == counter

    config = CurriculumConfig()
    share = authors_curriculum_share(steps)
    values = curriculum_values(counter, config)
    assert values.p_near_init == pytest.approx(0.8 + (1 / 11 - 0.8) * share)
    assert values.p_tight == pytest.approx(1 / 3 + (5 / 6 - 1 / 3) * share)

    core = SafetyCore(2, with_profile("finetune"))
    q = np.tile(Q_HOME, (2, 1))
    schedule = core.filter(np.zeros((2, 21)), q, np.zeros_like(q), counter).schedule
    assert schedule.xi_large == pytest.approx(authors_anneal(steps, 0.26, 0.16))
    assert schedule.xi_small == pytest.approx(authors_anneal(steps, 0.21, 0.08))
    assert schedule.eps_x == pytest.approx(authors_anneal(steps, 0.24, 0.12))

    policy = scheduled()
    policy.set_env_transitions(counter)
    expected = torch.full_like(policy.log_std, authors_log_std(steps))
    torch.testing.assert_close(policy.log_std, expected)


def test_log_std_after_two_billion_transitions() -> None:
    """The issue's figure: about -1.12 at the end of the authors' 2e6 x 1024 transitions,
    with no floor on the way (exploration is not collapsed after 3% of training)."""
    policy = scheduled()
    policy.set_env_transitions(2_048_000_000)
    assert float(policy.log_std[0]) == pytest.approx(-1.117, abs=1e-3)
    policy.set_env_transitions(61_440_000)  # 3% of training
    assert float(policy.log_std[0]) == pytest.approx(-0.4 - 59 * 0.000367)


def test_policy_service_follows_the_counter_across_new_weights() -> None:
    """The service sets its log std from each Schedule, and keeps it when new weights (which
    carry the log std they were saved with) arrive."""
    counter = 500 * 2**20
    messages = iter([
        ("schedule", Schedule(env_transitions=counter)),
        ("weights", announcement(scheduled(seed=1), 1)),
    ])  # fmt: skip

    def script(published):
        item = next(messages, None)
        return "end" if item is None else (item[0], encode(item[1]))

    service = ScriptedService(script, identity=ServiceIdentity("policy", "0"))
    config = PolicyLoopConfig(student_pose_noise=False)
    shell = PolicyShell(service, scheduled(seed=0), 0, config)
    shell.run()
    assert shell.version == 1 and shell.env_transitions == counter
    want = log_std_at(counter, shell.policy.config.log_std)
    torch.testing.assert_close(shell.policy.log_std, torch.full_like(shell.policy.log_std, want))
