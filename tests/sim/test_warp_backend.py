"""The `warp` backend (`--sim.backend warp`: MuJoCo Warp on its CPU device) against the C
engine: the same commands give the same trajectories, rewards, terminations and resets,
with contacts (the paddle pushing the object, the arm against a cabinet), and a snapshot
restores on it. The first test compiles Warp's kernels (about a minute on 2 cores, cached
on disk after)."""

from __future__ import annotations

import dataclasses
import os

import numpy as np
import pytest

from hamnet.evaluation.arm_events import ArmEvents
from hamnet.messages.safe_command import hold_command
from hamnet.sim.config import SimConfig
from hamnet.sim.env import StepResult, VectorEnv
from hamnet.sim.stages import stage_config
from hamnet.sim.warp_physics import WarpPhysics

pytestmark = pytest.mark.warp

DEVICE = os.environ.get("HAMNET_WARP_DEVICE", "cpu")
"""Warp's device: its CPU device by default, `cuda` in scripts/warp_gpu_check.sh."""

B = 4
Q_TOLERANCE = 1e-2
"""rad: float32 against float64 over 30 steps of contact (measured: up to 7.7e-3 with the
arm sweeping along a cabinet, 1e-3 pushing an object, 5e-6 without contact)."""
POSITION_TOLERANCE = 2e-3
"""m, for the object (measured: up to 1.8e-4 while pushed)."""


def pair(config: SimConfig, seed: int) -> tuple[VectorEnv, VectorEnv]:
    """The C and the Warp backend on `config`, reset with `seed`."""
    warp = dataclasses.replace(config, backend="warp", warp_device=DEVICE)
    c, w = VectorEnv(config), VectorEnv(warp)
    assert isinstance(w.physics, WarpPhysics) and not isinstance(c.physics, WarpPhysics)
    c.reset(seed=seed)
    w.reset(seed=seed)
    return c, w


def drive(c: VectorEnv, w: VectorEnv, drift: np.ndarray, steps: int) -> list[StepResult]:
    """`steps` steps of both, each commanded to its current q plus `drift` (J,); asserts
    they agree at every step and returns the C backend's results."""
    results = []
    for _ in range(steps):
        command = hold_command(c.observe().q + drift, c.config.control_samples)
        rc, rw = c.step(command), w.step(command)
        oc, ow = rc.observation, rw.observation
        np.testing.assert_allclose(ow.q, oc.q, atol=Q_TOLERANCE)
        np.testing.assert_allclose(
            ow.object_pose[:, :3], oc.object_pose[:, :3], atol=POSITION_TOLERANCE
        )
        np.testing.assert_allclose(rw.reward_terms, rc.reward_terms, atol=1e-3)
        np.testing.assert_array_equal(rw.terminated, rc.terminated)
        np.testing.assert_array_equal(rw.truncated, rc.truncated)
        np.testing.assert_array_equal(ow.episode_ids, oc.episode_ids)
        results.append(rc)
    return results


def test_the_paddle_pushes_the_object_alike() -> None:
    """The easy stage starts the paddle behind the object; drawing joints 2 and 4 back
    pushes it by more than 5 mm in some environment, the same on both."""
    c, w = pair(stage_config("easy", num_envs=B, num_objects=4, nthread=1, seed=3), seed=3)
    start = c.observe().object_pose[:, :3].copy()
    drift = np.zeros(7)
    drift[[1, 3]] = -0.03
    drive(c, w, drift, 30)
    assert np.linalg.norm(c.observe().object_pose[:, :3] - start, axis=1).max() > 0.005


def test_the_arm_against_a_cabinet_stops_alike() -> None:
    """Lifting joint 2 in the cabinet domain drives arm links into its boards in many
    steps; both backends hold the arm there alike."""
    config = stage_config("full", num_envs=B, num_objects=4, nthread=1, seed=1)
    c, w = pair(dataclasses.replace(config, domain="cabinet"), seed=1)
    events, hits = ArmEvents(c), 0
    drift = np.zeros(7)
    drift[1] = 0.05
    for _ in range(30):
        drive(c, w, drift, 1)
        hits += int(events.collided(np.arange(B)).any())
    assert hits >= 5


def test_resets_draw_the_same_episodes_on_procedural_scenes() -> None:
    """Full-stage scenes (plates, ramps, walls) with 3-step episodes: every reset inside
    `step` draws the same episode on both, and they stay together."""
    config = stage_config("full", num_envs=B, num_objects=4, nthread=1, seed=2)
    config = dataclasses.replace(config, task=dataclasses.replace(config.task, timeout=3))
    c, w = pair(config, seed=2)
    results = drive(c, w, np.full(7, 0.01), 10)
    assert sum(len(r.reset_ids) for r in results) >= B
    np.testing.assert_allclose(w.scenes().cuboid_centre, c.scenes().cuboid_centre)


def test_a_snapshot_restores_on_the_warp_backend() -> None:
    """Steps after a restore repeat the steps after the snapshot."""
    config = dataclasses.replace(
        stage_config("easy", num_envs=B, num_objects=2, nthread=1),
        backend="warp",
        warp_device=DEVICE,
    )
    env = VectorEnv(config)
    env.reset(seed=0)
    saved = env.snapshot()
    command = hold_command(env.observe().q + 0.02, config.control_samples)
    first = [env.step(command).observation.q.copy() for _ in range(3)]
    env.restore(*saved)
    again = [env.step(command).observation.q.copy() for _ in range(3)]
    np.testing.assert_allclose(again, first, atol=1e-6)


def test_an_unknown_backend_is_refused() -> None:
    with pytest.raises(ValueError, match="backend must be 'mujoco' or 'warp'"):
        dataclasses.replace(SimConfig(), backend="bullet")  # type: ignore[arg-type]
