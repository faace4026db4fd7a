"""Issue 27: hamnet's PPO core against an outside PPO, Stable-Baselines3's, side by side on a
Gymnasium MuJoCo task with the same budget and seeds.

Runs per seed, two processes at a time (one torch thread each):
- reference: SB3's `PPO("MlpPolicy")` with RL-Zoo's MuJoCo defaults (`normalize: true`,
  i.e. `VecNormalize` of observations and rewards, one environment, SB3's defaults
  otherwise: rl-baselines3-zoo 208b6fd, hyperparams/ppo.yml, `Ant-v4: &mujoco-defaults`);
- ours: `hamnet.trainer.gym_adapter.GymPPO` with `STANDARD_PPO` (the same settings through
  hamnet's GAE, losses, update, return scaler and observation statistics);
- random: uniformly random actions on the same seeds, the floor of the normalised figure.

A run's final return is the mean undiscounted return of the episodes that ended in its last
10% of env steps; `ours_vs_reference` = (ours - random) / (reference - random), the share of
the reference's improvement over a random policy that ours reaches (goal >= 0.9). Writes
`<out>.json` and `<out>.png` (both implementations' mean and range over seeds against env
steps) and ends, on stdout, with one JSON line of the figures. Needs the `reference` extra
(`pip install -e '.[reference]'`).

    .venv/bin/python benchmarks/ppo_reference.py --quick   # 1 seed, 12k steps: under a minute
    .venv/bin/python benchmarks/ppo_reference.py           # 3 seeds, 299k steps: 10-45 min
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import subprocess
import sys
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from importlib.metadata import version
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

# Run as a script, so benchmarks/ is on sys.path.
from common import header, progress, report

from hamnet.runtime.runs import commit

# Imported before the worker processes fork, so every run trains with the code checked out
# when the benchmark started, even if the working tree changes while it runs.
from hamnet.trainer.config import PPO_PRESETS, PPOConfig
from hamnet.trainer.gym_adapter import STANDARD_PPO, GymPPO, GymPPOConfig

if TYPE_CHECKING:  # gymnasium is imported where a run needs it: the reference extra
    from gymnasium.vector import SyncVectorEnv

TASK = "Reacher-v5"
"""Every episode is truncated at 50 steps, so the bootstrap of truncated episodes carries
every episode's tail, and PPO learns it within a few hundred thousand steps: the reference,
seed 0, went from -44.7 (first 49k steps) to -6.3 (at 197k) and -5.06 (at 492k), where on
Hopper-v5 (seed 0) it was still climbing at 492k (156 -> 1586)."""
ENV_STEPS = 299_008
"""146 rollouts of 2048 steps: the reference's seed 0 ends at -5.20 there against -5.06 at
492k, so the budget covers its learning. SB3 steps about 1400 times a second on a free core
of this machine (3.5 minutes a run); with the cores shared, a run took 15-23 minutes."""
SEEDS = (0, 1, 2)
FINAL_SHARE = 0.1
"""The final return averages the episodes ending in this last share of the env steps."""
RANDOM_STEPS = 50_000
"""Env steps of the random policy per seed (1000 Reacher episodes)."""
BINS = 40
"""Points of the plotted curves."""


def make_env(task: str, seed: int) -> SyncVectorEnv:
    """One environment in a Gymnasium vector env with SAME_STEP autoreset (what
    `hamnet.trainer.gym_adapter` reads), its action space seeded."""
    import gymnasium as gym
    from gymnasium.vector import AutoresetMode, SyncVectorEnv

    env = SyncVectorEnv([lambda: gym.make(task)], autoreset_mode=AutoresetMode.SAME_STEP)
    env.single_action_space.seed(seed)
    return env


PPO_SETTINGS: dict[str, PPOConfig] = {"standard": STANDARD_PPO, **PPO_PRESETS}
"""Our side's update: standard PPO (the comparison), or one of the trainer's presets."""


def run_ours(task: str, env_steps: int, seed: int, ppo: str) -> dict:
    """Episodes (end step, return) and per-update figures of `GymPPO` on one seed with the
    update settings `PPO_SETTINGS[ppo]`."""
    import torch

    torch.set_num_threads(1)
    started = time.perf_counter()
    learner = GymPPO(make_env(task, seed), GymPPOConfig(ppo=PPO_SETTINGS[ppo]), seed)
    updates: list[dict[str, float]] = []
    learner.train(env_steps, updates.append)
    return {
        "episodes": learner.episodes,
        "updates": updates,
        "wall_clock_s": time.perf_counter() - started,
    }


def run_reference(task: str, env_steps: int, seed: int, ppo: str) -> dict:
    """Episodes (end step, return) and per-update figures of SB3's PPO on one seed."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.logger import KVWriter, Logger
    from stable_baselines3.common.vec_env import VecNormalize

    torch.set_num_threads(1)
    episodes: list[tuple[int, float]] = []
    updates: list[dict[str, float]] = []

    class Episodes(BaseCallback):
        """Collects the Monitor's undiscounted episode returns (before VecNormalize)."""

        def _on_step(self) -> bool:
            for info in self.locals["infos"]:
                if "episode" in info:
                    episodes.append((self.num_timesteps, float(info["episode"]["r"])))
            return True

    class Updates(KVWriter):
        """Keeps each update's logged training figures."""

        def write(self, key_values: dict, key_excluded: dict, step: int = 0) -> None:
            if "train/approx_kl" in key_values:
                updates.append(
                    {
                        "env_steps": step,
                        **{
                            k.split("/")[1]: float(v)
                            for k, v in key_values.items()
                            if k.startswith("train/")
                        },
                    }
                )

    started = time.perf_counter()
    env = VecNormalize(make_vec_env(task, n_envs=1, seed=seed))
    model = PPO("MlpPolicy", env, seed=seed, device="cpu")
    model.set_logger(Logger(folder=None, output_formats=[Updates()]))
    model.learn(env_steps, callback=Episodes())
    return {"episodes": episodes, "updates": updates, "wall_clock_s": time.perf_counter() - started}


