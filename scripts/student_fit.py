"""What limits a student's fit of its teacher: the noise of its updates or what it can learn.

The student acts alone (beta 0, as deployed) and the teacher labels every state, in windows
of the run's `--steps-per-rollout` steps as a DAgger run collects them; a second set of
windows, from other environments (another seed), is held out. Measured at the student's
weights:

- gradient agreement: the mean cosine between the imitation-loss gradients of independent
  held-out windows (1: every window asks for the same step; near 0: each update is mostly
  noise, and a smaller rate or a larger batch would fit better);
- the held-out imitation loss after fitting the same training windows three ways, each from
  the student's weights with a fresh Adam: as the run updates (the newest window only,
  `--dagger.epochs` steps each at `--dagger.lr`, in the order collected); the same at a
  tenth of the rate; and aggregated (every window kept, each step on the gradient of
  `--batch-windows` windows drawn at random, the rate falling linearly to zero over
  `--passes` passes);
- each fitted student's loss on the states it visits itself (new windows, it acting): a
  fit that holds there would hold in the run, whose next windows come from the updated
  student; one lost there is covariate shift;
- with `--episodes`, each one's held-out success on the run's evaluation episodes.

A loss that falls well below the as-run figure when the updates are less noisy says the
run's updates, not the student's inputs or size, limit its fit.

    python scripts/student_fit.py runs/dagger-guided-clean
    python scripts/student_fit.py easy-paddle-student --windows 32 --held-out 8

The last line printed is one JSON object with these figures.
"""

from __future__ import annotations

import argparse
import copy
import itertools
import json
import random
from collections.abc import Callable, Iterator

import torch

from hamnet.perception.config import student_clouds
from hamnet.policy.policy import Policy
from hamnet.policy.shipped import read_weights
from hamnet.policy.weights import policy_from
from hamnet.trainer.algorithms.dagger import Demonstrations, imitation_loss
from hamnet.trainer.algorithms.recurrent_unroll import episode_starts, evaluate_sequence
from hamnet.trainer.collection.dagger_worker import InProcessDagger
from hamnet.trainer.config import STUDENT_ALONE, DaggerConfig
from hamnet.trainer.results.evaluate import evaluate
from hamnet.trainer.results.summary import policy_and_result, run_of

Schedule = Iterator[tuple[list[Demonstrations], float]]
"""The windows of each Adam step and the step's learning rate."""


def windows(source: InProcessDagger, student: Policy, count: int, steps: int) -> list:
    """`count` consecutive windows of `steps` steps of every environment, the student acting."""
    made = []
    for i in range(count):
        counter = i * steps * source.num_envs
        made.append(source.collect(student, steps, counter, 0).rollout)
        if (i + 1) % 8 == 0 or i + 1 == count:
            print(f"window {i + 1}/{count}", flush=True)
    return made


def loss_of(student: Policy, window: Demonstrations) -> torch.Tensor:
    """The imitation loss of `student` on one window, its GRUs unrolled as in training."""
    starts = episode_starts(window.dones, window.first)
    return imitation_loss(
        evaluate_sequence(student, window.inputs, window.labels, starts).mean, window.labels
    )


def gradient(student: Policy, window: Demonstrations) -> torch.Tensor:
    """The flat gradient of the imitation loss on `window` at `student`'s weights."""
    student.zero_grad(set_to_none=True)
    loss_of(student, window).backward()
    return torch.cat([p.grad.flatten() for p in student.parameters() if p.grad is not None])


def held_out_loss(student: Policy, held_out: list[Demonstrations]) -> float:
    with torch.no_grad():
        return sum(loss_of(student, w).item() for w in held_out) / len(held_out)


def as_run(train: list[Demonstrations], epochs: int, lr: float) -> Callable[[], Schedule]:
    """The run's updates: `epochs` steps on each window in turn, at a constant rate."""
    return lambda: (([w], lr) for w in train for _ in range(epochs))


