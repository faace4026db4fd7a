"""The policy service's Zenoh shell: one batch of actions for every paired state and tokens.

Consumes `sim/<w>/state` (RobotState k), `perception/<w>/tokens` (PerceptionTokens k, the
same step), `sim/<w>/scene` (EnvCode of reset environments, for the EnvCode oracle),
`trainer/weights` (WeightsAnnouncement) and `trainer/schedule` (Schedule: the log std follows
its `env_transitions`; until one arrives, the weights' own log std serves). Produces
`policy/<w>/action` (PolicyAction k:
`header.step` = k, `header.policy_version` = the weights' version, raw action, log-prob,
values, module weights). State and tokens are paired by step (`Pairing`); a state sent
again after its answer gets the same answer again. Steps older than the last answered are
dropped, unless the state comes from another run of the sim (`Header.run`): a restarted sim
counts from 0 again, and the policy then follows it at once, with fresh episode carries
(`hamnet.runtime.freshness`; a step implausibly far ahead is refused). The network inputs come from the one
input builder (`hamnet.policy.inputs`: previous action, memory resets, EnvCode cache).
A student reads `RobotState.object_pose_estimate`, the object pose a pose estimator reports on
the real robot (the sim publishes its true pose there, and the estimator's error model is
added unless switched off); only a teacher reads the privileged block.

Hot reload: an announcement is checked (sha256, metadata, architecture, config, tensor
shapes, finiteness) and loaded into a second copy of the network, which replaces the serving
one between two batches; a bad one is logged as an error and the old weights keep serving.
Every batch comes from one version and carries it.

Rollouts from the service chain (`--rollout-horizon T`, off by default): the shell also
consumes `sim/<w>/transition` (Transition k, the outcome of its action k) and publishes
`trainer/<w>/rollout` (RolloutChunk of T steps, `header.policy_version` = the oldest version
that acted), assembled by `hamnet.policy.chunking` from what it served once the trainer is
heard (its first weights announcement or schedule): chunks acted before would only queue up
at the trainer while it starts and make every later update learn from older data.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from hamnet.fr3.limits import NUM_JOINTS as J
from hamnet.policy import inputs as builder
from hamnet.policy.chunking import Chunk, ChunkAssembler
from hamnet.policy.networks import PolicyInputs
from hamnet.policy.observation import POSE_WIDTH, VELOCITY_WIDTH, PoseNoiseConfig, RobotObservation
from hamnet.policy.pairing import Pairing
from hamnet.policy.policy import Action, Policy
from hamnet.policy.registry import build
from hamnet.policy.weights import WeightsError, from_announcement, load_into
from hamnet.proto.common_pb2 import Header
from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.proto.sim_pb2 import RobotState, Scene, Transition
from hamnet.proto.trainer_pb2 import Schedule, WeightsAnnouncement
from hamnet.runtime import contract
from hamnet.runtime.codec import parse
from hamnet.runtime.compute import torch_device
from hamnet.runtime.freshness import Verdict, Watermark
from hamnet.runtime.service import Service
from hamnet.runtime.tensor import PayloadError, field_array, to_tensor
from hamnet.sim.rewards import REWARD_NAMES
from hamnet.trainer.chunks import encode_rollout

log = logging.getLogger(__name__)

STATE = contract.topic("sim/<w>/state")
TOKENS = contract.topic("perception/<w>/tokens")
SCENE = contract.topic("sim/<w>/scene")
WEIGHTS = contract.topic("trainer/weights")
SCHEDULE = contract.topic("trainer/schedule")
ACTION = contract.topic("policy/<w>/action")
TRANSITION = contract.topic("sim/<w>/transition")
ROLLOUT = contract.topic("trainer/<w>/rollout")


# --- decode / encode: pure functions, tested without a session -------------------------


@dataclass(frozen=True)
class StateIn:
    """What the policy reads of RobotState k."""

    run: int
    """The sim's run (`Header.run`)."""
    step: int
    episode_ids: np.ndarray
    """(B,) int64."""
    episode_step: np.ndarray
    """(B,) int32 policy steps since each episode started."""
    robot: RobotObservation


@dataclass(frozen=True)
class TokensIn:
    """PerceptionTokens k."""

    step: int
    episode_ids: np.ndarray
    """(B,) int64."""
    tokens: tuple[torch.Tensor, torch.Tensor, torch.Tensor]
    """Object, local and global tokens, (B, N, D) float32 each."""


