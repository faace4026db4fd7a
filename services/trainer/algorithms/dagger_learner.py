"""DAgger as a run's algorithm: the frozen teacher labels every state the mixture of teacher
and student visits, the student (the run's policy) learns to act as the teacher would
(`dagger.update_student`), on deployable inputs.

Its rollouts are `Demonstrations`: from a `DaggerWorker` in this process (`InProcessDagger`,
one group of environments, no overlap: two perceptions share the step) or from
`hamnet rollout --algo dagger` workers over Zenoh, whose chunks name the teacher's SHA-256
(`hamnet.trainer.storage.demonstration_chunks`). The student's checkpoint is a policy
checkpoint like PPO's, served by `hamnet policy --checkpoint`; its held-out result is
measured beside the teacher's on the same episodes with the same evaluation code: the
teacher with clouds of every surface, as it was trained, the student with clouds as the
cameras see them and the pose estimate, as it is deployed.
"""

from __future__ import annotations

import copy
import dataclasses
import logging
import math
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np
import torch

from hamnet.perception.config import student_clouds
from hamnet.policy.policy import Policy
from hamnet.proto.trainer_pb2 import RolloutChunk
from hamnet.runtime import contract
from hamnet.runtime.compute import torch_threads
from hamnet.trainer.algorithms.dagger import (
    Demonstrations,
    VelocityReadout,
    average_into,
    beta_at,
    lr_at,
    update_student,
)
from hamnet.trainer.algorithms.teacher import Teacher, check_student
from hamnet.trainer.collection.dagger_worker import InProcessDagger
from hamnet.trainer.collection.sources import Collected, RolloutSource
from hamnet.trainer.config import DaggerConfig
from hamnet.trainer.results.evaluate import HeldOut, evaluate
from hamnet.trainer.results.summary import repository_path
from hamnet.trainer.runners.progress import dagger_line
from hamnet.trainer.runners.ranks import ONE, Ranks
from hamnet.trainer.runners.run_config import RunConfig
from hamnet.trainer.runners.snapshots import (
    Arrays,
    ResumeError,
    Snapshot,
    nest,
    optimizer_snapshot,
    part,
    restore_optimizer,
)
from hamnet.trainer.runners.stopping import always
from hamnet.trainer.storage.demonstration_chunks import (
    DEMONSTRATIONS,
    decode_demonstrations,
    demonstrations_decoder,
    encode_demonstrations,
)
from hamnet.trainer.storage.rollout_chunks import Arrived

log = logging.getLogger(__name__)


