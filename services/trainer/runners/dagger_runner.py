"""DAgger's training loop: the PPO `Runner`'s loop, checkpoints, snapshots and metrics
file, with DAgger's rollouts and the student's imitation update (`dagger.update_student`)
in place of PPO's. The rollouts come from a `dagger_worker.DaggerWorker` in this process
(`InProcessDagger`) or, as PPO's do, from rollout workers over Zenoh (`stream.Streamed` of
`hamnet rollout --algo dagger` workers' demonstrations, `hamnet.trainer.storage.demonstration_chunks`).

The teacher is a policy checkpoint the PPO trainer wrote; it is frozen, and a snapshot
records its SHA-256 so a run resumes only with the teacher it was distilled from. The
student's checkpoint (`checkpoints/latest.safetensors`) is a policy checkpoint like PPO's,
served by `hamnet policy --checkpoint`.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hamnet.policy.policy import Policy
from hamnet.policy.registry import architecture
from hamnet.policy.shipped import read_weights, resolve
from hamnet.policy.weights import WeightsError, policy_from, sha256
from hamnet.runtime.compute import torch_threads
from hamnet.trainer.algorithms.dagger import Demonstrations, beta_at, update_student
from hamnet.trainer.collection.dagger_worker import DaggerWorker, build_dagger_worker
from hamnet.trainer.collection.sources import Collected, RolloutSource
from hamnet.trainer.config import DaggerConfig
from hamnet.trainer.runners.progress import dagger_line
from hamnet.trainer.runners.run_config import RunConfig
from hamnet.trainer.runners.runner import Runner
from hamnet.trainer.runners.snapshots import Arrays, ResumeError, Snapshot
from hamnet.trainer.runners.stopping import always


class DaggerError(ValueError):
    """A teacher or student DAgger cannot use (one line, for the command line)."""


@dataclass(frozen=True)
class Teacher:
    """The frozen teacher of a run."""

    policy: Policy
    path: Path
    sha256: str
    """Of the checkpoint file's bytes."""


def load_teacher(path: Path) -> Teacher:
    """The teacher in the policy checkpoint `path` (or the shipped policy of that name).

    Raises:
        DaggerError: no such file, not a policy checkpoint, or a student's (no privileged
            inputs, or recurrent): a student cannot label for another.
    """
    try:
        data = resolve(path).read_bytes()
    except OSError as error:
        raise DaggerError(f"cannot read teacher {path}: {error.strerror}") from None
    try:
        policy = policy_from(read_weights(path))  # a shipped one checked against its card
    except WeightsError as error:
        raise DaggerError(f"teacher {path} is not a policy checkpoint: {error}") from None
    if not policy.config.privileged or policy.config.recurrent:
        raise DaggerError(
            f"teacher {path} is a {policy.architecture!r} policy, a student's "
            "architecture: the teacher must be a privileged feed-forward policy "
            "trained by PPO (hamnet trainer)"
        )
    return Teacher(policy.requires_grad_(False), Path(path), sha256(data))


def check_student(name: str) -> None:
    """DaggerError unless `name` is a student architecture: no privileged input, and memory
    for `evaluate_sequence` to unroll."""
    config = architecture(name).config
    if config.privileged or not config.recurrent:
        raise DaggerError(
            f"--architecture {name} is not a student (no privileged inputs, "
            "recurrent): DAgger distils into one, e.g. 'student'"
        )


class InProcessDagger:
    """DAgger's rollouts from one `DaggerWorker` in this process (a `RolloutSource` whose
    rollouts are `Demonstrations`)."""

    def __init__(self, config: RunConfig, teacher: Policy, dagger: DaggerConfig) -> None:
        self.worker: DaggerWorker = build_dagger_worker(config, teacher)
        self.teacher, self.dagger = teacher, dagger

    @property
    def num_envs(self) -> int:
        return self.worker.num_envs

    @property
    def alone_in_update(self) -> bool:
        return True

    def collect(
        self,
        policy: Policy,
        steps: int,
        env_transitions: int,
        version: int,
        running: Callable[[], bool] = always,
    ) -> Collected:
        """T = `steps` steps of every environment, the student `policy` acting where beta's
        coin says (at the counter `env_transitions`), the teacher labelling."""
        policy.eval()
        return Collected(
            self.worker.collect(self.teacher, policy, steps, env_transitions, self.dagger, running)
        )

    def snapshot(self) -> Snapshot:
        return self.worker.snapshot()

    def restore(self, arrays: Arrays, meta: dict[str, Any]) -> None:
        self.worker.restore(arrays, meta)


