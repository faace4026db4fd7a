"""The arm's joint friction: by default the little the FR3 leaves after compensating its own
(`robot.JOINT_FRICTION["compensated"]`), with Menagerie's identified friction kept as a mode."""

from __future__ import annotations

import numpy as np
import pytest

from hamnet.messages.safe_command import hold_command
from hamnet.sim.config import SimConfig
from hamnet.sim.env import VectorEnv
from hamnet.sim.robot import JointDynamicsRandomization
from hamnet.task.physics import PHYSICS_PARAM_NAMES

B = 4
RESIDUAL = 0.02
"""Joint-1 residual asked for one policy step, rad (a small one: 8% of the authors' bound)."""
KP = 105.0
"""Middle of the impedance range [10, 200], N m/rad."""


def joint1_motion(joint_dynamics: JointDynamicsRandomization) -> np.ndarray:
    """(B,) joint-1 motion (rad) in one policy step towards a target RESIDUAL ahead of the
    episode start, on every sample (the training profile's references), at KP, rho 1."""
    env = VectorEnv(SimConfig(num_envs=B, nthread=1, joint_dynamics=joint_dynamics))
    start = env.reset(seed=3).q.astype(np.float64)  # (B, J)
    command = hold_command(start, env.config.control_samples, kp=KP)
    command.q_ref[:, :, 0] += RESIDUAL  # (B, S, J)
    return env.step(command).final_observation.q[:, 0] - start[:, 0]


def test_a_small_residual_moves_the_arm_as_if_it_had_no_joint_friction() -> None:
    """With the identified friction (1.137 N m on joint 1, x0.5-1.5, the default before)
    the arm moved 6-15% of the asked 0.02 rad in the step, 15-34% of what the same arm
    without joint friction moves (39-43%): the friction ate most of a small residual, and
    the policy could barely move the arm. The FR3 under libfranka's torque interface
    compensates its own friction, so in the default sim the same step must move nearly as
    far as the frictionless arm (91-95% measured)."""
    default = joint1_motion(JointDynamicsRandomization())
    frictionless = joint1_motion(JointDynamicsRandomization(friction=(0.0, 0.0)))
    assert np.all(frictionless > 0.2 * RESIDUAL)  # the same episodes; the arm moves
    assert np.all(default >= 0.85 * frictionless), default / frictionless


@pytest.mark.parametrize(
    ("mode", "scale", "joint1"),
    [("compensated", (0.0, 0.1), (0.0, 0.1137)), ("identified", (0.5, 1.5), (0.5685, 1.7055))],
)
def test_each_friction_mode_writes_its_friction_and_reports_it(
    mode: str, scale: tuple[float, float], joint1: tuple[float, float]
) -> None:
    """The identified mode keeps the friction the sim had before (Menagerie's 1.137 ...
    0.248 N m times U(0.5, 1.5)); the compensated mode, the default, 0-10% of it. Either way
    `joint_friction_scale` is the friction each episode has as a fraction of the identified,
    so the privileged input means the same in both."""
    ranges = JointDynamicsRandomization(friction_mode=mode)  # type: ignore[arg-type]
    assert ranges.friction_scale == pytest.approx(scale)
    env = VectorEnv(SimConfig(num_envs=8, nthread=1, joint_dynamics=ranges))
    params = dict(zip(PHYSICS_PARAM_NAMES, env.reset(seed=4).physics_params.T, strict=True))
    column = params["joint_friction_scale"]  # (B,)
    assert np.all((column >= scale[0]) & (column <= scale[1])) and np.ptp(column) > 0.1 * scale[1]
    dofs = env.world.robot_dof
    identified = env.world.model.dof_frictionloss[dofs]  # (J,) N m
    np.testing.assert_allclose(identified, [1.137] * 4 + [0.763, 0.44, 0.248])
    written = env.physics.fields["dof_frictionloss"][:, dofs]  # (B, J) N m
    np.testing.assert_allclose(written, column[:, None] * identified, rtol=1e-6)
    assert np.all((written[:, 0] >= joint1[0]) & (written[:, 0] <= joint1[1]))


def test_compensated_is_the_default_and_a_bad_mode_or_range_fails_loudly() -> None:
    assert SimConfig().joint_dynamics.friction_mode == "compensated"
    with pytest.raises(ValueError, match="friction_mode"):
        JointDynamicsRandomization(friction_mode="compensate")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="friction"):
        JointDynamicsRandomization(friction=(-0.1, 1.0))
    custom = JointDynamicsRandomization(friction_mode="identified", friction=(0.8, 1.2))
    assert custom.friction_scale == (0.8, 1.2)
