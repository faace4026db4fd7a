"""Sim benchmark: how close `VectorEnv` steps come to raw MuJoCo on the same world, and how
they scale with threads.

Consumes the sim core only (no networking). For each environment count and thread count it
builds one `VectorEnv`, resets it, and measures in the same run, alternating round by round:

- raw: a `mujoco.batch.Batch` of the same compiled world (`env.world.model`) with the
  environment's per-environment fields and state copied in (same scenes, objects, contacts),
  persistent like the env's, stepped with `Batch.step(nstep=40)` and nothing in between:
  the ceiling.
- ours: `VectorEnv.step` with commands that hold the arm (kp = 100, rho = 1), so it includes
  what a policy step costs besides physics: writing gains, the per-sample references, the
  observation, rewards and termination, and the resets of episodes that end. Episodes time
  out after `timeout` steps (their start is staggered over it, as in a long run) so resets
  happen at a steady rate; `reset_share` is `env.reset_seconds` over the wall time.

Produces a table on stdout, a progress line per configuration on stderr and, as the last
stdout line, one JSON object: `ratio_vs_raw` (our physics steps/s over raw at the largest
environment count, all threads; goal >= 0.85), `thread_scaling` (ours, largest count,
most threads over one thread; goal >= 1.7), `env_steps_per_s_64`, reset costs,
`near_start_fallback_rate` (near starts that found no collision-free arm posture and start
retracted, every start near, the curriculum's first ceiling mix; goal <= 0.05; `_end`: its
last mix) and every row under `results`.

    .venv/bin/python benchmarks/sim.py --quick     # < 1 min on 2 cores
    .venv/bin/python benchmarks/sim.py             # full sweep

With `--backend warp` it measures the MuJoCo Warp backend instead (`--warp-device`, default
cuda): `VectorEnv.step` at each of `--warp-num-envs` environments, against the C engine's
`VectorEnv.step` at the same count, as `env_steps_per_s` per count and
`warp_vs_mujoco_<largest>`. Without a CUDA device for a cuda run, the JSON says so
(`not_measured`) and the exit status is 0: the backend's results are checked on Warp's CPU
device by tests/sim/test_warp_backend.py, its speed needs a GPU.
"""

from __future__ import annotations

import dataclasses
import os
import platform
import time
from dataclasses import dataclass
from importlib import metadata
from typing import Literal

import mujoco
import numpy as np
import tyro

# Run as a script, so benchmarks/ is on sys.path: the helpers every benchmark shares.
from common import header, median_p99, print_header, progress, report
from mujoco.batch import Batch

from hamnet.messages.safe_command import hold_command
from hamnet.sim.config import SimConfig
from hamnet.sim.curriculum import curriculum_values, scene_config_at
from hamnet.sim.env import VectorEnv
from hamnet.sim.episodes import draw_episodes


@dataclass(frozen=True)
class SimBenchConfig:
    """What to sweep and for how long."""

    quick: bool = False
    """A short run (fewer steps per configuration) for smoke tests, under a minute."""
    num_envs: tuple[int, ...] = (1, 16, 64)
    """Environment counts; the largest is the one the figures name."""
    threads: tuple[int, ...] = (1, 2)
    """Physics thread counts."""
    steps: int = 240
    """Policy steps measured per configuration and path (quick: 30)."""
    rounds: int = 6
    """Raw and ours alternate this many times per configuration, sharing `steps`."""
    warmup: int = 3
    """Policy steps of each path before measuring."""
    timeout: int = 100
    """Episode length in policy steps (10 s): the hold command never succeeds nor drops the
    object, so timeouts set the reset rate; 100 is between early training (frequent drops)
    and the task's 300-step limit."""
    num_objects: int = 16
    """Procedural objects in the library (the sim's default)."""
    seed: int = 0
    backend: Literal["mujoco", "warp"] = "mujoco"
    """`warp`: measure the MuJoCo Warp backend (`hamnet.sim.warp_physics`) instead."""
    warp_device: str = "cuda"
    """Warp's device for `--backend warp`."""
    warp_num_envs: tuple[int, ...] = (1024, 2048, 4096, 8192)
    """Environment counts of `--backend warp` (quick: the first)."""
    fallback_draws: int = 6
    """Episodes per environment (largest count, every start near) for the fallback rate of
    near starts, per ceiling mix (quick: 2)."""

    @property
    def measured_steps(self) -> int:
        """Policy steps per configuration and path."""
        return 30 if self.quick else self.steps

    @property
    def measured_fallback_draws(self) -> int:
        """Episodes per environment and ceiling mix for the near-start fallback rate."""
        return 2 if self.quick else self.fallback_draws


