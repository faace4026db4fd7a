"""The sim's arm stops at the FR3's joint limits, whatever a command asks for (issue 29)."""

from __future__ import annotations

import numpy as np

from hamnet.fr3.limits import FR3
from hamnet.messages.safe_command import Command
from hamnet.sim.config import SimConfig
from hamnet.sim.env import VectorEnv
from hamnet.sim.robot import TIMESTEP
from hamnet.sim.scene_config import SceneConfig

UPRIGHT = np.array([0.0, 0.0, 0.0, -0.2, 0.0, 1.5, np.pi / 4])
"""Arm nearly straight up: joint 1 turns it through its whole range without touching any
table, whatever its height (walls and ceilings are off in the test's scenes)."""

RUN_UPS = (0.3, 1.0, 3.0, 5.75)
"""Distance from joint 1's start to its upper limit, rad (5.75: from its lower end)."""

GAINS = ((200.0, 1.0), (1e4, 0.0))
"""(kp N m/rad, rho): the top of the policy's impedance range, critically damped; and what
a forged command could send, all the 87 N m torque clip allows and no damping."""

STEPS = 280
"""Physics steps driven (0.7 s, inside the 300-step timeout: no episode ends)."""


def test_the_batch_steps_the_arm_with_the_fr3s_ranges_as_stiff_limits() -> None:
    """Every simulation of the batch (not only the compiled world) has each arm joint limited
    to Franka's range, with the limit's time constant at 2 * TIMESTEP."""
    env = VectorEnv(SimConfig(num_envs=2, num_objects=3, nthread=1))
    joints = env.world.model.dof_jntid[env.world.robot_dof]  # (J,)
    for sim in range(env.num_envs):
        model = env.physics.batch.get_model(sim)
        assert model.jnt_limited[joints].all()
        np.testing.assert_array_equal(model.jnt_range[joints, 0], FR3.q_min)
        np.testing.assert_array_equal(model.jnt_range[joints, 1], FR3.q_max)
        np.testing.assert_allclose(model.jnt_solref[joints], [[2 * TIMESTEP, 1.0]] * 7)
        np.testing.assert_array_equal(model.jnt_margin[joints], 0.0)


def test_a_reference_far_past_joint_1s_limit_stops_at_the_limit() -> None:
    """Joint 1 driven at `GAINS` towards q_max + 1 rad from `RUN_UPS` before its limit (8
    environments): it reaches the limit at 0.25-19 rad/s (the FR3's own speed limit is
    2.62 rad/s) and must stop there, within 1.5 physics steps' travel at that speed.

    The limit is MuJoCo's joint-limit constraint (range, limited). It is soft: past the limit
    it pulls the joint back like a critically damped spring of time constant tau
    (solreflimit), so a joint arriving at speed v goes about v*tau/e beyond it, and the
    discrete step adds to that. With MuJoCo's default tau = 0.02 s (8 steps) the arm overshot
    by 2.6-3.6 steps' travel: 0.0018-0.14 rad, 0.069 rad at kp 200 from the lower end and
    0.14 at the forged gains (the issue saw 0.042 rad, joint 1 at 2.943, on a plain stack).
    The model's tau = 2 * TIMESTEP = 5 ms, the stiffest MuJoCo accepts, gives v*tau/e = 0.74
    step's travel; measured 0.27-0.87 (0.0004-0.041 rad, at most 0.0084 at kp 200). The
    tolerance, 1.5 steps' travel at the arrival speed (0.0009 rad at 0.25 rad/s, 0.071 at
    19), sits between the two with a 1.7x margin each side.

    The sim observes every physics step (one per env step), so the peak is never missed:
    the penetration lasts a few milliseconds, less than a 0.1 s policy period.
    """
    config = SimConfig(
        num_envs=len(RUN_UPS) * len(GAINS),
        num_objects=3,
        nthread=1,
        policy_period_s=TIMESTEP,
        control_samples=1,
        scene=SceneConfig(p_ceiling=0.0, p_wall=0.0),
    )
    env = VectorEnv(config)
    start = env.reset(seed=0).q.astype(np.float64)  # (B, J)
    assert np.all((start > FR3.q_min) & (start < FR3.q_max))  # episodes start inside the ranges
    b = env.num_envs
    kp, rho = (np.repeat(column, len(RUN_UPS)) for column in zip(*GAINS, strict=True))  # (B,)
    q = np.tile(UPRIGHT, (b, 1))  # (B, J)
    q[:, 0] = FR3.q_max[0] - np.tile(RUN_UPS, len(GAINS))
    p, w = env.physics, env.world
    object_qpos = p.qpos[:, w.object_qpos].copy()  # (B, 7) where the reset put the objects
    p.set_state(np.arange(b), q, object_qpos[:, :3], object_qpos[:, 3:])
    q_ref = q.copy()
    q_ref[:, 0] = FR3.q_max[0] + 1.0
    command = Command(
        q_ref=q_ref[:, None, :],  # (B, S=1, J)
        kp=np.tile(kp[:, None], (1, 7)),
        kd=np.tile((rho * np.sqrt(kp))[:, None], (1, 7)),
        tau_limit=np.tile(FR3.tau_max, (b, 1)),
    )
    q1, dq1 = np.zeros((STEPS, b)), np.zeros((STEPS, b))
    for step in range(STEPS):
        result = env.step(command)
        assert len(result.reset_ids) == 0
        q1[step] = result.observation.q[:, 0]
        dq1[step] = result.observation.dq[:, 0]
    past = q1 > FR3.q_max[0]  # (T, B)
    assert past.any(axis=0).all()  # every joint reached its limit
    arrival = dq1[past.argmax(axis=0) - 1, np.arange(b)]  # (B,) speed the step before, rad/s
    overshoot = q1.max(axis=0) - FR3.q_max[0]  # (B,) rad
    tolerance = 1.5 * arrival * TIMESTEP  # (B,) rad
    assert np.all(overshoot <= tolerance), (overshoot, arrival)