def _floats(owner, name: str, shape) -> torch.Tensor:
    """A float32 field as a tensor (one copy out of the read-only wire buffer)."""
    return torch.tensor(field_array(owner, name, np.float32, shape))


def decode_state(message: RobotState, privileged: bool, physics_params: int) -> StateIn:
    """RobotState k: a teacher (`privileged`) reads the privileged block, a student the
    pose estimator's object pose (`object_pose_estimate`), as on the real robot.

    Args:
        physics_params: P, the width of the physics parameters.
    Raises:
        PayloadError: `missing`, `dtype`, `shape`, `nonfinite`.
    """
    q = _floats(message, "q", (None, J))  # (B, J)
    b = len(q)
    if privileged:
        if not message.HasField("privileged"):
            raise PayloadError("missing", "RobotState.privileged is needed by a teacher")
        block = message.privileged
        extra = {
            "object_pose": _floats(block, "object_pose", (b, 7)),
            "object_velocity": _floats(block, "object_velocity", (b, VELOCITY_WIDTH)),
            "physics_params": _floats(block, "physics_params", (b, physics_params)),
        }
    else:
        extra = {"object_pose": _floats(message, "object_pose_estimate", (b, 7))}
    robot = RobotObservation(
        q=q,
        dq=_floats(message, "dq", (b, J)),
        ee_pose=_floats(message, "ee_pose", (b, POSE_WIDTH)),
        goal_pose=_floats(message, "goal_pose", (b, 7)),
        **extra,
    )
    episode_ids = field_array(message, "episode_ids", np.int64, (b,)).copy()
    episode_step = field_array(message, "episode_step", np.int32, (b,)).copy()
    return StateIn(message.header.run, message.header.step, episode_ids, episode_step, robot)


def decode_tokens(message: PerceptionTokens, num_tokens: int, token_dim: int) -> TokensIn:
    """PerceptionTokens k (object, local and global tokens (B, N, D)).

    Raises:
        PayloadError: `missing`, `dtype`, `shape`, `nonfinite`.
    """
    shape = (None, num_tokens, token_dim)
    obj = _floats(message, "object_tokens", shape)
    b = len(obj)
    local = _floats(message, "local_tokens", (b, num_tokens, token_dim))
    whole = _floats(message, "global_tokens", (b, num_tokens, token_dim))
    episode_ids = field_array(message, "episode_ids", np.int64, (b,)).copy()
    return TokensIn(message.header.step, episode_ids, (obj, local, whole))


def decode_scene(message: Scene, env_code_dim: int) -> tuple[np.ndarray, np.ndarray]:
    """(env_ids (K,), env_code (K, 25)) of a Scene."""
    env_ids = field_array(message, "env_ids", np.int32, (None,))
    env_code = field_array(message, "env_code", np.float32, (len(env_ids), env_code_dim))
    return env_ids.copy(), env_code.copy()


@dataclass(frozen=True)
class TransitionIn:
    """Transition k: the outcome of the command that answered state k."""

    step: int
    episode_ids: np.ndarray
    """(B,) int64, before any reset."""
    reward_terms: np.ndarray
    """(B, R) float32, in the order of `REWARD_NAMES`."""
    terminated: np.ndarray
    """(B,) bool."""
    truncated: np.ndarray
    """(B,) bool."""
    success: np.ndarray
    """(B,) bool."""


def decode_transition(message: Transition) -> TransitionIn:
    """Transition k, its reward terms checked against the critic's (`REWARD_NAMES`).

    Raises:
        PayloadError: `missing`, `dtype`, `shape` (other reward terms), `nonfinite`.
    """
    if tuple(message.reward_names) != REWARD_NAMES:
        raise PayloadError("shape", f"reward terms {list(message.reward_names)}, the critic's "
                                    f"are {list(REWARD_NAMES)}")  # fmt: skip
    ids = field_array(message, "episode_ids", np.int64, (None,)).copy()
    b = len(ids)
    flags = {name: field_array(message, name, bool, (b,)).copy()
             for name in ("terminated", "truncated", "success")}  # fmt: skip
    rewards = field_array(message, "reward_terms", np.float32, (b, len(REWARD_NAMES))).copy()
    return TransitionIn(message.header.step, ids, rewards, **flags)


