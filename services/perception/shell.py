"""The perception service's Zenoh shell: clouds and UniCORN tokens for every state.

Consumes `sim/<w>/scene` (Scene: the environments starting an episode, published before the
state of that step) and `sim/<w>/state` (RobotState: `header.step` k, `episode_ids`, and
`privileged.object_pose`). Produces `perception/<w>/tokens` (PerceptionTokens k, with the
state's step and episode ids, so the policy pairs them by step) for all B environments.

`encoder_version` is the version of the encoder weights; 0 means random weights
(`--random-init` or a random checkpoint), so a consumer can tell untrained tokens apart.

A state is answered only when every environment's cached scene belongs to its current
episode; otherwise it waits (counted as `waiting_for_scene`) and is answered as soon as the
scene arrives (Zenoh orders messages per key, not across keys, so a scene may follow its
state); meanwhile the sim is asked for its scenes (a service started late missed them). A
state sent again gets the same answer.
A state without the privileged object pose (the real bridge) is dropped and counted: the
object cloud must then come from the depth cameras (`--clouds-from cameras`,
`hamnet.perception.camera_shell`).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Annotated

import torch

from hamnet.messages import robot_state, scene
from hamnet.messages.robot_state import StateIn
from hamnet.messages.tokens import encode as encode_tokens
from hamnet.perception.config import CloudConfig
from hamnet.perception.core import EpisodeScenes, Perception
from hamnet.perception.unicorn import UniCORN
from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.proto.sim_pb2 import RobotState, Scene
from hamnet.runtime.cli import Flattened
from hamnet.runtime.codec import parse
from hamnet.runtime.compute import torch_device
from hamnet.runtime.loop_report import LoopReport, Window
from hamnet.runtime.ports import Ports
from hamnet.runtime.service import Service
from hamnet.runtime.shell_config import ComputeConfig, ReportConfig
from hamnet.runtime.tensor import PayloadError

log = logging.getLogger(__name__)

PORTS = Ports(
    inputs={"state": "sim/<w>/state", "scene": "sim/<w>/scene", "frames": "camera/<w>/frames"},
    outputs={"tokens": "perception/<w>/tokens", "object_pose": "perception/<w>/object_pose"},
)
"""What perception reads and writes (`hamnet.runtime.ports`): frames and object_pose with
`--clouds-from cameras` (`camera_shell`), scene without."""


# --- decode / encode: pure functions, tested without a session -------------------------


def decode_state(message: RobotState, num_envs: int | None) -> StateIn:
    """RobotState k with its episode ids and privileged block (the sim's object pose);
    `num_envs` None accepts any batch size.

    Raises:
        PayloadError: `missing` (no episode ids, or no privileged object pose: a real robot
            needs the camera path), `dtype`, `shape`, `nonfinite`.
    """
    state = robot_state.decode(message, num_envs, required=("episode_ids",))
    if state.privileged is None:
        raise PayloadError(
            "missing",
            "RobotState.privileged.object_pose is not set: without the sim's object pose the "
            "object cloud must come from depth cameras (hamnet perception --clouds-from cameras)",
        )
    return state


_SCENE_READS = ("episode_ids", "cuboid_pos", "cuboid_quat", "cuboid_half_size", "cuboid_active",
                "object_points")  # fmt: skip


def decode_scene(message: Scene, num_envs: int | None, num_points: int) -> EpisodeScenes:
    """The K scenes of a Scene message as CPU tensors.

    Raises:
        PayloadError: `missing`, `dtype`, `shape` (counts disagree, object points not
            (K, num_points, 3)), `nonfinite`, `range` (an environment index outside [0, B),
            or a scene without any active cuboid).
    """
    decoded = scene.decode(message, _SCENE_READS, num_envs=num_envs, num_points=num_points)
    if len(decoded.env_ids) and not decoded.cuboid_active.any(1).all():
        raise PayloadError("range", "Scene holds a scene without any active cuboid")
    return EpisodeScenes.from_arrays(
        decoded.env_ids, decoded.episode_ids, decoded.cuboid_pos, decoded.cuboid_quat,
        decoded.cuboid_half_size, decoded.cuboid_active, decoded.object_points,
    )  # fmt: skip


# --- the loop ------------------------------------------------------------------------------


@dataclass(frozen=True)
class PerceptionLoopConfig:
    """Batch size, device and reporting of the shell (both paths: sim scenes, camera frames)."""

    num_envs: int = 0
    """B, environments per state; 0 takes it from the first state."""
    compute: Annotated[ComputeConfig, Flattened] = field(default_factory=ComputeConfig)
    report: Annotated[ReportConfig, Flattened] = field(default_factory=ReportConfig)

    def __post_init__(self) -> None:
        if self.num_envs < 0:
            raise ValueError(f"num_envs must be >= 0, got {self.num_envs}")


class PerceptionShell:
    """One perception worker on the network."""

    def __init__(
        self,
        service: Service,
        encoder: UniCORN,
        version: int,
        config: PerceptionLoopConfig | None = None,
        clouds: CloudConfig | None = None,
    ) -> None:
        self.service, self.encoder, self.version = service, encoder, version
        self.config = config if config is not None else PerceptionLoopConfig()
        self.clouds = clouds if clouds is not None else CloudConfig()
        self.device = torch_device(self.config.compute.device, self.config.compute.threads)
        port = service.ports(PORTS)
        self.num_envs: int | None = self.config.num_envs or None
        self.scene_key = port["scene"]
        service.inbox.subscribe("scene", self.scene_key, decoder=self._decode_scene)
        service.inbox.subscribe("state", port["state"], decoder=self._decode_state)
        self.tokens = service.publisher(port["tokens"])
        self.core: Perception | None = None
        self.pending: list[EpisodeScenes] = []
        """Scenes received before the first state (which fixes B)."""
        self.waiting: StateIn | None = None
        """The newest state whose scenes have not all arrived: answered when they do (Zenoh
        does not order messages across keys, so a scene may follow its state)."""
        self.answered: tuple[tuple[int, int], PerceptionTokens] | None = None
        """((run, step), tokens) of the last state answered."""
        self.report = LoopReport(self.config.report.report_period_s, self._line, logger=log)
        self.counts = self.report.counts
        """What happened since the last rate line."""

    def run(self) -> int:
        """Answer states until stopped; returns the exit status."""
        random = " (random weights)" if self.version == 0 else ""
        log.info("encoder version %d%s on %s", self.version, random, self.device)
        while self.service.running:
            received = self.service.receive(timeout=0.1)
            if received is not None:
                if received.name == "scene":
                    self._on_scene(received.value)
                else:
                    self._on_state(received.value)
            self.report.tick()
        return 0

    def _on_scene(self, scenes: EpisodeScenes) -> None:
        if self.core is None:
            self.pending.append(scenes)
            return
        self.core.start_episodes(scenes)
        if self.waiting is not None:  # the state came first: answer it now that it can be
            state, self.waiting = self.waiting, None
            self._on_state(state)

    def _on_state(self, state: StateIn) -> None:
        if self.answered is not None and self.answered[0] == (state.run, state.step):
            self.tokens.put(self.answered[1])  # the sim sent it again: same answer
            self.counts["repeated"] += 1
            return
        if self.core is None:
            self.num_envs = len(state.episode_ids)
            self.core = Perception(
                self.encoder, self.num_envs, self.clouds, self.device, self.config.compute.seed
            )
            log.info("%d environments, first state %d", self.num_envs, state.step)
            for scenes in self.pending:
                if len(scenes.env_ids) and int(scenes.env_ids.max()) >= self.num_envs:
                    self.service.drops.drop(self.scene_key,
                                            "range", "scene for an environment beyond the first state's batch")  # fmt: skip
                    continue
                self.core.start_episodes(scenes)
            self.pending.clear()
        waiting = self.core.missing(torch.from_numpy(state.episode_ids))
        if len(waiting):
            self.counts["waiting_for_scene"] += 1
            log.debug("state %d: no scene yet for environments %s", state.step, waiting.tolist())
            self.waiting = state
            self.service.inbox.catch_up("scene", self.scene_key)  # we may have started late
            return
        self.waiting = None
        started = time.perf_counter()
        percepts = self.core.step(torch.from_numpy(state.privileged.object_pose))
        message = encode_tokens(percepts, state.step, state.episode_ids, self.version)
        self.tokens.put(message)
        self.answered = ((state.run, state.step), message)
        self.counts["published"] += 1
        self.report.sample("step_s", time.perf_counter() - started)

    def _line(self, w: Window) -> str:
        return (f"{w.rate('published'):.1f} token messages/s, median {w.median_ms('step_s'):.1f} "
                f"ms per step, {w.count('repeated')} repeated, {w.count('waiting_for_scene')} "
                "states waiting for their scene")  # fmt: skip

    def _decode_state(self, key: str, payload: bytes) -> StateIn:
        return decode_state(parse(RobotState, payload), self.num_envs)

    def _decode_scene(self, key: str, payload: bytes) -> EpisodeScenes:
        return decode_scene(parse(Scene, payload), self.num_envs, self.clouds.num_points)
