"""PPO at small scale (issue 27): the plain state-based MLP on the easy stage, trained by the
project's own trainer with its defaults and with the authors' update, against the outside
anchor the issue measured (a CleanRL-style PPO on the same stage), at equal transitions; and
any two variants of the trainer's update side by side (the action spaces, bfloat16).

    python scripts/ppo_small_scale.py                  # 2 M transitions per variant (about 1 h)
    python scripts/ppo_small_scale.py --transitions 300000 --out runs/ppo-small-scale-short
    python scripts/ppo_small_scale.py --from-runs      # rewrite the result from finished runs
    python scripts/ppo_small_scale.py --variants defaults paddle --no-anchor --seed 1 \
        --transitions 1200000 --runs runs/action-space-s1 --out docs/results/action-space-s1
                                                       # the action spaces (issue 28)
    python scripts/ppo_small_scale.py --architecture hamnet --variants paddle-float32 paddle-bfloat16 \
        --no-anchor --transitions 800000 --runs runs/bfloat16 --out docs/results/ppo-bfloat16
                                                       # HAMnet's update in bfloat16 (issue 28)

Two variants run side by side (one core each, one torch thread), each as
`hamnet trainer --inprocess --architecture state-mlp` (or `--architecture`) on the easy
stage, with the shipped encoder where the architecture reads clouds; the script writes
`docs/results/ppo-small-scale.json` and `.png`: per variant the training success rate per
0.1 M transitions, the deterministic policy's held-out success (`--eval-episodes`), and the
update's diagnostics (KL of the kept policy, clip fraction, gradient agreement, actor steps
kept, log std) that explain the difference, and each run's wall clock.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from hamnet.evaluation.metrics import wilson_interval
from hamnet.policy.registry import ARCHITECTURES
from hamnet.runtime.runs import commit, read_metrics
from hamnet.trainer.results.summary import repository_path

ROOT = Path(__file__).resolve().parents[1]

AUTHORS_FLAGS = (
    "--ppo.minibatches", "1", "--ppo.kl-stop", "before-step", "--ppo.lr-schedule", "adaptive",
    "--ppo.value-lr", "None",
    "--ppo.clip-per-term", "--samples-per-update", "512", "--init", "torch",
    "--log-std.mode", "schedule", "--log-std.initial", "-0.4",
)  # fmt: skip
"""The trainer before issue 27: the authors' update (`PPO_PRESETS["authors"]`) on 64 x 8
samples, PyTorch's initialization and the authors' log-std schedule."""

VARIANTS: dict[str, tuple[str, ...]] = {
    "defaults": (),
    "authors": AUTHORS_FLAGS,
    "paddle": ("--action-space", "paddle"),
    "paddle-float32": ("--action-space", "paddle", "--ppo.precision", "float32"),
    "paddle-bfloat16": ("--action-space", "paddle", "--ppo.precision", "bfloat16"),
}
"""Variant name -> the trainer flags that make it (beyond the shared ones): the defaults, the
authors' update, the defaults acting in the paddle-twist action space, and that with the
update's network passes in float32 and in bfloat16 (`PPOConfig.precision`)."""

ANCHOR = {
    "source": "issue 27, 'On the easy stage': a CleanRL-style PPO on privileged state (MLP 2x256 "
    "tanh, orthogonal init, learned log std from -0.5, fixed kp 150, +-0.1 rad joint residual, "
    "64 environments x 32 steps, 4 epochs x 4 minibatches, lr 3e-4, clip 0.2), joint friction "
    "about 1%, the easy stage as it is (0.05 m / 0.3 rad); training success over the episodes "
    "ending in each 0.1 M transitions",
    "env_transitions": [100_000, 200_000, 300_000, 700_000, 800_000, 1_400_000],
    "success_rate": [0.016, 0.031, 0.047, 0.073, 0.0575, 0.0575],
    "note": "0.8-1.4 M: 'flat at 0.05-0.065', drawn at the middle of that range",
}
"""The anchor's curve, as the issue reports it (the points it names)."""

BUCKET = 100_000
"""Transitions per point of the curves (the anchor's 0.1 M)."""


def run_variant(name: str, flags: tuple[str, ...], args: argparse.Namespace) -> subprocess.Popen:
    """Start one variant's trainer, its output to `<runs>/<name>.log`."""
    folder = args.runs / name
    folder.mkdir(parents=True, exist_ok=True)
    command = [sys.executable, "-m", "hamnet", "trainer", "--inprocess", "--architecture",
               args.architecture, "--stage", "easy", "--sim.seed", str(args.seed), "--sim.nthread", "1",
               "--learner-threads", "1", "--max-env-transitions", str(args.transitions), "--eval-episodes",
               str(args.eval_episodes), "--run-dir", repository_path(folder), *flags]  # fmt: skip
    environment = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONUNBUFFERED": "1"}
    log = (args.runs / f"{name}.log").open("w")
    return subprocess.Popen(
        command, stdout=log, stderr=subprocess.STDOUT, cwd=ROOT, env=environment
    )


def train(args: argparse.Namespace) -> None:
    """Every variant asked for, two at a time."""
    names = args.variants
    for start in range(0, len(names), 2):
        running = [run_variant(name, VARIANTS[name], args) for name in names[start : start + 2]]
        for process in running:
            if process.wait() != 0:
                raise SystemExit(f"a run failed: see {args.runs}/*.log")