def make_env(
    config: SimBenchConfig, num_envs: int, nthread: int, backend: str = "mujoco"
) -> VectorEnv:
    """A reset env whose episodes are at staggered steps of their `timeout`."""
    sim = SimConfig(
        num_envs=num_envs,
        nthread=nthread,
        num_objects=config.num_objects,
        seed=config.seed,
        backend=backend,
        warp_device=config.warp_device,
    )
    sim = dataclasses.replace(sim, task=dataclasses.replace(sim.task, timeout=config.timeout))
    env = VectorEnv(sim)
    env.reset(config.seed)
    rng = np.random.default_rng(config.seed)
    env.episode_step[:] = rng.integers(0, config.timeout, num_envs)  # as in a long run
    return env


def raw_copy(env: VectorEnv, nthread: int) -> Batch:
    """A persistent Batch of the env's world with its per-environment fields and state."""
    physics = env.physics
    raw = Batch(env.world.model, env.num_envs, nthread=nthread, persistent=True)
    for name, values in physics.fields.items():
        raw.expand(name)[:] = values
    raw.set_const()
    raw.bind("qpos")[:] = physics.qpos
    raw.bind("qvel")[:] = physics.qvel
    raw.bind("ctrl")[:] = physics.qpos[:, env.world.robot_qpos]  # hold: the reference is q
    raw.forward()
    return raw


@dataclass
class Timings:
    """Wall time of each policy step of one path, and what happened meanwhile."""

    seconds: list[float] = dataclasses.field(default_factory=list)
    reset_seconds: float = 0.0
    resets: int = 0

    def summary(self, num_envs: int, physics_steps: int) -> dict[str, float]:
        total = float(np.sum(self.seconds))
        median_ms, p99_ms = median_p99(self.seconds, 1e3)
        return {
            "env_steps_per_s": round(num_envs * len(self.seconds) / total, 1),
            "physics_steps_per_s": round(num_envs * physics_steps * len(self.seconds) / total, 1),
            "step_median_ms": round(median_ms, 3),
            "step_p99_ms": round(p99_ms, 3),
            "reset_share": round(self.reset_seconds / total, 4),
            "resets": self.resets,
            "reset_ms": round(1e3 * self.reset_seconds / self.resets, 3) if self.resets else None,
        }


def time_raw(raw: Batch, nstep: int, count: int, out: Timings) -> None:
    for _ in range(count):
        started = time.perf_counter()
        raw.step(nstep=nstep)
        out.seconds.append(time.perf_counter() - started)


def time_ours(env: VectorEnv, count: int, out: Timings) -> None:
    samples = env.config.control_samples
    observation = env.observe()
    for _ in range(count):
        command = hold_command(observation.q, samples)  # what the safety filter would send
        resetting, episodes = env.reset_seconds, int(env.episode_ids.max())
        started = time.perf_counter()
        observation = env.step(command).observation
        out.seconds.append(time.perf_counter() - started)
        out.reset_seconds += env.reset_seconds - resetting
        out.resets += int(env.episode_ids.max()) - episodes


