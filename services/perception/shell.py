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
state sent again gets the same answer; a state older than the last answered is dropped
(counted as stale), unless it comes from another run of the sim, which is followed at once,
as the policy does (`hamnet.runtime.freshness`).
A state without the privileged object pose (the real bridge) is dropped and counted: the
object cloud must then come from the depth cameras (`--clouds-from cameras`,
`hamnet.perception.camera_shell`). Without Zenoh: decode (`hamnet.perception.messages`), the
clouds and tokens (`hamnet.perception.core`).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Annotated

import torch

from hamnet.messages.robot_state import StateIn
from hamnet.messages.tokens import encode as encode_tokens
from hamnet.perception.config import CloudConfig
from hamnet.perception.core import EpisodeScenes, Perception
from hamnet.perception.messages import decode_scene, decode_state
from hamnet.perception.unicorn import UniCORN
from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.proto.sim_pb2 import RobotState, Scene
from hamnet.runtime.cli import Flattened
from hamnet.runtime.codec import payload_decoder
from hamnet.runtime.compute import torch_device
from hamnet.runtime.freshness import Answered, Verdict
from hamnet.runtime.loop_report import LoopReport, Window
from hamnet.runtime.ports import Ports
from hamnet.runtime.service import Service
from hamnet.runtime.shell_config import ComputeConfig, ReportConfig

log = logging.getLogger(__name__)

PORTS = Ports(
    inputs={"state": "sim/<w>/state", "scene": "sim/<w>/scene", "frames": "camera/<w>/frames"},
    outputs={"tokens": "perception/<w>/tokens", "object_pose": "perception/<w>/object_pose"},
)
"""What perception reads and writes (`hamnet.runtime.ports`): frames and object_pose with
`--clouds-from cameras` (`camera_shell`), scene without."""


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
        scene = lambda m: decode_scene(m, self.num_envs, self.clouds.num_points)
        state = lambda m: decode_state(m, self.num_envs)
        service.inbox.subscribe("scene", self.scene_key, decoder=payload_decoder(Scene, scene))
        service.inbox.subscribe("state", port["state"], decoder=payload_decoder(RobotState, state))
        self.tokens = service.publisher(port["tokens"])
        self.core: Perception | None = None
        self.pending: list[EpisodeScenes] = []
        """Scenes received before the first state (which fixes B)."""
        self.waiting: StateIn | None = None
        """The newest state whose scenes have not all arrived: answered when they do (Zenoh
        does not order messages across keys, so a scene may follow its state)."""
        self.answered: Answered[PerceptionTokens] = Answered()
        """The sim's run followed, the last step answered in it and its tokens."""
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
        verdict = self.answered.follow(state.run, state.step)
        if verdict is Verdict.REPEAT:
            self.tokens.put(self.answered.message)  # the sim sent it again: same answer
            self.counts["repeated"] += 1
            return
        if verdict in (Verdict.STALE, Verdict.IMPLAUSIBLE):
            self.counts[verdict.value] += 1
            return
        if verdict is Verdict.RESTART:
            log.warning("the sim restarted (another run): following it from step %d", state.step)
        if self.core is None:
            self.num_envs = len(state.episode_ids)
            self.core = Perception(
                self.encoder, self.num_envs, self.clouds, self.device, self.config.compute.seed
            )
            log.info("%d environments, first state %d", self.num_envs, state.step)
            for scenes in self.pending:
                if len(scenes.env_ids) and int(scenes.env_ids.max()) >= self.num_envs:
                    self.service.drops.drop(
                        self.scene_key,
                        "range",
                        "scene for an environment beyond the first state's batch",
                    )
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
        self.answered.answer(state.step, message)
        self.counts["published"] += 1
        self.report.sample("step_s", time.perf_counter() - started)

    def _line(self, w: Window) -> str:
        return (
            f"{w.rate('published'):.1f} token messages/s, median {w.median_ms('step_s'):.1f} "
            f"ms per step, {w.count('repeated')} repeated, {w.count('stale')} stale, "
            f"{w.count('waiting_for_scene')} states waiting for their scene"
        )