def bucketed(rows: list[dict], key: str) -> tuple[list[float], list[float]]:
    """Mean of `key` over the iterations ending in each `BUCKET` transitions (NaN rows, as
    the first iteration's update figures, left out): x in transitions at the bucket's end."""
    sums: dict[int, list[float]] = {}
    for row in rows:
        value = row.get(key, math.nan)
        if isinstance(value, (int, float)) and math.isfinite(value):
            sums.setdefault(math.ceil(row["env_transitions"] / BUCKET), []).append(value)
    buckets = sorted(sums)
    return [b * BUCKET for b in buckets], [sum(sums[b]) / len(sums[b]) for b in buckets]


DIAGNOSTICS = ("approx_kl", "clip_fraction", "gradient_agreement", "gradient_steps", "log_std")


def summarise(rows: list[dict], summary: dict) -> dict:
    """A variant's curve, diagnostics per bucket and held-out result."""
    x, success = bucketed(rows, "success_rate")
    episodes = summary["eval_episodes"]
    successes = round(summary["final_success_rate"] * episodes)
    return {
        "held_out_success_rate": summary["final_success_rate"],
        "held_out_wilson_95": wilson_interval(successes, episodes),
        "held_out_episodes": episodes,
        "held_out_goal_return": summary["final_goal_return"],
        "env_transitions": x,
        "success_rate": success,
        "wall_clock_s": summary["wall_clock_s"],
        "wall_clock_per_bucket_s": bucketed(rows, "wall_clock_s")[1],
        "diagnostics": {key: bucketed(rows, key)[1] for key in DIAGNOSTICS},
        "run_command": summary["command"],
    }


def plot(variants: dict[str, dict], architecture: str, anchor: bool, out: Path) -> None:
    """Success against transitions (next to the anchor with `anchor`), and the diagnostics
    below."""
    figure, axes = plt.subplots(2, 3, figsize=(15, 8))
    success = axes[0, 0]
    if anchor:
        success.plot([x / 1e6 for x in ANCHOR["env_transitions"]], ANCHOR["success_rate"],
                     "k--o", label="anchor (CleanRL-style, issue 27)")  # fmt: skip
    for name, variant in variants.items():
        xs = [x / 1e6 for x in variant["env_transitions"]]
        success.plot(xs, variant["success_rate"],
                     label=f"{name} (held-out {variant['held_out_success_rate']:.3f}, "
                     f"{variant['wall_clock_s'] / 60:.0f} min)")  # fmt: skip
        for axis, key in zip(axes.flat[1:], DIAGNOSTICS, strict=True):
            axis.plot(xs, variant["diagnostics"][key], label=name)
            axis.set_title(key)
    success.set_title("training success rate per 0.1 M transitions")
    for axis in axes.flat:
        axis.set_xlabel("env transitions (millions)")
        axis.grid(alpha=0.3)
        axis.legend(fontsize=8)
    shown = ", ".join(variants) + (", the outside anchor" if anchor else "")
    figure.suptitle(f"{architecture} on the easy stage: {shown}")
    figure.tight_layout()
    figure.savefig(out, dpi=90)
    plt.close(figure)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--transitions", type=int, default=2_000_000, help="budget per variant")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--architecture", choices=ARCHITECTURES, default="state-mlp",
                        help="the policy both variants train (hamnet trainer --architecture)")  # fmt: skip
    parser.add_argument("--variants", nargs="+", choices=VARIANTS, default=["defaults", "authors"],
                        help="which variants to run, two side by side at a time")  # fmt: skip
    parser.add_argument("--no-anchor", action="store_true",
                        help="leave the anchor out (it was measured on the 0.05 m easy stage)")  # fmt: skip
    parser.add_argument("--eval-episodes", type=int, default=256,
                        help="held-out episodes of each final policy (deterministic)")  # fmt: skip
    parser.add_argument("--runs", type=Path, default=ROOT / "runs" / "ppo-small-scale")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "ppo-small-scale",
                        help="result path without suffix (.json and .png are written)")  # fmt: skip
    parser.add_argument("--from-runs", action="store_true", help="no training: summarise --runs")
    args = parser.parse_args()
    code = commit()
    if not args.from_runs:
        train(args)
    variants = {
        name: summarise(read_metrics(args.runs / name),
                        json.loads((args.runs / name / "summary.json").read_text()))
        for name in args.variants
    }  # fmt: skip
    result = {
        "stage": "easy",
        "architecture": args.architecture,
        "env_transitions": args.transitions,
        "variants": variants,
        "anchor": None if args.no_anchor else ANCHOR,
        "command": " ".join(
            [
                "python",
                "scripts/ppo_small_scale.py",
                *(a for a in sys.argv[1:] if a != "--from-runs"),
            ]
        ),
        "seed": args.seed,
        "commit": code,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.with_suffix(".json").write_text(json.dumps(result, indent=1) + "\n")
    plot(variants, args.architecture, not args.no_anchor, args.out.with_suffix(".png"))
    print(json.dumps({f"{name}_held_out_success_rate": v["held_out_success_rate"]
                      for name, v in variants.items()}))  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