def encode_action(
    step: int, version: int, episode_ids: np.ndarray, action: Action, deterministic: bool
) -> PolicyAction:
    """PolicyAction k: action (B, 21), log_prob (B,), values (B, R), module weights (B, L, M)."""
    message = PolicyAction(
        header=Header(step=step, policy_version=version), deterministic=deterministic
    )
    to_tensor(np.asarray(episode_ids, dtype=np.int64), message.episode_ids)
    for name in ("action", "log_prob", "values", "module_weights"):
        value = getattr(action, name).detach().to("cpu", torch.float32).numpy()
        to_tensor(value, getattr(message, name))
    return message


# --- the loop ----------------------------------------------------------------------------


@dataclass(frozen=True)
class ShellConfig:
    """Inference options of the shell."""

    deterministic: bool = False
    """Serve the distribution's mean (evaluation) instead of samples (rollouts)."""
    device: str = "cpu"
    """torch device for inference: cpu, cuda, cuda:1, ..."""
    threads: int = 1
    """torch CPU threads (1: the services of a stack share the machine's cores)."""
    seed: int = 0
    """Seed of the sampling noise."""
    pending: int = 8
    """Steps that may wait for their other half (state or tokens) before the oldest is
    dropped."""
    report_period_s: float = 10.0
    """Seconds between rate lines in the log."""
    student_pose_noise: bool = True
    """Add the pose estimator's error model (`PoseNoiseConfig`) to a student's object pose:
    on against the sim, off where the pose already comes from an estimator."""
    rollout_horizon: int = 0
    """T > 0: also publish RolloutChunks of T steps for `hamnet trainer` (what was served,
    joined with the sim's transitions); 0: off."""

    def __post_init__(self) -> None:
        if self.pending < 1:
            raise ValueError(f"pending must be >= 1, got {self.pending}")
        if self.rollout_horizon < 0:
            raise ValueError(f"rollout_horizon must be >= 0, got {self.rollout_horizon}")


