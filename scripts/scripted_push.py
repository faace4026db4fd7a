"""The easy stage's scripted reference: a hand-written pusher that reads the true state
(`hamnet.evaluation.scripted_pusher`) on the same held-out episodes as the PPO result, through
the same action space, safety filter and physics.

    python scripts/scripted_push.py          # docs/results/scripted-push.json + .png

It says what the stage asks of a learner: the success a controller that knows where the
object and its goal are gets from this arm, beside HAMnet's and the state MLP's (read from
docs/results/ppo-easy.json, the same 256 episodes).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from hamnet.evaluation.metrics import wilson_interval
from hamnet.evaluation.scripted_pusher import PusherConfig, scripted_held_out
from hamnet.runtime.runs import commit
from hamnet.sim.stages import stage_config
from hamnet.sim.task_config import TaskConfig
from hamnet.trainer.runners.run_config import RunConfig

ROOT = Path(__file__).resolve().parents[1]
PPO_RESULT = ROOT / "docs" / "results" / "ppo-easy.json"
TIGHT_RADIUS = TaskConfig().success_radius
"""The authors' success radius (the task's default, 0.05 m), reported beside the stage's 0.1 m."""


def interval(rate: float, episodes: int) -> list[float]:
    """95% Wilson interval of a success rate over `episodes`."""
    return [round(bound, 3) for bound in wilson_interval(round(rate * episodes), episodes)]


def plot(result: dict, start: np.ndarray, final: np.ndarray, out: Path) -> None:
    """Success of the three on the same episodes, and where the pusher left each object."""
    figure, (bars, scatter) = plt.subplots(1, 2, figsize=(12, 4.5))
    names = ["scripted pusher", "HAMnet (PPO, 1 h)", "state MLP (PPO, 1 h)"]
    rates = [result["success_rate"], *result["ppo_easy"].values()]
    episodes = result["eval_episodes"]
    low, high = zip(*(wilson_interval(round(rate * episodes), episodes) for rate in rates))
    errors = [np.subtract(rates, low), np.subtract(high, rates)]
    bars.bar(names, rates, yerr=errors, capsize=6, color=["tab:green", "tab:blue", "tab:orange"])
    bars.axhline(0.5, color="grey", linestyle="--", label="issue 28's goal")
    bars.set_ylabel(f"held-out success ({episodes} episodes, 95% Wilson)")
    bars.legend()
    scatter.scatter(start, final, s=10, alpha=0.6, color="tab:green")
    scatter.axhline(0.1, color="grey", linestyle="--", label="success radius 0.1 m")
    scatter.plot([0.1, 0.3], [0.1, 0.3], color="black", linewidth=0.8, label="not moved nearer")
    scatter.set_xlabel("object-goal distance at the start (m)")
    scatter.set_ylabel("at the end (m)")
    scatter.legend()
    for axis in (bars, scatter):
        axis.grid(alpha=0.3)
    figure.suptitle("The easy stage's scripted reference against PPO on the same episodes")
    figure.tight_layout()
    figure.savefig(out, dpi=100)
    plt.close(figure)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=256, help="held-out episodes")
    parser.add_argument("--seed", type=int, default=0, help="the run seed whose held-out episodes")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "scripted-push")
    args = parser.parse_args()
    pusher = PusherConfig()
    config = RunConfig(stage="easy", sim=stage_config("easy", seed=args.seed))
    print(f"scripted pusher on {args.episodes} held-out episodes of the easy stage", flush=True)
    held_out = scripted_held_out(config, args.episodes, pusher)
    ppo = json.loads(PPO_RESULT.read_text())
    result = {
        "success_rate": held_out.success_rate,
        "success_interval_95": interval(held_out.success_rate, args.episodes),
        "within_0.05m": held_out.within(TIGHT_RADIUS),
        "goal_return": held_out.goal_return,
        "median_final_distance_m": float(np.median(held_out.final_distance)),
        "median_start_distance_m": float(np.median(held_out.start_distance)),
        "eval_episodes": args.episodes,
        "ppo_easy": {
            "hamnet": ppo["final_success_rate"],
            "baseline": ppo["baseline_final_success_rate"],
        },
        "same_episodes_as_ppo_easy": args.seed == ppo["seed"]
        and args.episodes == ppo["eval_episodes"],
        "pusher": dataclasses.asdict(pusher),
        "stage": "easy",
        "seed": args.seed,
        "command": " ".join(["python", "scripts/scripted_push.py", *sys.argv[1:]]),
        "commit": commit(),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.with_suffix(".json").write_text(json.dumps(result, indent=1) + "\n")
    plot(result, held_out.start_distance, held_out.final_distance, args.out.with_suffix(".png"))
    print(
        json.dumps(
            {key: result[key] for key in ("success_rate", "success_interval_95", "within_0.05m")}
        )
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