class Dagger:
    """A DAgger run's teacher, schedule, optimizer and the outcomes of the student's episodes."""

    name = "dagger"

    def __init__(self, teacher: Teacher, config: DaggerConfig) -> None:
        self.teacher, self.dagger = teacher, config
        self.student_episodes: deque[bool] = deque(maxlen=200)
        """Outcomes of the last episodes the student acted (the episode tracker's window)."""

    def prepare(self, config: RunConfig) -> RunConfig:
        """DaggerError unless the run's architecture is a student; one group of environments,
        acting in the teacher's action space (the student learns the teacher's outputs)."""
        check_student(config.architecture)
        space = self.teacher.policy.config.action_space
        return dataclasses.replace(config, overlap=False, action_space=space)

    def in_process(self, config: RunConfig) -> RolloutSource:
        return InProcessDagger(config, self.teacher.policy, self.dagger)

    @property
    def topic(self) -> contract.Topic:
        return DEMONSTRATIONS

    def encode(self, rollout: Demonstrations, version: int, sequence: int) -> RolloutChunk:
        return encode_demonstrations(rollout, version, sequence, self.teacher.sha256)

    def decoder(self, policy: Policy) -> Callable[[str, bytes], Arrived]:
        """Demonstrations of this run's teacher only: another's are refused."""
        return demonstrations_decoder(self.teacher.sha256)(policy)

    def start(self, policy: Policy, envs: int, ranks: Ranks = ONE, threads: int = 1) -> None:
        """The student is `policy`; DAgger learns from one rank. With a velocity loss, its
        linear read-out of the student's memory learns beside it (training only: the
        checkpoint is the student's)."""
        self.student, self.threads = policy, threads
        self.averaging = self.dagger.weight_average > 0
        """Whether the student is the moving average of the weights the optimizer steps."""
        self.trained = copy.deepcopy(policy) if self.averaging else policy
        """What the optimizer steps: the student itself, or with `weight_average` a copy
        whose moving average the student is."""
        self.readout = (
            VelocityReadout(policy.memory_width, self.teacher.policy)
            if self.dagger.velocity_coef > 0
            else None
        )
        learned = list(self.trained.parameters()) + (
            list(self.readout.parameters()) if self.readout is not None else []
        )
        self.optimizer = torch.optim.Adam(learned, lr=self.dagger.lr)
        self.replay: deque[np.ndarray] = deque(maxlen=self.dagger.replay_windows - 1)
        """The windows before the newest that the update draws from, oldest first, each as
        its chunk's bytes (`encode_demonstrations`, read-only: a window's per-episode tokens
        once, and nothing to copy when the run keeps its state in memory)."""

    def learn(
        self,
        collected: Collected,
        whole: Demonstrations,
        env_transitions: int,
        running: Callable[[], bool] = always,
    ) -> dict[str, float]:
        """One imitation update on the whole window collected from the counter
        `env_transitions`."""
        demos: Demonstrations = collected.rollout
        ended = demos.dones & ~demos.teacher_acted  # (T, B) student episodes that ended
        self.student_episodes.extend(demos.success[ended].tolist())
        rate = lr_at(env_transitions, self.dagger)
        config = dataclasses.replace(self.dagger, lr=rate)
        with torch_threads(self.threads):
            if self.averaging:
                for mine, its in zip(self.trained.buffers(), self.student.buffers(), strict=True):
                    mine.copy_(its)  # the normalizer's statistics, the schedule's counter
            stats = update_student(
                self.trained, self.optimizer, demos, config, self.readout, self.replayed
            )
            if self.averaging:
                average_into(self.student, self.trained, self.dagger.weight_average)
        if self.replay.maxlen:
            encoded = self.encode(demos, 0, 0).SerializeToString()
            self.replay.append(np.frombuffer(encoded, dtype=np.uint8))
        return {
            "beta": beta_at(env_transitions, self.dagger),
            "student_share": 1.0 - float(demos.teacher_acted.float().mean()),
            **dataclasses.asdict(stats),
            "learning_rate": rate,
            "student_episodes": len(self.student_episodes),
            "student_episode_success": (
                float(np.mean(self.student_episodes)) if self.student_episodes else math.nan
            ),
        }

    def replayed(self) -> list[Demonstrations]:
        """`replay_draw` of the kept windows, drawn without replacement by torch's global
        generator (the run's snapshot keeps its state)."""
        count = min(self.dagger.replay_draw, len(self.replay))
        if not count:
            return []
        picks = torch.randperm(len(self.replay))[:count].tolist()
        return [
            decode_demonstrations(
                RolloutChunk.FromString(self.replay[i].tobytes()),
                self.student,
                self.teacher.sha256,
            )
            for i in picks
        ]

    def progress(self, row: dict[str, float]) -> str:
        return dagger_line(row)

    def snapshot(self) -> Snapshot:
        """Adam's state, the velocity read-out's weights, the weights the optimizer steps
        (with `weight_average`), the kept windows, the student's last outcomes and the
        teacher's identity."""
        outcomes = np.array(self.student_episodes, dtype=bool)
        readout = dict(self.readout.state_dict()) if self.readout is not None else {}
        replay = {str(i): window for i, window in enumerate(self.replay)}
        parts = {
            "optimizer": optimizer_snapshot(self.optimizer),
            "readout": (readout, {}),
            "replay": (replay, {"windows": len(replay)}),
        }
        if self.averaging:
            parts["trained"] = (dict(self.trained.state_dict()), {})
        arrays, meta = nest(parts)
        teacher = {"path": str(self.teacher.path), "sha256": self.teacher.sha256}
        return {**arrays, "student_episodes": outcomes}, {**meta, "teacher": teacher}

    def restore(self, arrays: Arrays, meta: dict[str, Any]) -> None:
        """Continue a DAgger run of this teacher (ResumeError for another's)."""
        saved = meta.get("teacher")
        if saved is None:
            raise ResumeError("it is not a DAgger run")
        if saved["sha256"] != self.teacher.sha256:
            raise ResumeError(
                f"it distils the teacher {saved['path']} (sha256 {saved['sha256'][:12]}), "
                f"not {self.teacher.path} ({self.teacher.sha256[:12]})"
            )
        readout = part(arrays, meta, "readout")[0] if "readout" in meta else {}
        if bool(readout) != (self.readout is not None):
            raise ResumeError(
                f"it was run {'with' if readout else 'without'} a velocity loss: give it "
                "the --dagger.velocity-coef it was run with"
            )
        if self.readout is not None:
            self.readout.load_state_dict({k: torch.tensor(v) for k, v in readout.items()})
        if self.averaging:
            # A run that averages from here on starts its copy at the restored student.
            trained = part(arrays, meta, "trained")[0] if "trained" in meta else None
            self.trained.load_state_dict(
                self.student.state_dict()
                if trained is None
                else {k: torch.tensor(v) for k, v in trained.items()}
            )
        restore_optimizer(self.optimizer, *part(arrays, meta, "optimizer"))
        windows, kept = part(arrays, meta, "replay") if "replay" in meta else ({}, {"windows": 0})
        self.replay.clear()
        for i in range(kept["windows"]):
            window = np.array(windows[str(i)], dtype=np.uint8)
            window.flags.writeable = False
            self.replay.append(window)
        self.student_episodes.clear()
        self.student_episodes.extend(np.asarray(arrays["student_episodes"]).tolist())

    def held_out(
        self, policy: Policy, config: RunConfig, env_transitions: int
    ) -> tuple[HeldOut, dict[str, object]]:
        """The student, with clouds as the cameras see them, and the teacher on the same
        episodes; the student's figures are the run's."""
        episodes = config.eval_episodes
        student = evaluate(policy, config, episodes, env_transitions, student_clouds())
        teacher = evaluate(self.teacher.policy, config, episodes, env_transitions)
        ratio = student.success_rate / teacher.success_rate if teacher.success_rate else None
        log.info("teacher on the same episodes: %.3f", teacher.success_rate)
        fields = {
            "student_success_rate": student.success_rate,
            "teacher_success_rate": teacher.success_rate,
            "teacher_goal_return": teacher.goal_return,
            "student_vs_teacher": ratio,
        }
        if self.averaging:  # what the average bought, on the same episodes
            trained = evaluate(self.trained, config, episodes, env_transitions, student_clouds())
            log.info("the stepped weights, not averaged: %.3f", trained.success_rate)
            fields["unaveraged_success_rate"] = trained.success_rate
        return student, fields

    def summary_fields(self) -> dict[str, object]:
        return {
            "algo": "dagger",
            "teacher": repository_path(self.teacher.path),
            "teacher_sha256": self.teacher.sha256,
        }