def measure(config: SimBenchConfig, num_envs: int, nthread: int) -> dict:
    """Raw and ours for one environment count and thread count, interleaved."""
    env = make_env(config, num_envs, nthread)
    nstep = env.config.physics_steps_per_sample * env.config.control_samples  # 40
    time_ours(env, config.warmup, Timings())  # also sets the gains the raw copy takes over
    raw = raw_copy(env, nthread)
    time_raw(raw, nstep, config.warmup, Timings())
    raw_t, ours_t = Timings(), Timings()
    chunk = max(config.measured_steps // config.rounds, 1)
    for _ in range(config.rounds):
        time_raw(raw, nstep, chunk, raw_t)
        time_ours(env, chunk, ours_t)
    raw_s, ours_s = raw_t.summary(num_envs, nstep), ours_t.summary(num_envs, nstep)
    ratio = ours_s["physics_steps_per_s"] / raw_s["physics_steps_per_s"]
    excluding = float(np.sum(ours_t.seconds)) - ours_t.reset_seconds
    return {
        "num_envs": num_envs,
        "nthread": nthread,
        "raw": raw_s,
        "ours": ours_s,
        "ratio_vs_raw": round(ratio, 3),
        "ratio_vs_raw_without_resets": round(float(np.sum(raw_t.seconds)) / excluding, 3),
    }


def print_table(rows: list[dict]) -> None:
    print_header(
        f"{'envs':>4} {'thr':>3} {'raw phys/s':>11} {'our phys/s':>11} {'env steps/s':>11} "
        f"{'ratio':>6} {'w/o reset':>9} {'step med':>9} {'p99':>8} {'resets':>6} "
        f"{'reset %':>7} {'ms/reset':>8}"
    )
    for row in rows:
        raw, ours = row["raw"], row["ours"]
        per_reset = f"{ours['reset_ms']:.1f}" if ours["reset_ms"] is not None else "-"
        print(
            f"{row['num_envs']:>4} {row['nthread']:>3} {raw['physics_steps_per_s']:>11.0f} "
            f"{ours['physics_steps_per_s']:>11.0f} {ours['env_steps_per_s']:>11.0f} "
            f"{row['ratio_vs_raw']:>6.3f} {row['ratio_vs_raw_without_resets']:>9.3f} "
            f"{ours['step_median_ms']:>9.2f} {ours['step_p99_ms']:>8.2f} {ours['resets']:>6} "
            f"{ours['reset_share']:>7.1%} {per_reset:>8}"
        )
    print("(phys/s: physics steps of all environments per second; step med/p99: ms per policy "
          "step of ours; ratio: ours over raw physics steps/s)")  # fmt: skip


def near_start_fallbacks(config: SimBenchConfig, num_envs: int) -> dict[str, float]:
    """Share of near starts that fall back to the retracted pose (`Episodes.start_fallback`)
    with every start near, `fallback_draws` episodes per environment, the ceilings mixed as
    at the curriculum's start (p_tight 1/3, the figure named) and at its end (5/6); and the
    wall time of such a draw per environment, ms."""
    sim = SimConfig(num_envs=num_envs, nthread=1, num_objects=config.num_objects, seed=config.seed)
    env = VectorEnv(sim)
    ids = np.arange(num_envs)
    figures = {}
    end = sim.curriculum.start_step + sim.curriculum.num_steps
    for name, counter in (("start", 0), ("end", end)):
        values = curriculum_values(counter, sim.curriculum)
        scene = scene_config_at(values, sim.scene)
        started, fallbacks = time.perf_counter(), []
        for _ in range(config.measured_fallback_draws):
            drawn = draw_episodes(env.rng, env.physics, env.kinematics, env.library, ids, sim,
                                  scene, p_near_init=1.0)  # fmt: skip
            fallbacks.append(drawn.start_fallback)
        elapsed = time.perf_counter() - started
        figures[f"near_start_fallback_rate_{name}"] = round(float(np.mean(fallbacks)), 4)
        figures[f"near_start_draw_ms_{name}"] = round(1e3 * elapsed / np.size(fallbacks), 3)
    return figures


def warp_main(config: SimBenchConfig) -> dict:
    """The warp backend's env steps/s against the C engine's at each count."""
    import warp as wp  # only for this measurement

    figures = {**header("sim", config.quick), "backend": "warp", "device": config.warp_device}
    if config.warp_device.startswith("cuda") and wp.get_cuda_device_count() == 0:
        return {**figures, "not_measured": "no CUDA device on this machine"}
    counts = config.warp_num_envs[:1] if config.quick else config.warp_num_envs
    steps, rows = max(2, config.measured_steps // 6), {}
    for num_envs in counts:
        rates = {}
        for backend in ("warp", "mujoco"):
            env = make_env(config, num_envs, 0, backend)
            time_ours(env, config.warmup, Timings())  # Warp compiles its kernels here
            timings = Timings()
            time_ours(env, steps, timings)
            rates[backend] = round(num_envs * steps / sum(timings.seconds), 1)
        progress(f"{num_envs} envs: warp {rates['warp']}, mujoco {rates['mujoco']} env steps/s")
        rows[num_envs] = rates
    largest = max(rows)
    return {
        **figures,
        f"env_steps_per_s_{largest}": rows[largest]["warp"],
        f"warp_vs_mujoco_{largest}": round(rows[largest]["warp"] / rows[largest]["mujoco"], 4),
        "results": {str(count): rates for count, rates in rows.items()},
        "steps": steps,
        "cpus": os.cpu_count(),
    }


def main(config: SimBenchConfig) -> dict:
    """Run the sweep; returns the JSON figures."""
    if config.backend == "warp":
        return warp_main(config)
    started = time.monotonic()
    rows = []
    for num_envs in config.num_envs:
        for nthread in config.threads:
            row = measure(config, num_envs, nthread)
            progress(
                f"{num_envs} envs, {nthread} threads: raw {row['raw']['physics_steps_per_s']:.0f}, "
                f"ours {row['ours']['physics_steps_per_s']:.0f} physics steps/s "
                f"(ratio {row['ratio_vs_raw']:.3f}, resets {row['ours']['reset_share']:.1%})"
            )
            rows.append(row)
    print_table(rows)
    fallbacks = near_start_fallbacks(config, max(config.num_envs))
    progress(f"near starts: {fallbacks}")
    largest, most, fewest = max(config.num_envs), max(config.threads), min(config.threads)
    at = {(r["num_envs"], r["nthread"]): r for r in rows}
    top, single = at[(largest, most)], at[(largest, fewest)]
    reset_ms = [r["ours"]["reset_ms"] for r in rows if r["ours"]["resets"]]

    def scaling(path: str) -> float:
        return round(top[path]["physics_steps_per_s"] / single[path]["physics_steps_per_s"], 3)

    figures = {
        **header("sim", config.quick),
        "ratio_vs_raw": top["ratio_vs_raw"],
        "ratio_vs_raw_without_resets": top["ratio_vs_raw_without_resets"],
        "thread_scaling": scaling("ours"),
        "raw_thread_scaling": scaling("raw"),
        f"env_steps_per_s_{largest}": top["ours"]["env_steps_per_s"],
        f"physics_steps_per_s_{largest}": top["ours"]["physics_steps_per_s"],
        f"raw_physics_steps_per_s_{largest}": top["raw"]["physics_steps_per_s"],
        f"reset_share_{largest}": top["ours"]["reset_share"],
        "reset_ms_median": round(float(np.median(reset_ms)), 3) if reset_ms else None,
        "near_start_fallback_rate": fallbacks["near_start_fallback_rate_start"],
        **fallbacks,
        "largest_num_envs": largest,
        "threads": list(config.threads),
        "results": rows,
        "steps": config.measured_steps,
        "timeout": config.timeout,
        "num_objects": config.num_objects,
        "seed": config.seed,
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "mujoco": mujoco.__version__,
        "numpy": metadata.version("numpy"),
        "elapsed_s": round(time.monotonic() - started, 1),
    }
    figures["goals"] = {
        "ratio_vs_raw_at_least_0.85": figures["ratio_vs_raw"] >= 0.85,
        "thread_scaling_at_least_1.7": figures["thread_scaling"] >= 1.7,
        "near_start_fallback_rate_at_most_0.05": figures["near_start_fallback_rate"] <= 0.05,
    }
    return figures


if __name__ == "__main__":
    report(main(tyro.cli(SimBenchConfig, description=__doc__)))