def aggregated(
    train: list[Demonstrations], batch: int, passes: int, lr: float, seed: int
) -> Callable[[], Schedule]:
    """Steps on `batch` windows drawn at random from all of them, `passes` x len/`batch`
    steps, the rate falling linearly from `lr` to zero."""

    def schedule() -> Schedule:
        draw = random.Random(seed)
        total = passes * len(train) // batch
        for step in range(total):
            yield draw.sample(train, batch), lr * (1 - step / total)

    return schedule


def fit(student: Policy, schedule: Schedule, max_grad_norm: float) -> Policy:
    """A copy of `student` after the `schedule`'s Adam steps (a fresh Adam)."""
    fitted = copy.deepcopy(student)
    fitted.train()
    optimizer = torch.optim.Adam(fitted.parameters())
    for batch, lr in schedule:
        for group in optimizer.param_groups:
            group["lr"] = lr
        optimizer.zero_grad(set_to_none=True)
        for window in batch:
            (loss_of(fitted, window) / len(batch)).backward()
        torch.nn.utils.clip_grad_norm_(list(fitted.parameters()), max_grad_norm)
        optimizer.step()
    fitted.eval()
    return fitted


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("student", help="a shipped student's name or a DAgger run's folder")
    parser.add_argument("--windows", type=int, default=48, help="training windows")
    parser.add_argument("--held-out", type=int, default=16, help="held-out windows")
    parser.add_argument("--steps", type=int, default=8, help="steps per window (the run's T)")
    parser.add_argument("--batch-windows", type=int, default=4, help="windows per aggregated step")
    parser.add_argument("--passes", type=int, default=4, help="aggregated passes over the windows")
    parser.add_argument("--seed", type=int, default=1, help="seed of the training environments")
    parser.add_argument(
        "--episodes", type=int, default=0, help="held-out episodes to score each student on"
    )
    args = parser.parse_args()
    torch.set_num_threads(1)
    torch.manual_seed(args.seed)
    student, result = policy_and_result(args.student)
    teacher = policy_from(read_weights(result["teacher"]))
    config = DaggerConfig()
    collect = lambda seed, n, acting: windows(
        InProcessDagger(run_of(result, seed), teacher, STUDENT_ALONE), acting, n, args.steps
    )
    train = collect(args.seed, args.windows, student)
    held_out = collect(args.seed + 1000, args.held_out, student)
    student.eval()
    grads = [gradient(student, w) for w in held_out]
    cosines = [
        torch.nn.functional.cosine_similarity(a, b, 0).item()
        for a, b in itertools.combinations(grads, 2)
    ]
    agreement = sum(cosines) / len(cosines)
    print(f"gradient agreement between held-out windows: mean cosine {agreement:.3f}", flush=True)
    arms = {
        "as_run": as_run(train, config.epochs, config.lr),
        "as_run_tenth_lr": as_run(train, config.epochs, config.lr / 10),
        "aggregated": aggregated(train, args.batch_windows, args.passes, config.lr, args.seed),
    }
    students = {"run": student} | {
        name: fit(student, schedule(), config.max_grad_norm) for name, schedule in arms.items()
    }
    after, own, success = {}, {}, {}
    for name, policy in students.items():
        after[name] = held_out_loss(policy, held_out)
        own[name] = held_out_loss(policy, collect(args.seed + 2000, args.held_out, policy))
        line = f"{name}: held-out loss {after[name]:.5f}, on its own states {own[name]:.5f}"
        if args.episodes:
            run = run_of(result)
            scored = evaluate(policy, run, args.episodes, result["env_steps"], student_clouds())
            success[name] = scored.success_rate
            line += f", success {scored.success_rate:.3f} on {args.episodes} episodes"
        print(line, flush=True)
    print(
        json.dumps(
            {
                "student": args.student,
                "windows": args.windows,
                "held_out_windows": args.held_out,
                "steps": args.steps,
                "gradient_cosine": agreement,
                "held_out_loss": after,
                "own_states_loss": own,
                "success": success,
            }
        )
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
