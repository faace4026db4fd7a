"""`hamnet trainer --algo dagger`: distil a PPO teacher into the student by DAgger, then
measure both on the same held-out episodes with the same evaluation code (`evaluate.py`):
the teacher with clouds of every surface as it was trained, the student with clouds as the
cameras see them and the pose estimate, as it is deployed.

Every unusable input (no `--teacher`, a missing or non-policy file, a student as teacher, a
student architecture that is not one, a snapshot of another run or teacher, rollout
workers) is one line on stderr and exit status 2.
"""

from __future__ import annotations

import logging
import sys

from hamnet.perception.config import student_clouds
from hamnet.runtime.service import Service, ServiceIdentity
from hamnet.trainer.cli import TrainerConfig, publish_while
from hamnet.trainer.dagger_runner import DaggerError, DaggerRunner, load_teacher
from hamnet.trainer.evaluate import evaluate
from hamnet.trainer.resume import ResumeError
from hamnet.trainer.summary import write_summary

log = logging.getLogger(__name__)


def distil(config: TrainerConfig, identity: ServiceIdentity, code: str) -> int:
    """Run DAgger as `config` says, trained by the code of commit `code`; the exit status."""
    run = config.resumed_run
    try:
        if not config.inprocess:
            raise DaggerError("--algo dagger collects in-process only (rollout workers host "
                              "no teacher yet): add --inprocess")  # fmt: skip
        if config.teacher is None:
            raise DaggerError("--algo dagger needs --teacher CKPT, a policy checkpoint of "
                              "hamnet trainer (RUN_DIR/checkpoints/latest.safetensors)")  # fmt: skip
        teacher = load_teacher(config.teacher)
        runner = DaggerRunner(run, config.dagger, teacher, resume=config.resume is not None)
    except (DaggerError, ResumeError) as error:
        print(f"hamnet trainer: {error}", file=sys.stderr)
        return 2
    if config.publish:
        with Service(identity, config.common.transport) as service:
            publish_while(service, runner, config.weights_period_s)
    else:
        runner.run()
    extra: dict[str, object] = {"algo": "dagger", "teacher": str(teacher.path),
                                "teacher_sha256": teacher.sha256}  # fmt: skip
    student = None
    if run.eval_episodes:
        counter = runner.env_transitions
        student = evaluate(runner.policy, run, run.eval_episodes, counter, student_clouds())
        held = evaluate(teacher.policy, run, run.eval_episodes, counter)
        ratio = student.success_rate / held.success_rate if held.success_rate else None
        extra |= {"student_success_rate": student.success_rate,
                  "teacher_success_rate": held.success_rate,
                  "teacher_goal_return": held.goal_return, "student_vs_teacher": ratio}  # fmt: skip
        log.info("on %d held-out episodes: student %.3f, teacher %.3f", run.eval_episodes,
                 student.success_rate, held.success_rate)  # fmt: skip
    print(write_summary(runner.config, student, code, extra))
    return 0
