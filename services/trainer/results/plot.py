"""Learning curves of a run as PNG: `hamnet trainer plot RUN_DIR [--out FILE]`.

Reads `<run_dir>/metrics.jsonl` (one line per iteration) and draws, against env_transitions
(the paper's x-axis), the success rate, the episode return per reward term, the episode
length, and PPO's KL and learning rate (a DAgger run: its imitation loss, beta and the share
of steps the student acted): what a person checks to see whether a run learns.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only: no display on a training machine
import matplotlib.pyplot as plt

from hamnet.runtime.runs import read_metrics
from hamnet.task.rewards import REWARD_NAMES


def save_figure(figure: plt.Figure, out: Path, dpi: int = 110) -> Path:
    """Lay `figure` out, write it to `out` (its folder made) and close it; returns `out`."""
    figure.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(out, dpi=dpi)
    plt.close(figure)
    return out


def plot_run(rows: list[dict[str, float]], out: Path, title: str) -> Path:
    """Write the curves of `rows` to `out` (PNG); returns `out`."""
    x = [row["env_transitions"] / 1e6 for row in rows]
    series = lambda key: [row.get(key, math.nan) for row in rows]
    figure, axes = plt.subplots(2, 2, figsize=(11, 7), sharex=True)
    panels = [
        (axes[0, 0], "success rate (last episodes)", [("success_rate", "success")]),
        (
            axes[0, 1],
            "episode return per reward term",
            [(f"return/{name}", name) for name in REWARD_NAMES] + [("return/total", "total")],
        ),
        (axes[1, 0], "episode length (policy steps)", [("episode_length", "length")]),
    ]
    dagger = any("imitation_loss" in row for row in rows)
    if dagger:
        panels[0][2].append(("student_episode_success", "student-acted episodes"))
        panels.append(
            (
                axes[1, 1],
                "DAgger",
                [
                    ("imitation_loss", "imitation loss (MSE)"),
                    ("beta", "beta (teacher acts)"),
                    ("student_share", "student-acted share"),
                ],
            )
        )
    else:
        panels.append(
            (
                axes[1, 1],
                "PPO",
                [
                    ("approx_kl", "KL"),
                    ("learning_rate", "learning rate"),
                    ("clip_fraction", "clip fraction"),
                ],
            )
        )
    for axis, name, keys in panels:
        for key, label in keys:
            axis.plot(x, series(key), label=label, linewidth=1.2)
        axis.set_title(name)
        axis.grid(alpha=0.3)
        axis.legend(fontsize=8)
    if not dagger:
        axes[1, 1].set_yscale("log")
    for axis in axes[1]:
        axis.set_xlabel("env transitions (millions)")
    figure.suptitle(title)
    return save_figure(figure, out)


def main(argv: Sequence[str]) -> int:
    """`hamnet trainer plot RUN_DIR [--out FILE]`; returns the exit status."""
    parser = argparse.ArgumentParser(
        prog="hamnet trainer plot", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("run_dir", type=Path, help="a folder hamnet trainer wrote (its --run-dir)")
    parser.add_argument(
        "--out", type=Path, default=None, help="PNG to write (default RUN_DIR/curves.png)"
    )
    args = parser.parse_args(list(argv))
    try:
        rows = read_metrics(args.run_dir)
    except FileNotFoundError as error:
        print(f"hamnet trainer plot: {error}")
        return 2
    print(plot_run(rows, args.out or args.run_dir / "curves.png", str(args.run_dir)))
    return 0
