"""Test helpers: real sim messages (the sim's own shell, stepped by hold commands), the
messages of the services not built yet, and an .rrd file read back by entity."""

from __future__ import annotations

from collections import defaultdict
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import pyarrow as pa
import rerun

from hamnet.messages.safe_command import hold_command
from hamnet.proto.common_pb2 import Header
from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.proto.safety_pb2 import SafetyEvent, SafetyEventKind
from hamnet.proto.trainer_pb2 import Metrics
from hamnet.runtime.codec import encode
from hamnet.runtime.service import ServiceIdentity
from hamnet.runtime.tensor import from_tensor, to_tensor
from hamnet.sim import quaternion
from hamnet.sim.config import SimConfig
from hamnet.sim.env import VectorEnv
from hamnet.sim.shell import SimLoopConfig, SimShell
from hamnet.task.rewards import REWARD_NAMES
from hamnet.trainer.algorithms.ppo import UpdateStats
from hamnet.trainer.publisher import encode_metrics
from tests.scripted import ScriptedService
from tests.sim.test_shell import safe_command

B, S, J = 2, 8, 7
L, M, P = 5, 8, 64
"""Base-network layers, modules, points per cloud of the scripted policy and perception."""


def sim_messages(steps: int, timeout: int = 3) -> list[tuple[str, object]]:
    """What a real sim of B environments publishes over `steps` steps held still, episodes
    of `timeout` steps: (topic, message) in publish order, through the wire format."""
    config = SimConfig(num_envs=B, num_objects=2, nthread=1)
    env = VectorEnv(replace(config, task=replace(config.task, timeout=timeout)))
    seen: set[int] = set()

    def script(published):
        state = [m for topic, m in published if topic == "state"][-1]
        step = state.header.step
        if step in seen or step >= steps:
            return None
        seen.add(step)
        command = hold_command(from_tensor(state.q, np.float32, (B, J)), S)
        return "command", encode(safe_command(command, step))

    service = ScriptedService(script, identity=ServiceIdentity("sim", "0"))
    SimShell(service, env, SimLoopConfig()).run()
    return service.published


def tokens(step: int, rng: np.random.Generator) -> PerceptionTokens:
    """PerceptionTokens of step `step`: random clouds (B, P, 3), tokens (B, 17, 8)."""
    message = PerceptionTokens(header=Header(step=step))
    for name in ("object_cloud", "environment_cloud", "local_cloud"):
        to_tensor(rng.uniform(-1, 1, (B, P, 3)).astype(np.float32), getattr(message, name))
    for name in ("object_tokens", "local_tokens", "global_tokens"):
        to_tensor(rng.standard_normal((B, 17, 8)).astype(np.float32), getattr(message, name))
    to_tensor(np.arange(B, dtype=np.int64), message.episode_ids)
    return message


def action(step: int, rng: np.random.Generator) -> PolicyAction:
    """PolicyAction of step `step` with module weights (B, L, M), a softmax per layer."""
    message = PolicyAction(header=Header(step=step, policy_version=3))
    logits = rng.standard_normal((B, L, M))
    weights = np.exp(logits) / np.exp(logits).sum(axis=-1, keepdims=True)  # (B, L, M)
    to_tensor(weights.astype(np.float32), message.module_weights)
    to_tensor(rng.standard_normal((B, 21)).astype(np.float32), message.action)
    to_tensor(rng.standard_normal((B, 3)).astype(np.float32), message.values)
    to_tensor(np.zeros(B, np.float32), message.log_prob)
    return message


TRANSITIONS_PER_ITERATION = 64 * 64
"""env_transitions of one scripted trainer iteration (64 steps of 64 environments)."""


def metrics(iteration: int, rng: np.random.Generator) -> Metrics:
    """Metrics of iteration `iteration` as the trainer publishes them (its own
    `encode_metrics`) for a row with the keys of `Runner.iterate`, of a run that learns:
    the success rate rises from 0.1 towards 0.6, with noise."""
    success = 0.6 - 0.5 * np.exp(-iteration / 8) + 0.03 * rng.standard_normal()
    stats = UpdateStats(policy_loss=-0.01 * rng.random(), value_loss=1.0 / (1 + iteration),
                        bound_loss=0.0, approx_kl=0.016 * rng.uniform(0.5, 1.5),
                        clip_fraction=0.2 * rng.random(), learning_rate=3e-4,
                        gradient_steps=64, early_stopped=False)  # fmt: skip
    returns = {f"return/{name}": float(v) for name, v in
               zip(REWARD_NAMES, (10 * success, 0.5 + 0.02 * iteration, -0.1), strict=True)}  # fmt: skip
    row = {
        "iteration": iteration,
        "env_transitions": iteration * TRANSITIONS_PER_ITERATION,
        "env_steps_per_s": 1500 + 100 * rng.standard_normal(),
        "collect_s": 2.0,
        "learn_s": 0.7,
        "log_std": -0.5 - 0.01 * iteration,
        **asdict(stats),
        "policy_lag": 0,
        **returns,
        "return/total": sum(returns.values()),
        "episodes": 100,
        "success_rate": float(np.clip(success, 0, 1)),
        "episode_length": 80 - 2 * success,
    }
    return encode_metrics(row, iteration)