class PolicyShell:
    """One policy worker on the network: pairing, batched inference, hot reload."""

    def __init__(
        self, service: Service, policy: Policy, version: int, config: ShellConfig | None = None
    ) -> None:
        self.service, self.config = service, config if config is not None else ShellConfig()
        self.device = torch_device(self.config.device, self.config.threads)
        self.policy, self.version = policy.to(self.device).eval(), version
        self.spare: Policy | None = None
        """The second copy that the next weights are loaded into."""
        model = policy.config
        ns, w = service.namespace, service.identity.worker
        inbox = service.inbox
        width = model.observation.physics_params
        inbox.subscribe("state", STATE.key(ns, w=w), decoder=lambda k, p: decode_state(
            parse(RobotState, p), model.privileged, width))
        inbox.subscribe("tokens", TOKENS.key(ns, w=w), decoder=lambda k, p: decode_tokens(
            parse(PerceptionTokens, p), model.num_tokens, model.token_dim))
        inbox.subscribe("scene", SCENE.key(ns, w=w),
                        decoder=lambda k, p: decode_scene(parse(Scene, p), model.env_code_dim))
        inbox.subscribe("weights", WEIGHTS.key(ns),
                        decoder=lambda k, p: parse(WeightsAnnouncement, p))  # fmt: skip
        inbox.subscribe("schedule", SCHEDULE.key(ns),
                        decoder=lambda k, p: int(parse(Schedule, p).env_transitions))
        self.env_transitions: int | None = None
        """The trainer's counter (hamnet.runtime.counter), None before its first Schedule."""
        self.action = service.publisher(ACTION.key(ns, w=w))
        self.assembler: ChunkAssembler | None = None
        """Rollout chunks of what was served (None: `rollout_horizon` 0)."""
        if self.config.rollout_horizon:
            self.assembler = ChunkAssembler(self.config.rollout_horizon)
            inbox.subscribe("transition", TRANSITION.key(ns, w=w),
                            decoder=lambda k, p: decode_transition(parse(Transition, p)))  # fmt: skip
            self.rollout = service.publisher(ROLLOUT.key(ns, w=w))
        self.chunks_sent = 0
        self.trainer_heard = False
        """A weights announcement or schedule has arrived: steps served now join chunks."""
        self.pairing: Pairing[StateIn, TokensIn] = Pairing(self.config.pending)
        self.generator = torch.Generator(self.device).manual_seed(self.config.seed)
        self.env_code = torch.zeros(0, model.env_code_dim, device=self.device)
        """(E, 25) latest EnvCode of every environment (rows grow as scenes arrive)."""
        self.carry: builder.Carry | None = None
        """Previous action and memory of every environment (None before the first step)."""
        self.pose_noise = PoseNoiseConfig() if self.config.student_pose_noise else None
        self.watermark = Watermark()
        """The sim's run followed and the last step answered in it."""
        self.answered: PolicyAction | None = None
        """The answer to the watermark's step, sent again when the sim repeats that state."""
        self.counts = dict.fromkeys(
            ("actions", "resent", "stale", "implausible", "restarts", "mismatch", "rejected"), 0
        )
        self.latencies: list[float] = []
        self._last_report = time.monotonic()

    def run(self) -> int:
        """Serve until stopped; returns the exit status."""
        log.info("serving %s version %d on %s (%s)", self.policy.architecture, self.version,
                 self.device, "deterministic" if self.config.deterministic else "sampling")  # fmt: skip
        while self.service.running:
            received = self.service.receive(timeout=0.1)
            if received is not None:
                self._handle(received.name, received.value)
            if self.assembler is not None and not self.trainer_heard:
                # A trainer announces each version once: ask one that started first (once a second).
                self.service.inbox.catch_up("weights", WEIGHTS.key(self.service.namespace))
            self._report()
        return 0

    def _handle(self, name: str, value: Any) -> None:
        self.trainer_heard |= name in ("weights", "schedule")
        if name == "weights":
            self._on_weights(value)
        elif name == "schedule":
            self.env_transitions = value
            self.policy.set_env_transitions(value)
        elif name == "scene":
            self._on_scene(*value)
        elif name == "state":
            self._on_state(value)
        elif name == "transition":
            self._on_transition(value)
        elif self._acts_on(self.watermark.judge_step(value.step)):
            self._serve(self.pairing.add_tokens(value.step, value))

    def _acts_on(self, verdict: Verdict) -> bool:
        """Whether a fresh step; stale and implausible ones are counted (a repeat of the
        answered step is not: perception repeats its tokens when the sim repeats a state)."""
        if verdict in (Verdict.STALE, Verdict.IMPLAUSIBLE):
            self.counts[verdict.value] += 1
        return verdict is Verdict.FRESH

    def _on_state(self, state: StateIn) -> None:
        verdict = self.watermark.judge(state.run, state.step)
        if verdict is Verdict.RESTART:
            self._restart(state)
        elif verdict is Verdict.REPEAT and self.answered is not None:
            self.action.put(self.answered)  # the sim sent it again: the same answer
            self.counts["resent"] += 1
            return
        elif not self._acts_on(verdict):
            return
        self._serve(self.pairing.add_state(state.step, state))

    def _restart(self, state: StateIn) -> None:
        """Follow the run of `state`: drop what belongs to the sim's previous run."""
        if not self.watermark.restart(state.run):
            return  # the first state: tokens that came before it are this run's
        log.warning("the sim restarted (another run): following it from step %d", state.step)
        self.counts["restarts"] += 1
        self.pairing.clear("restart")
        self.carry, self.answered = None, None
        if self.assembler is not None:
            self.assembler.restart()

    def _on_transition(self, t: TransitionIn) -> None:
        self._publish(self.assembler.add_transition(
            t.step, t.episode_ids, t.reward_terms, t.terminated, t.truncated, t.success))  # fmt: skip

    def _on_scene(self, env_ids: np.ndarray, env_code: np.ndarray) -> None:
        self.env_code = builder.store_env_code(
            self.env_code, torch.from_numpy(env_ids).long(), torch.from_numpy(env_code))

    def _serve(self, pair: tuple[StateIn, TokensIn] | None) -> None:
        if pair is None:
            return
        state, tokens = pair
        if not np.array_equal(state.episode_ids, tokens.episode_ids):
            self.counts["mismatch"] += 1
            log.warning("state and tokens of step %d disagree on episode ids: dropped", state.step)
            return
        started = time.monotonic()
        with torch.inference_mode():
            inputs = self._inputs(state, tokens)
            action = self.policy.act(inputs, self.config.deterministic, self.generator)
        self.carry = builder.end_step(self.carry, action.action, action.memory)
        message = encode_action(state.step, self.version, state.episode_ids, action,
                                self.config.deterministic)  # fmt: skip
        self.action.put(message)
        self.watermark.advance(state.step)
        self.answered = message
        self.counts["actions"] += 1
        self.latencies.append(time.monotonic() - started)
        if self.assembler is not None and self.trainer_heard:
            self._publish(self.assembler.add_step(
                state.step, state.episode_ids, inputs, action.action, action.log_prob,
                action.values, self.version))  # fmt: skip

    def _publish(self, chunks: list[Chunk]) -> None:
        """Send complete rollout chunks to the trainer."""
        for chunk in chunks:
            self.rollout.put(encode_rollout(chunk.rollout, chunk.version, self.chunks_sent))
            self.chunks_sent += 1

    def _inputs(self, state: StateIn, tokens: TokensIn) -> PolicyInputs:
        """The network inputs of a pair, on the device (the builder zeroes the carry of
        environments whose episode started)."""
        robot = RobotObservation(**{
            name: None if value is None else value.to(self.device)
            for name, value in vars(state.robot).items()
        })  # fmt: skip
        b, config = len(state.episode_ids), self.policy.config
        if self.carry is None or len(self.carry.episode_ids) != b:
            self.carry = builder.initial_carry(self.policy, b)
        ids = torch.from_numpy(state.episode_ids).to(self.device)
        steps = torch.from_numpy(state.episode_step).to(self.device)
        self.carry = builder.begin_step(self.carry, ids, steps)
        if config.scene_input == "env_code" and len(self.env_code) < b:
            log.warning("no scene yet for environments %d..%d: their EnvCode is zero",
                        len(self.env_code), b - 1)  # fmt: skip
            self._on_scene(np.arange(b), np.zeros((b, self.env_code.shape[1]), np.float32))
        return builder.policy_inputs(
            config, self.carry, robot, tuple(t.to(self.device) for t in tokens.tokens),
            self.env_code, self.pose_noise, self.generator,
        )  # fmt: skip

    def _on_weights(self, message: WeightsAnnouncement) -> None:
        version = message.version
        if version == self.version and version > 0:
            return  # a repeat of what is served (a trainer's last announcement, an answer to a late worker)
        try:
            self._load_spare(message)
        except WeightsError as error:
            self.counts["rejected"] += 1
            log.error("rejected weights version %d: %s; still serving version %d", version,
                      error, self.version)  # fmt: skip
            return
        self.policy, self.spare, self.version = self.spare, self.policy, version
        if self.env_transitions is not None:
            self.policy.set_env_transitions(self.env_transitions)
        log.info("serving weights version %d", version)

    def _load_spare(self, message: WeightsAnnouncement) -> None:
        """Check an announcement and load it into the spare copy (WeightsError if unfit)."""
        if message.version <= self.version:
            raise WeightsError(f"version {message.version} is not newer")
        weights = from_announcement(message)
        if self.spare is None:
            self.spare = build(self.policy.architecture, self.policy.config).to(self.device).eval()
        load_into(self.spare, weights)

    def _report(self) -> None:
        now = time.monotonic()
        elapsed = now - self._last_report
        if elapsed < self.config.report_period_s:
            return
        c = self.counts
        latency = 1e3 * np.median(self.latencies) if self.latencies else float("nan")
        drops = self.pairing.dropped
        log.info(
            "%.1f actions/s, inference median %.1f ms, version %d, %d resent, %d stale, "
            "%d implausible, %d sim restarts, %d mismatched, %d rejected weights, unpaired "
            "halves dropped: %d superseded, %d overflow", c["actions"] / elapsed, latency,
            self.version, c["resent"], c["stale"], c["implausible"], c["restarts"],
            c["mismatch"], c["rejected"], drops["superseded"], drops["overflow"],
        )  # fmt: skip
        if self.assembler is not None:
            log.info("%d rollout chunks sent; partial chunks dropped: %s", self.chunks_sent,
                     self.assembler.dropped)  # fmt: skip
        self.counts = dict.fromkeys(self.counts, 0)
        self.latencies.clear()
        self._last_report = now
