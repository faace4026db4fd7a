"""What a teacher's privileged block is worth to it: its held-out success on a student's
result's episodes with the block as trained and with parts of it replaced by what no sensor
needs to give (the physics parameters by their mean over the episodes; the object's
velocity by zeros, or by the finite difference of its last two poses, which a student's
history holds). A teacher that does as well without them leaves the student nothing to
infer: its shortfall is then its fit of the teacher's actions, not what it cannot observe.
It also reads the student's pose estimate: one reading a step, or the mean of the last few
in the episode (what a filter of the estimates would give).

    python scripts/teacher_privileged.py easy-paddle-student
    python scripts/teacher_privileged.py runs/dagger-push

The last line printed is one JSON object: the teacher's success rate under each setting.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable

import numpy as np
import torch

from hamnet.messages.robot_state import Observation
from hamnet.policy.inputs import mean_pose
from hamnet.policy.observation import PoseNoiseConfig, estimated_pose
from hamnet.sim import quaternion
from hamnet.trainer.algorithms.teacher import load_teacher
from hamnet.trainer.results.evaluate import evaluate
from hamnet.trainer.results.summary import policy_and_result, run_of

Edit = Callable[[Observation], None]


def mean_physics() -> Edit:
    """Every episode's physics parameters replaced by their mean over the first batch."""
    mean: list[np.ndarray] = []

    def edit(observation: Observation) -> None:
        if not mean:
            mean.append(observation.physics_params.mean(axis=0))
        observation.physics_params[...] = mean[0]

    return edit


def zero_velocity(observation: Observation) -> None:
    """The object's velocity replaced by zeros."""
    observation.object_velocity[...] = 0.0


