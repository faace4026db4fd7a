"""Where in its episodes a shipped student departs from its teacher, and what its memory is
worth there: the student acts alone (DAgger's beta 0, the deployed situation) on its result's
stage, the teacher labels every state, and the squared error of the student's action is
binned by the episode's step, once with the memory the student acted with and once with the
memory reset at every step (the same inputs, no history).

An error that falls with the episode's step where the memory is kept, and not where it is
reset, is the memory inferring what the student cannot observe (the teacher's privileged
physics and object velocity); equal errors mean the student learned to ignore its history.
The student's GRU learns from windows of the run's `--steps-per-rollout` steps (gradients
never cross a window's start), so a gain that stops at that length points at the window.

    python scripts/student_memory.py easy-paddle-student --steps 256
    python scripts/student_memory.py runs/dagger-paddle-t32 --steps 256   # a finished run

How much of the object's velocity (the one privileged input the teacher relies on,
`scripts/teacher_privileged.py`) the student's memory holds: a linear read-out of the memory
after each step, fitted by least squares on the first half of the environments, scored on
the other half (`dagger.VelocityReadout.loss`: squared error in the teacher's standardised
units, about 1 for no better than the teacher's mean velocity), with the memory kept and
reset.

The last line printed is one JSON object: per bin of episode steps, the mean squared error
with memory and without, and the labels' mean square (the error's scale); the velocity
read-out's held-out loss with memory and without.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json

import torch

from hamnet.policy.policy import Policy
from hamnet.policy.shipped import read_weights
from hamnet.policy.weights import policy_from
from hamnet.runtime.trees import take_rows
from hamnet.trainer.algorithms.dagger import VelocityReadout
from hamnet.trainer.algorithms.recurrent_unroll import episode_starts
from hamnet.trainer.collection.dagger_worker import InProcessDagger
from hamnet.trainer.config import STUDENT_ALONE
from hamnet.trainer.results.summary import policy_and_result, run_of

BIN_EDGES = (0, 1, 4, 8, 16, 32, 64, 1_000_000)
"""Episode steps [edge, next edge): the first step (no history), the window's length (8,
the shipped student's), and beyond."""

RIDGE = 1e-2
"""The read-out's ridge penalty, relative to the features' mean square: plain least squares
on a few thousand correlated steps of 385 features overfits the fitted half (held-out losses
of 9-14 on 128 steps of the shipped students)."""


def episode_step(starts: torch.Tensor) -> torch.Tensor:
    """(T, B) each step's index in its episode, from the (T, B) steps that begin one
    (the first row begins every episode: the collection starts on reset environments)."""
    index = torch.zeros(starts.shape, dtype=torch.long)
    for t in range(1, len(starts)):
        index[t] = torch.where(starts[t], 0, index[t - 1] + 1)
    return index


def held_out_velocity_loss(
    memories: torch.Tensor, velocity: torch.Tensor, student: Policy, teacher: Policy
) -> float:
    """The loss of a linear read-out of the object's (T, B, 6) `velocity` from (T, B, H)
    `memories`, fitted by ridge regression (with a bias) on the first half of the
    environments and scored on the other half, in the teacher's standardised units."""
    readout = VelocityReadout(student.memory_width, teacher)
    half = memories.shape[1] // 2
    target = readout.target(velocity)
    rows = lambda x: x[:, :half].flatten(0, 1)
    features = torch.cat([rows(memories), torch.ones(len(rows(memories)), 1)], 1).double()
    gram = features.T @ features
    ridge = RIDGE * gram.diagonal().mean() * torch.eye(len(gram), dtype=gram.dtype)
    solution = torch.linalg.solve(gram + ridge, features.T @ rows(target).double()).float()
    with torch.no_grad():
        readout.linear.weight.copy_(solution[:-1].T)
        readout.linear.bias.copy_(solution[-1])
        return readout.loss(memories[:, half:], velocity[:, half:]).item()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "student",
        help="a shipped student's name, or a finished DAgger run's folder (its summary.json "
        "names the teacher and the stage)",
    )
    parser.add_argument("--steps", type=int, default=256, help="steps of every environment")
    parser.add_argument("--seed", type=int, default=1, help="seed of the environments")
    args = parser.parse_args()
    torch.set_num_threads(1)
    student, result = policy_and_result(args.student)
    if student.config.privileged or not student.memory_width:
        parser.error(f"{args.student} is not a recurrent student")
    teacher = policy_from(read_weights(result["teacher"]))
    source = InProcessDagger(run_of(result, args.seed), teacher, STUDENT_ALONE)
    demos = source.collect(student, args.steps, 0, 0).rollout
    steps, b = demos.dones.shape
    index = episode_step(episode_starts(demos.dones, demos.first))
    errors = {"memory": torch.zeros(steps, b), "reset": torch.zeros(steps, b)}
    memories = {name: torch.zeros(steps, b, student.memory_width) for name in errors}
    with torch.no_grad():
        for t in range(steps):
            rows = take_rows(demos.inputs, torch.arange(t * b, (t + 1) * b))
            blank = dataclasses.replace(rows, memory=student.initial_memory(b))
            for name, inputs in (("memory", rows), ("reset", blank)):
                out = student.act(inputs, deterministic=True)
                errors[name][t] = (out.action - demos.labels[t]).square().mean(-1)
                memories[name][t] = out.memory
    scale = demos.labels.square().mean(-1)
    bins = []
    for low, high in itertools.pairwise(BIN_EDGES):
        mask = (index >= low) & (index < high)
        if not mask.any():
            continue
        row = {
            "steps": [low, min(high, int(index.max()) + 1)],
            "samples": int(mask.sum()),
            "mse_memory": float(errors["memory"][mask].mean()),
            "mse_reset": float(errors["reset"][mask].mean()),
            "label_mean_square": float(scale[mask].mean()),
        }
        bins.append(row)
        print(
            f"steps {row['steps'][0]:>3}-{row['steps'][1] - 1:<4} n={row['samples']:>6} "
            f"mse with memory {row['mse_memory']:.5f}, reset {row['mse_reset']:.5f} "
            f"(labels' mean square {row['label_mean_square']:.4f})",
            flush=True,
        )
    velocity = {
        name: held_out_velocity_loss(memory, demos.object_velocity, student, teacher)
        for name, memory in memories.items()
    }
    print(
        f"velocity read from the memory, held-out loss: kept {velocity['memory']:.3f}, "
        f"reset {velocity['reset']:.3f} (1: no better than the teacher's mean)",
        flush=True,
    )
    episodes = int(demos.dones.sum())
    success = float(demos.success.sum()) / max(1, episodes)
    print(
        json.dumps(
            {
                "student": args.student,
                "episodes_ended": episodes,
                "student_success": success,
                "bins": bins,
                "velocity_loss_memory": velocity["memory"],
                "velocity_loss_reset": velocity["reset"],
            }
        )
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