def run_random(task: str, env_steps: int, seed: int, ppo: str) -> dict:
    """Episode returns of uniformly random actions on one seed."""
    env = make_env(task, seed)
    env.reset(seed=seed)
    running, episodes = 0.0, []
    for step in range(1, env_steps + 1):
        _, reward, terminated, truncated, _ = env.step(env.single_action_space.sample()[None])
        running += float(reward[0])
        if terminated[0] or truncated[0]:
            episodes.append((step, running))
            running = 0.0
    return {"episodes": episodes, "updates": [], "wall_clock_s": 0.0}


RUNS: dict[str, Callable[[str, int, int, str], dict]] = {
    "reference": run_reference,
    "ours": run_ours,
    "random": run_random,
}


def final_return(episodes: list[tuple[int, float]], env_steps: int, share: float) -> float:
    """Mean return of the episodes that ended in the last `share` of `env_steps`."""
    tail = [r for step, r in episodes if step > (1.0 - share) * env_steps]
    return float(np.mean(tail))


def curve(episodes: list[tuple[int, float]], env_steps: int, bins: int) -> list[float | None]:
    """Mean episode return in each of `bins` equal spans of env steps (None: no episode)."""
    steps = np.array([s for s, _ in episodes])
    returns = np.array([r for _, r in episodes])
    index = np.minimum((steps - 1) * bins // env_steps, bins - 1)
    return [float(returns[index == b].mean()) if (index == b).any() else None for b in range(bins)]


def diagnostics(updates: list[dict[str, float]]) -> dict[str, float]:
    """Means over the updates of the figures both implementations log, and of ours alone
    the agreement of two independent half-minibatches' actor gradients (SB3 has none)."""
    keys = ("approx_kl", "clip_fraction", "value_loss", "explained_variance", "gradient_agreement")
    return {
        k: float(np.nanmean([u[k] for u in updates])) for k in keys if updates and k in updates[0]
    }


def plot(path: Path, figures: dict) -> None:
    """Mean and range over seeds of each implementation's curve (`figures["curves"]`)
    against env steps, with the random policy's return."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    env_steps, bins = figures["env_steps"], len(figures["curves"]["ours"][str(figures["seeds"][0])])
    x = (np.arange(bins) + 0.5) * env_steps / bins
    labels = {
        "ours": f"ours (hamnet.trainer, {figures['settings']['ours']['ppo_settings']} PPO)",
        "reference": f"reference ({figures['reference_package']} {figures['reference_version']})",
    }
    figure, axis = plt.subplots(figsize=(7, 4.5))
    for name, per_seed in figures["curves"].items():
        y = np.array([[np.nan if v is None else v for v in c] for c in per_seed.values()])
        axis.plot(x, np.nanmean(y, 0), label=labels[name])  # y: (seeds, bins)
        axis.fill_between(x, np.nanmin(y, 0), np.nanmax(y, 0), alpha=0.25)
    axis.axhline(figures["random_return"], color="grey", linestyle="--", label="random actions")
    seeds = ", ".join(map(str, figures["seeds"]))
    axis.set(
        xlabel="env steps",
        ylabel="episode return",
        title=f"{figures['task']}: PPO, mean and range over seeds {seeds}",
    )
    axis.legend()
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)


def settings(ppo: str) -> dict:
    """Both sides' hyperparameters, for the JSON."""
    ours = dataclasses.asdict(GymPPOConfig(ppo=PPO_SETTINGS[ppo]))
    return {
        "ours": {"ppo_settings": ppo, **ours},
        "reference": "SB3 PPO defaults (n_steps 2048, batch_size 64, n_epochs 10, lr 3e-4, "
        "gamma 0.99, gae_lambda 0.95, clip 0.2, ent_coef 0, vf_coef 0.5, max_grad_norm 0.5, "
        "MlpPolicy 64x64 tanh, ortho init, log_std_init 0) with VecNormalize(norm_obs, "
        "norm_reward, clip 10, gamma 0.99) on 1 env: RL-Zoo's MuJoCo defaults "
        "(rl-baselines3-zoo 208b6fd, hyperparams/ppo.yml, Ant-v4: &mujoco-defaults)",
    }


def run_all(task: str, env_steps: int, seeds: list[int], ppo: str) -> dict[str, list[dict]]:
    """Every run of every seed, two worker processes at a time; per kind, one result a seed."""
    budget = {name: env_steps for name in RUNS} | {"random": min(env_steps, RANDOM_STEPS)}
    with ProcessPoolExecutor(max_workers=2) as pool:
        futures = {
            name: [pool.submit(_run, name, task, budget[name], seed, ppo) for seed in seeds]
            for name in RUNS
        }
        results = {name: [f.result() for f in per_seed] for name, per_seed in futures.items()}
    for name, per_seed in results.items():
        for result in per_seed:
            result["env_steps"] = budget[name]
    return results


def figures_of(
    results: dict[str, list[dict]], args: argparse.Namespace, env_steps: int, code: dict
) -> dict:
    """The result's figures: final returns per kind and seed, the normalised ratio, both
    sides' settings and diagnostics, the curves, and how to reproduce it (`code`: the
    checkout the runs imported, `checkout()` before they started)."""
    seeds = [str(seed) for seed in args.seeds]
    share = {name: FINAL_SHARE for name in RUNS} | {"random": 1.0}
    finals = {
        name: [final_return(r["episodes"], r["env_steps"], share[name]) for r in per_seed]
        for name, per_seed in results.items()
    }
    mean = {name: float(np.mean(values)) for name, values in finals.items()}
    learners = ("ours", "reference")
    return {
        **header("ppo_reference", args.quick),
        "task": args.task,
        "env_steps": env_steps,
        "seeds": args.seeds,
        "ours_final_return": mean["ours"],
        "reference_final_return": mean["reference"],
        "random_return": mean["random"],
        "ours_vs_reference": (mean["ours"] - mean["random"]) / (mean["reference"] - mean["random"]),
        **{f"{name}_final_returns": finals[name] for name in RUNS},
        "final_return": f"mean return of the episodes ending in the last {FINAL_SHARE:.0%} "
        "of env steps, then mean over seeds; random: every episode of "
        f"{results['random'][0]['env_steps']} steps of uniform actions",
        "reference_package": "stable-baselines3",
        "reference_version": version("stable-baselines3"),
        "gymnasium_version": version("gymnasium"),
        "settings": settings(args.ppo),
        "diagnostics": {
            name: dict(zip(seeds, (diagnostics(r["updates"]) for r in results[name])))
            for name in learners
        },
        "wall_clock_s": {name: [r["wall_clock_s"] for r in results[name]] for name in learners},
        "curves": {
            name: dict(zip(seeds, (curve(r["episodes"], env_steps, BINS) for r in results[name])))
            for name in learners
        },
        "command": " ".join(["python", "benchmarks/ppo_reference.py", *sys.argv[1:]]),
        **code,
    }


def checkout() -> dict:
    """The commit checked out and the package's files changed from it (`uncommitted`: the
    code that trained differs from `commit` there; empty, it is that commit's)."""
    status = subprocess.run(
        ["git", "status", "--porcelain", "--", "services"],
        capture_output=True,
        text=True,
        check=False,
        cwd=Path(__file__).resolve().parents[1],
    )
    return {"commit": commit(), "uncommitted": [line[3:] for line in status.stdout.splitlines()]}


def write(out: Path, figures: dict) -> None:
    """`<out>.json` with every figure and `<out>.png` with the curves."""
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps(figures, indent=1) + "\n")
    plot(out.with_suffix(".png"), figures)
    progress(f"wrote {out.with_suffix('.json')} and {out.with_suffix('.png')}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="1 seed, 12k env steps, no files")
    parser.add_argument("--task", default=TASK)
    parser.add_argument("--env-steps", type=int, default=None)
    parser.add_argument("--seeds", type=int, nargs="+", default=None)
    parser.add_argument(
        "--ppo",
        choices=sorted(PPO_SETTINGS),
        default="standard",
        help="our update's settings: standard PPO, or a trainer preset",
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="files <out>.json and <out>.png (default docs/results/"
        "ppo-reference; --quick writes none unless given)",
    )
    args = parser.parse_args()
    env_steps = args.env_steps or (12_288 if args.quick else ENV_STEPS)
    args.seeds = args.seeds or ([0] if args.quick else list(SEEDS))
    out = args.out or (None if args.quick else Path("docs/results/ppo-reference"))
    os.environ["OMP_NUM_THREADS"] = "1"
    code = checkout()  # what the runs import: the package was imported above, before they fork
    results = run_all(args.task, env_steps, args.seeds, args.ppo)
    figures = figures_of(results, args, env_steps, code)
    if out is not None:
        write(out, figures)
    del figures["curves"]  # in the file; the stdout line stays short
    report(figures)


def _run(name: str, task: str, env_steps: int, seed: int, ppo: str) -> dict:
    """One run in a worker process, with a progress line at its end."""
    started = time.perf_counter()
    result = RUNS[name](task, env_steps, seed, ppo)
    seconds = time.perf_counter() - started
    progress(f"{name} seed {seed}: {len(result['episodes'])} episodes in {seconds:.0f} s")
    return result


if __name__ == "__main__":
    main()
