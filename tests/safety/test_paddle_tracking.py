"""How far the arm moves the paddle for the twist a paddle-space action asks (issue 28).

Measured on the easy stage's start postures (the training profile's filter, the compensated
arm), a constant twist of 1.5 cm per policy step upwards (free motion, no contact): the
paddle lags the first step (0.3 of the asked motion at the largest stiffness) and settles by
the fourth at 0.72 of it at kp_u = +1, 0.51 at kp_u = 0 and 0.09 at kp_u = -1 (medians over
32 environments; the target is the measured posture plus the residual, so a steady twist
is tracked at a steady fraction; the test plays 16). The policy's stiffness components therefore decide
whether its twist moves the arm at all: at the smallest stiffness it barely does.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hamnet.fr3.limits import NUM_JOINTS
from hamnet.sim.stages import stage_config
from hamnet.trainer.results.evaluate import held_out_worker
from hamnet.trainer.runners.run_config import RunConfig

B = 16
ASKED = 0.5
"""The twist's z component: half its bound, 1.5 cm per step (`twist_linear` 0.03 m)."""
STEPS = 4
LATE = 10**9
"""Schedule counter past the annealing: the filter's final residual scale."""


def upward_motion(kp_u: float) -> np.ndarray:
    """(STEPS,) the paddle's median upward motion per policy step, as a fraction of the
    asked, under a constant upward twist at the stiffness component `kp_u`."""
    config = RunConfig(
        sim=stage_config("easy", num_envs=B), architecture="state-mlp", action_space="paddle"
    )
    worker = held_out_worker(config, B)
    action = np.zeros((B, 3 * NUM_JOINTS), dtype=np.float32)
    action[:, 2] = ASKED
    action[:, NUM_JOINTS : 2 * NUM_JOINTS] = kp_u
    asked = ASKED * worker.safety.config.action_magnitude.twist_linear  # m
    fractions = []
    for _ in range(STEPS):
        before = worker.observation.ee_pos_rot6d[:, 2].copy()
        result = worker.env.step(worker.command(torch.as_tensor(action), LATE))
        assert not result.reset_ids.size, "an episode ended while the paddle moved up"
        worker.start(result.reset_ids, result.observation)
        fractions.append(np.median(worker.observation.ee_pos_rot6d[:, 2] - before) / asked)
    return np.array(fractions)


@pytest.mark.parametrize(("kp_u", "low", "high"), [(1.0, 0.55, 0.9), (-1.0, 0.0, 0.2)])
def test_a_steady_twist_moves_the_paddle_by_a_fraction_its_stiffness_sets(
    kp_u: float, low: float, high: float
) -> None:
    motion = upward_motion(kp_u)
    assert motion[0] < motion[-1], motion  # it lags, then settles
    assert low <= motion[-1] <= high, motion