class PoseHistory:
    """The last `keep` object poses of every environment (oldest first) and how far back
    each one's current episode reaches among them."""

    def __init__(self, keep: int) -> None:
        self.keep = keep
        self.poses: list[np.ndarray] = []
        self.age = np.zeros(0, dtype=np.int64)  # steps of history each episode has

    def push(self, pose: np.ndarray, episode_step: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Add this step's (B, 7) poses; returns the kept poses (K, B, 7), newest last, and
        (B,) how many steps before the newest each environment's episode reaches (< K)."""
        self.age = np.zeros(len(pose), np.int64) if not self.poses else self.age + 1
        self.age[episode_step == 0] = 0
        self.poses.append(pose)
        del self.poses[: -self.keep]
        return np.stack(self.poses), np.minimum(self.age, len(self.poses) - 1)


def read_pose(
    observation: Observation, noise: PoseNoiseConfig | None, generator: torch.Generator
) -> np.ndarray:
    """(B, 7) float64 object poses: true, or with `noise` as a student's estimator reads them
    (`estimated_pose`, a new error every step)."""
    pose = torch.from_numpy(observation.object_pose)
    if noise is not None:
        pose = estimated_pose(pose, noise, generator)
    return pose.numpy().astype(np.float64)


def difference_velocity(
    period_s: float, span: int = 1, noise: PoseNoiseConfig | None = None, seed: int = 0
) -> Edit:
    """The object's velocity replaced by the difference of its poses `span` steps apart (or
    as many as its episode has had; zero at its first step) over their time: linear in m/s,
    angular from the relative rotation (twice the vector part of q_t q_{t-span}^-1, its
    small-angle form), world frame. With `noise`, of the poses a student's estimator reads
    (`estimated_pose`, a new error every step), the pose itself left true."""
    history = PoseHistory(span + 1)
    generator = torch.Generator().manual_seed(seed)

    def edit(observation: Observation) -> None:
        pose = read_pose(observation, noise, generator)
        poses, back = history.push(pose, observation.episode_step)  # back: steps compared
        previous = poses[len(poses) - 1 - back, np.arange(len(pose))]  # (B, 7)
        turn = quaternion.multiply(pose[:, 3:], quaternion.conjugate(previous[:, 3:]))
        turn *= np.sign(turn[:, :1] + (turn[:, :1] == 0))  # the short way round
        velocity = np.concatenate([pose[:, :3] - previous[:, :3], 2.0 * turn[:, 1:]], 1)
        seconds = np.maximum(back, 1)[:, None] * period_s
        observation.object_velocity[...] = np.where(back[:, None] > 0, velocity / seconds, 0.0)

    return edit


def pose_estimate(noise: PoseNoiseConfig, seed: int) -> Edit:
    """The object's pose replaced by a student's estimate of it (`estimated_pose`, a new
    error every step). The teacher's object cloud follows the estimate, where a student's
    comes from the cameras: an upper bound on what the estimate costs."""
    generator = torch.Generator().manual_seed(seed)

    def edit(observation: Observation) -> None:
        pose = torch.from_numpy(observation.object_pose)
        observation.object_pose[...] = estimated_pose(pose, noise, generator).numpy()

    return edit


def averaged_estimate(noise: PoseNoiseConfig, span: int, seed: int) -> Edit:
    """The object's pose replaced by the mean of the estimator's last `span` readings in its
        episode (`estimated_pose`, a new error every step): positions averaged, quaternions
        averaged on the hemisphere of the newest and normalised (`inputs.mean_pose`, as a student
    with `pose_readings` reads them). What a filter of the estimates
        could give the teacher: less noise, `(span - 1) / 2` steps of lag on a moving object."""
    history = PoseHistory(span)
    generator = torch.Generator().manual_seed(seed)

    def edit(observation: Observation) -> None:
        reading = read_pose(observation, noise, generator)
        readings, reach = history.push(reading, observation.episode_step)  # (K, B, 7), (B,)
        mean = mean_pose(torch.from_numpy(readings.transpose(1, 0, 2)), torch.from_numpy(reach + 1))
        observation.object_pose[...] = mean.numpy()

    return edit


def both(*edits: Edit) -> Edit:
    """The edits applied in turn."""

    def edit(observation: Observation) -> None:
        for each in edits:
            each(observation)

    return edit


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "student",
        help="a shipped student's name (its card names its result) or a DAgger run's folder",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the result's evaluation")
    args = parser.parse_args()
    result = policy_and_result(args.student)[1]  # the student's run's summary fields
    teacher = load_teacher(result["teacher"]).policy
    config = run_of(result, args.seed)  # evaluate acts in the teacher's architecture
    episodes, period = result["eval_episodes"], config.sim.policy_period_s
    estimate = PoseNoiseConfig()  # the student's estimator's error
    settings: dict[str, Callable[[], Edit | None]] = {
        "as_trained": lambda: None,
        "mean_physics": mean_physics,
        "zero_velocity": lambda: zero_velocity,
        "difference_velocity": lambda: difference_velocity(period),
        "mean_physics_difference_velocity": lambda: both(
            mean_physics(), difference_velocity(period)
        ),
        "estimated_pose": lambda: pose_estimate(estimate, args.seed),
        "estimate_difference_velocity": lambda: difference_velocity(
            period, noise=estimate, seed=args.seed
        ),
        "estimate_difference_velocity_span_4": lambda: difference_velocity(
            period, 4, estimate, args.seed
        ),
        "estimated_pose_difference_velocity": lambda: both(
            mean_physics(), pose_estimate(estimate, args.seed), difference_velocity(period)
        ),
        "averaged_estimate_4": lambda: averaged_estimate(estimate, 4, args.seed),
        "averaged_estimate_8": lambda: averaged_estimate(estimate, 8, args.seed),
    }
    rates = {}
    for name, make in settings.items():
        held_out = evaluate(teacher, config, episodes, result["env_steps"], edit=make())
        rates[name] = held_out.success_rate
        print(f"{name}: {held_out.success_rate:.3f} on {episodes} held-out episodes", flush=True)
    print(json.dumps({"teacher": result["teacher"], "episodes": episodes, **rates}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