class DaggerRunner(Runner):
    """A DAgger run: the teacher labels, the student (the run's policy) learns."""

    def __init__(
        self,
        config: RunConfig,
        dagger: DaggerConfig,
        teacher: Teacher,
        resume: bool = False,
        source: Callable[[Policy], RolloutSource] | None = None,
    ) -> None:
        """The student is `config.architecture`; `source(student)` makes the rollout source,
        whose rollouts are `Demonstrations` (default `InProcessDagger`: one group of
        environments, no overlap, since two perceptions share the step). ResumeError as
        `Runner`'s, and when the snapshot is not of a DAgger run or of another teacher."""
        check_student(config.architecture)
        self.dagger, self.teacher = dagger, teacher
        self.student_episodes: deque[bool] = deque(maxlen=200)
        """Outcomes of the last episodes the student acted (the tracker's window)."""
        config = dataclasses.replace(config, overlap=False)

        def in_process(_: Policy) -> InProcessDagger:
            return InProcessDagger(config, teacher.policy, dagger)

        super().__init__(config, in_process if source is None else source, resume)

    def iterate(self, running: Callable[[], bool] = always) -> dict[str, float]:
        """One rollout of teacher and student and one imitation update; the metrics
        (InterruptedError while the rollout is under way once `running()` turns False)."""
        started = time.perf_counter()
        config, student = self.config, self.policy
        student.eval()
        collected = self.source.collect(
            student, config.rollout_steps, self.env_transitions, self.version, running
        )
        demos: Demonstrations = collected.rollout
        collect_done = time.perf_counter()
        self.tracker.add(demos, collected.envs)
        ended = demos.dones & ~demos.teacher_acted  # (T, B) student episodes that ended
        self.student_episodes.extend(demos.success[ended].tolist())
        with torch_threads(self.learner_threads):
            stats = update_student(student, self.optimizer, demos, self.dagger)
        student.normalizer.update(demos.inputs.observation)  # after: act and learn agreed
        beta = beta_at(self.env_transitions, self.dagger)
        transitions = demos.labels.shape[0] * demos.labels.shape[1]
        return {
            **self.advance(transitions, started, collect_done),
            "beta": beta,
            "student_share": 1.0 - float(demos.teacher_acted.float().mean()),
            **dataclasses.asdict(stats),
            "learning_rate": self.dagger.lr,
            **self.tracker.summary(),
            "student_episodes": len(self.student_episodes),
            "student_episode_success": (
                float(np.mean(self.student_episodes)) if self.student_episodes else math.nan
            ),
            "policy_lag": collected.policy_lag,
            "dropped_rollouts": collected.dropped,
            **collected.figures,
        }

    def progress(self, row: dict[str, float]) -> str:
        return dagger_line(row)

    def snapshot(self) -> Snapshot:
        """`Runner`'s snapshot with the teacher's identity."""
        arrays, meta = super().snapshot()
        arrays = {**arrays, "student_episodes": np.array(self.student_episodes, dtype=bool)}
        return arrays, {
            **meta,
            "teacher": {"path": str(self.teacher.path), "sha256": self.teacher.sha256},
        }

    def restore(self, arrays: Arrays, meta: dict[str, Any]) -> None:
        """`Runner`'s restore, once the snapshot is of a DAgger run of this teacher."""
        saved = meta.get("teacher")
        if saved is None:
            raise ResumeError(f"cannot resume {self.config.run_dir}: it is not a DAgger run")
        if saved["sha256"] != self.teacher.sha256:
            raise ResumeError(
                f"cannot resume {self.config.run_dir}: it distils the teacher "
                f"{saved['path']} (sha256 {saved['sha256'][:12]}), not "
                f"{self.teacher.path} ({self.teacher.sha256[:12]})"
            )
        super().restore(arrays, meta)

    def restore_parts(self, arrays: Arrays, meta: dict[str, Any]) -> None:
        """`Runner`'s parts and the outcomes of the student's last episodes."""
        super().restore_parts(arrays, meta)
        self.student_episodes.clear()
        self.student_episodes.extend(np.asarray(arrays["student_episodes"]).tolist())
