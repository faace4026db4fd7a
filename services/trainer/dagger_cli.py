"""`hamnet trainer --algo dagger`: distil a PPO teacher into the student by DAgger, from
`hamnet rollout --algo dagger` workers over Zenoh (`--workers N`, as PPO's) or in this
process (`--inprocess`), then measure both on the same held-out episodes with the same
evaluation code (`evaluate.py`): the teacher with clouds of every surface as it was trained,
the student with clouds as the cameras see them and the pose estimate, as it is deployed.

Every unusable input (no `--teacher`, a missing or non-policy file, a student as teacher, a
student architecture that is not one, a snapshot of another run or teacher) is one line on
stderr and exit status 2.
"""

from __future__ import annotations

import logging
import math
import sys

from hamnet.perception.config import student_clouds
from hamnet.policy.policy import Policy
from hamnet.runtime.service import Service, ServiceIdentity
from hamnet.trainer.cli import TrainerConfig, publish_while
from hamnet.trainer.collection.streamed import Streamed
from hamnet.trainer.results.evaluate import evaluate
from hamnet.trainer.results.summary import repository_path, write_summary
from hamnet.trainer.runners.dagger_runner import DaggerError, DaggerRunner, Teacher, load_teacher
from hamnet.trainer.runners.snapshots import ResumeError
from hamnet.trainer.runners.stopping import until_signalled
from hamnet.trainer.storage.demonstration_chunks import DEMONSTRATIONS, demonstrations_decoder

log = logging.getLogger(__name__)


def distil(config: TrainerConfig, identity: ServiceIdentity, code: str) -> int:
    """Run DAgger as `config` says, trained by the code of commit `code`; the exit status."""
    run, algorithm, resume = config.resumed_run, config.algorithm, config.resume is not None
    try:
        if algorithm.teacher is None:
            raise DaggerError(
                "--algo dagger needs --teacher CKPT, a policy checkpoint of "
                "hamnet trainer (RUN_DIR/checkpoints/latest.safetensors)"
            )
        teacher = load_teacher(algorithm.teacher)
        if config.inprocess and not config.publish:
            with until_signalled() as running:
                runner = DaggerRunner(run, algorithm.dagger, teacher, resume)
                runner.run(running=running)
                stopped = not running()
        else:
            with Service(identity, config.common.transport) as service:
                runner = distil_with(service, config, teacher)
                stopped = not service.running
    except (DaggerError, ResumeError) as error:
        print(f"hamnet trainer: {error}", file=sys.stderr)
        return 2
    extra: dict[str, object] = {
        "algo": "dagger",
        "teacher": repository_path(teacher.path),
        "teacher_sha256": teacher.sha256,
        "stopped_by_signal": stopped,
    }
    student = None
    if run.eval_episodes and not stopped:  # a stopped run saves within the grace period
        counter = runner.env_transitions
        student = evaluate(runner.policy, run, run.eval_episodes, counter, student_clouds())
        held = evaluate(teacher.policy, run, run.eval_episodes, counter)
        ratio = student.success_rate / held.success_rate if held.success_rate else None
        extra |= {
            "student_success_rate": student.success_rate,
            "teacher_success_rate": held.success_rate,
            "teacher_goal_return": held.goal_return,
            "student_vs_teacher": ratio,
        }
        log.info(
            "on %d held-out episodes: student %.3f, teacher %.3f",
            run.eval_episodes,
            student.success_rate,
            held.success_rate,
        )
    print(write_summary(runner.config, student, code, extra))
    return 0


def distil_with(service: Service, config: TrainerConfig, teacher: Teacher) -> DaggerRunner:
    """Distil while publishing on `service`: in-process, or from the demonstrations of
    `config.run.workers` rollout workers, whose chunks of another teacher are refused."""
    run, dagger = config.resumed_run, config.algorithm.dagger
    resume = config.resume is not None
    if config.inprocess:
        runner = DaggerRunner(run, dagger, teacher, resume)
        return publish_while(service, runner, config.weights_period_s)

    def streamed(student: Policy) -> Streamed:
        return Streamed(
            service,
            student,
            config.run.workers,
            run.num_envs,
            config.max_policy_lag,
            worker_timeout_s=config.worker_timeout_s,
            decoder=demonstrations_decoder(teacher.sha256),
            topic=DEMONSTRATIONS,
        )

    runner = DaggerRunner(run, dagger, teacher, resume, streamed)
    return publish_while(service, runner, math.inf)  # the source announces every version