def dagger_metrics(iteration: int, rng: np.random.Generator) -> Metrics:
    """Metrics of DAgger iteration `iteration` (the keys of a DAgger run's rows): the
    imitation loss falling, beta half way down."""
    success = float(rng.uniform(0.05, 0.15))
    terms = (success, 0.01, 0.1)
    returns = {f"return/{name}": v for name, v in zip(REWARD_NAMES, terms, strict=True)}
    row = {
        "iteration": iteration,
        "env_transitions": iteration * TRANSITIONS_PER_ITERATION,
        "env_steps_per_s": 120.0,
        "collect_s": 4.0,
        "learn_s": 0.5,
        "beta": 0.5,
        "student_share": 0.5,
        "imitation_loss": 0.3 / iteration,
        "imitation_loss_after": 0.2 / iteration,
        "value_loss": 0.0,
        "gradient_norm": 0.4,
        "learning_rate": 3e-4,
        **returns,
        "episodes": 64,
        "success_rate": success,
        "episode_length": 90.0,
        "student_episodes": 32,
        "student_episode_success": success / 2,
        "velocity_loss": 0.5 / iteration,
    }
    return encode_metrics(row, iteration)


def clip_event(step: int, env: int) -> SafetyEvent:
    """The Cartesian clip clipped 2 of 10 commands at `step`, in environment `env`."""
    message = SafetyEvent(header=Header(step=step), kind=SafetyEventKind.CLIPPED_CARTESIAN,
                          stage="cartesian_clip", reason="clipped 2 of 10 commands")  # fmt: skip
    to_tensor(np.array([env], np.int32), message.env_ids)
    return message


def statistics_event(step: int) -> SafetyEvent:
    """Statistics at `step`: a quarter clipped by the Cartesian clip, none by the joint
    limits, no command through the torque pre-clip."""
    message = SafetyEvent(header=Header(step=step), stage="", reason="statistics over 5 s")
    message.stages.add(stage="cartesian_clip", commands=40, clipped=10, max_excess=0.1)
    message.stages.add(stage="joint_limits", commands=40, clipped=0)
    message.stages.add(stage="torque_preclip", commands=0, clipped=0)
    return message


EE_OFFSET = np.array([0.0, 0.0, 0.09])
"""Site `ee` in the paddle body's frame, m (fr3.xml)."""


def xyzw_matrix(quat: list[float]) -> np.ndarray:
    """Rotation matrix (3, 3) of a Rerun (xyzw) quaternion."""
    x, y, z, w = quat
    return quaternion.to_matrix(np.array([w, x, y, z]))


def drawn_ee(rrd: Rrd, step: int) -> np.ndarray:
    """Where the drawn paddle puts site `ee` at `step`, (3,) m."""
    translation = rrd.rows("/robot/fr3_paddle", "Transform3D:translation")[step][0]
    quat = rrd.rows("/robot/fr3_paddle", "Transform3D:quaternion")[step][0]
    return np.array(translation) + xyzw_matrix(quat) @ EE_OFFSET


class Rrd:
    """An .rrd file read back: its chunks' record batches by entity path."""

    def __init__(self, path: Path) -> None:
        self.batches: dict[str, list[tuple[bool, pa.RecordBatch]]] = defaultdict(list)
        reader = rerun.chunk.RrdReader(path)
        for chunk in reader.stream().to_chunks():
            self.batches[chunk.entity_path].append((chunk.is_static, chunk.to_record_batch()))
        self.blueprint: list[pa.RecordBatch] = [
            chunk.to_record_batch()
            for store in reader.blueprints()
            for chunk in reader.stream(store=store).to_chunks()
        ]
        """The record batches of the file's blueprint."""
        self.view_origins: list[str] = [v[0] for v in self.blueprint_values("ViewBlueprint:space_origin")]
        """Origin entity of every view of the file's blueprint."""

    def blueprint_values(self, column: str) -> list:
        """Every value of `column` in the blueprint (None where a row lacks it left out)."""
        values = [v for b in self.blueprint if column in b.schema.names for v in b.column(column).to_pylist()]
        return [v for v in values if v is not None]

    @property
    def entities(self) -> set[str]:
        """Every entity path in the file."""
        return set(self.batches)

    def static(self, entity: str, column: str) -> list:
        """Values of `column` logged static at `entity`."""
        return [v for s, b in self.batches[entity] if s for v in b.column(column).to_pylist()]

    def rows(self, entity: str, column: str, timeline: str = "step") -> dict[int, object]:
        """{time on `timeline`: value of `column`} of the temporal rows at `entity` (the
        last row logged at a time wins)."""
        rows = {}
        for static, batch in self.batches[entity]:
            if static or column not in batch.schema.names:
                continue
            times, values = batch.column(timeline).to_pylist(), batch.column(column).to_pylist()
            rows.update((t, v) for t, v in zip(times, values, strict=True) if v is not None)
        return dict(sorted(rows.items()))
