"""Test helpers: real sim messages (the sim's own shell, stepped by hold commands), the
messages of the services not built yet, and an .rrd file read back by entity."""

from __future__ import annotations

from collections import defaultdict
from dataclasses import replace
from pathlib import Path

import numpy as np
import pyarrow as pa
import rerun

from hamnet.proto.common_pb2 import Header
from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.runtime.codec import encode
from hamnet.runtime.service import ServiceIdentity
from hamnet.runtime.tensor import from_tensor, to_tensor
from hamnet.sim import quaternion
from hamnet.sim.commands import hold_command
from hamnet.sim.config import SimConfig
from hamnet.sim.env import VectorEnv
from hamnet.sim.shell import LoopConfig, SimShell
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
    SimShell(service, env, LoopConfig()).run()
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
        self.view_origins: list[str] = [
            origin[0]
            for store in reader.blueprints()
            for chunk in reader.stream(store=store).to_chunks()
            if "ViewBlueprint:space_origin" in (batch := chunk.to_record_batch()).schema.names
            for origin in batch.column("ViewBlueprint:space_origin").to_pylist()
        ]
        """Origin entity of every view of the file's blueprint."""

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
