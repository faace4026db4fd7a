"""Training benchmark: env steps per second of PPO with learning included, against the physics
ceiling of the same world, and where a step's time goes.

Measures in one run, on the easy stage with HAMnet on its paper inputs:
- inprocess: `hamnet trainer --inprocess`'s loop (`Runner.iterate`: two groups of environments, one
  group's physics overlapping the other's networks), learning included, at the default
  precision (bfloat16 encoder layers and update passes where the CPU has native bfloat16);
- inprocess float32: the same loop with the encoder and the update in float32
  (`--encoder-precision float32 --ppo.precision float32`);
- workers: the same loop learning from `hamnet rollout` processes over Zenoh on loopback
  (`hamnet.trainer.collection.streamed.Streamed`), with 1 worker of B environments and 2 of B/2 each;
- workers acting while the trainer learns: 1 worker of B environments that goes on acting
  on the weights it has while the trainer's update (one thread) runs, its chunks up to
  `LEARNING_LAG` version old (`--max-policy-lag 1`): collection overlapped with learning;
- sequential: the same loop with one group (physics, then the networks), and the share of
  each component in its step: sim, perception, policy, safety, learner;
- the seconds an update of each component in the overlapped and the sequential loop (timed
  in the measured iterations themselves), and how busy the overlapped loop's two threads
  were while it acted (`overlap_busy`: physics, networks), which says what overlapping
  can still gain;
- physics ceiling: a raw `mujoco.batch.Batch` of the same compiled world, per-environment
  fields and state, stepped 40 physics steps per policy step and nothing else;
- services: the same loop learning from the service chain, `hamnet sim`, `perception`,
  `policy --rollout-horizon T` and `safety --profile training` as processes on loopback, the
  policy service assembling the chunks (tests/stack/test_chain_rollouts.py). The chain keeps
  stepping while the trainer learns, so the trainer accepts chunks up to `CHAIN_LAG`
  versions old. If its first update has not come within `--chain-deadline-s` (the four
  services start in the measured window's warm-up), the ratio is null and the JSON says why.

Produces a progress line per setup on stderr and, as the last stdout line, one JSON object
with `inprocess_env_steps_per_s`, `inprocess_vs_physics_ceiling` (goal >= 0.33),
`inprocess_float32_env_steps_per_s` and `precision_speedup` (default / float32),
`overlap_speedup`, `shares`, `seconds_per_update`, `overlap_busy`,
`workers_vs_inprocess` (the faster of 1 and 2 workers, both
reported), `workers_acting_while_learning_env_steps_per_s` with its ratios to in-process
and to the ceiling, and `services_vs_inprocess` (goal >= 0.8); and per setup the update's seconds an
iteration (`update_s`) and the rate of the iteration less it (`acting_env_steps_per_s`,
`workers_vs_inprocess_acting`): how many steps an update keeps varies from run to run
and setup to setup, and moves the rates with learning by a tenth or more.

    .venv/bin/python benchmarks/training.py --quick     # 16 envs x 32 steps, 2 iterations, 1 worker
    .venv/bin/python benchmarks/training.py             # 64 envs x 128 steps (the run's), 3 iterations

`--quick` is a smoke run of every setup: 16 environments (rates are lower than with 64, and
the ratios noisier), 512 samples an update, 2 measured iterations a setup, and one rollout
worker (its `workers_2_env_steps_per_s` is null). The full run learns from the run's 8192
samples an update: the in-process trainer learns on every core while its environments
wait (`RunConfig.learner_threads`), and so does one fed by synchronous workers. The process setups' start (torch and the networks
load in each) is in their unmeasured warm-up iteration.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import threading
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from tempfile import TemporaryDirectory

# Run as a script, so benchmarks/ is on sys.path: the helpers every benchmark shares and
# the sim benchmark's raw copy of a world.
from common import header, loopback_transport, progress, report, spawn, stop
from sim import raw_copy

from hamnet.runtime.compute import native_bfloat16
from hamnet.runtime.service import Service, ServiceIdentity
from hamnet.sim.config import SimConfig
from hamnet.sim.stages import stage_config
from hamnet.trainer.collection.streamed import Streamed
from hamnet.trainer.runners.run_config import RunConfig
from hamnet.trainer.runners.runner import Runner

FULL_STEPS, QUICK_STEPS = 128, 32
"""T of the benchmark's iterations: at 64 environments 128 makes the run's 8192 samples per
update (`RunConfig.samples_per_update`), whose minibatches of 2048 the learner's cost per
sample depends on; `--quick` takes 16 x 32 = 512 samples (minibatches of 128) to stay
under a minute, so its learner share is not the run's."""
LEARNING_LAG = 1
"""Versions a worker's chunk may lag when it acts while the trainer learns: one, the
rollout acted during the update of the one before (`workers_acting_while_learning`)."""
CHAIN_LAG = 8
"""Versions a chain's chunk may lag the trainer (as tests/stack/test_chain_rollouts.py)."""


def timed(function: Callable, seconds: dict[str, float], name: str) -> Callable:
    """`function`, adding its wall time to `seconds[name]`."""

    def wrapper(*args, **kwargs):
        started = time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            seconds[name] += time.perf_counter() - started

    return wrapper


def per_iteration(seconds: dict[str, float], elapsed: float, iterations: int) -> dict[str, float]:
    """Summed component `seconds` and the measured window's `elapsed` wall time as seconds an
    iteration (the whole as `iteration`)."""
    per = {name: round(value / iterations, 3) for name, value in sorted(seconds.items())}
    return {**per, "iteration": round(elapsed / iterations, 3)}


def acting_seconds(seconds: dict[str, float]) -> float:
    """An iteration's seconds less its update's (`per_iteration`'s `iteration`, `learner`)."""
    return seconds["iteration"] - seconds["learner"]


def instrument(runner: Runner) -> dict[str, float]:
    """Seconds each component of `runner`'s loop takes from now on, summed over its calls:
    sim (`env.step`, in the physics thread when overlapped), perception, policy, safety,
    learner. The wrappers cost two clock reads a call."""
    seconds: dict[str, float] = defaultdict(float)
    for worker in runner.source.workers:
        worker.env.step = timed(worker.env.step, seconds, "sim")
        worker.perception.step = timed(worker.perception.step, seconds, "perception")
        worker.perception.start_episodes = timed(
            worker.perception.start_episodes, seconds, "perception"
        )
        worker.safety.command = timed(worker.safety.command, seconds, "safety")
    runner.policy.act = timed(runner.policy.act, seconds, "policy")
    runner.algorithm.learn = timed(runner.algorithm.learn, seconds, "learner")
    return seconds


def loop_rate(config: RunConfig, iterations: int) -> tuple[float, dict[str, float], Runner]:
    """Env steps/s of `iterations` iterations after one warm-up, learning included, the
    seconds per iteration of the whole (`iteration`) and of each component (`instrument`),
    and the runner."""
    runner = Runner(config)
    runner.iterate()
    seconds = instrument(runner)
    started = time.perf_counter()
    for _ in range(iterations):
        runner.iterate()
    elapsed = time.perf_counter() - started
    steps = iterations * config.num_envs * config.rollout_steps
    return steps / elapsed, per_iteration(seconds, elapsed, iterations), runner


def shares_of(seconds: dict[str, float]) -> dict[str, float]:
    """Each component's share of a sequential iteration's wall time (`loop_rate`'s seconds
    of a one-group loop, where the components take turns), and the rest as `other`."""
    total = seconds["iteration"]
    shares = {
        name: round(value / total, 3) for name, value in seconds.items() if name != "iteration"
    }
    shares["other"] = round(1.0 - sum(shares.values()), 3)
    return shares


def acting_rate(samples: int, seconds: dict[str, float]) -> float:
    """Env steps/s of an iteration less its update (`seconds`: `iteration`, `learner`): what
    a synchronous setup's acting ran at. From a fresh policy the actor keeps 20-30 of its 32
    steps, as many as the setup's own rollout allows, so the update took 5.9-7.8 s of an
    iteration from run to run and setup to setup; acting rates compare setups without it."""
    return round(samples / acting_seconds(seconds), 1)


def overlap_busy(seconds: dict[str, float]) -> dict[str, float]:
    """The share of the overlapped loop's acting time (its iteration less the update) that
    each of its two threads spent working: the physics thread in `env.step`, the main thread
    in perception, policy and safety. Both near 1: the overlap is balanced and only less work
    per step makes acting faster."""
    acting = acting_seconds(seconds)
    networks = seconds["perception"] + seconds["policy"] + seconds["safety"]
    return {"physics": round(seconds["sim"] / acting, 3), "networks": round(networks / acting, 3)}


def remote_rate(
    sim: SimConfig,
    commands: list[list[str]],
    workers: int,
    max_policy_lag: int,
    steps: int,
    iterations: int,
    run_dir: Path,
    deadline_s: float | None = None,
) -> tuple[float, dict[str, float]] | None:
    """Env steps/s of the loop learning from rollouts that `commands` (`hamnet` processes,
    started on a loopback network of their own) stream from `workers` sources of
    `sim.num_envs` environments each, `steps` steps a rollout, after one warm-up iteration
    that includes their start, and the seconds an iteration of the whole and of its update
    (`iteration`, `learner`); None when that iteration has not ended within `deadline_s`
    (None: no deadline)."""
    transport = loopback_transport()
    processes = [spawn(command, transport) for command in commands]
    try:
        with Service(ServiceIdentity("trainer", "bench"), transport) as service:
            config = RunConfig(sim=sim, run_dir=run_dir, steps_per_rollout=steps)
            runner = Runner(config, lambda policy: Streamed(
                service, policy, workers, sim.num_envs, max_policy_lag))  # fmt: skip
            timer = None if deadline_s is None else threading.Timer(deadline_s, service.stop)
            if timer is not None:
                timer.start()
            try:
                runner.iterate()
            except InterruptedError:
                return None
            finally:
                if timer is not None:
                    timer.cancel()
            seconds: dict[str, float] = defaultdict(float)
            runner.algorithm.learn = timed(runner.algorithm.learn, seconds, "learner")
            started = time.perf_counter()
            for _ in range(iterations):
                runner.iterate()
            elapsed = time.perf_counter() - started
            steps = iterations * workers * sim.num_envs * config.rollout_steps
            return steps / elapsed, per_iteration(seconds, elapsed, iterations)
    finally:
        stop(processes)


def streamed_rate(
    sim: SimConfig, workers: int, steps: int, iterations: int, run_dir: Path, lag: int = 0
) -> tuple[float, dict[str, float]]:
    """Env steps/s of the loop learning from `workers` rollout worker processes of
    `sim.num_envs / workers` environments each, after one warm-up iteration, and the
    seconds an iteration (`remote_rate`). `lag` > 0: the workers act while the trainer
    learns, on weights up to `lag` versions old (`--max-policy-lag`; the update then takes
    one thread), where 0 makes them wait for each update."""
    each = dataclasses.replace(sim, num_envs=sim.num_envs // workers)
    commands = [["rollout", "--worker", str(k), "--sim.num-envs", str(each.num_envs),
                 "--steps-per-rollout", str(steps), "--max-policy-lag", str(lag)]
                for k in range(workers)]  # fmt: skip
    rate = remote_rate(each, commands, workers, lag, steps, iterations, run_dir)
    assert rate is not None  # no deadline
    return rate


def chain_rate(
    sim: SimConfig, steps: int, iterations: int, run_dir: Path, deadline_s: float
) -> tuple[float, dict[str, float]] | None:
    """Env steps/s of the loop learning from the service chain's chunks and the seconds an
    iteration (`remote_rate`; None: no update within `deadline_s`)."""
    horizon = str(steps)
    commands = [
        ["sim", "--stage", "easy", "--num-envs", str(sim.num_envs)],
        ["perception"],
        ["policy", "--random-init", "hamnet", "--rollout-horizon", horizon],
        ["safety", "--profile", "training"],
    ]
    return remote_rate(sim, commands, 1, CHAIN_LAG, steps, iterations, run_dir, deadline_s)


def physics_ceiling(runner: Runner, steps: int) -> float:
    """Env steps/s of raw MuJoCo on the run's world (40 physics steps per policy step)."""
    env = runner.source.workers[0].env
    raw = raw_copy(env, nthread=0)
    nstep = env.config.physics_steps_per_sample * env.config.control_samples
    raw.step(nstep=nstep)
    started = time.perf_counter()
    for _ in range(steps):
        raw.step(nstep=nstep)
    return env.num_envs * steps / (time.perf_counter() - started)


def main() -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--quick",
        action="store_true",
        help="16 environments, 2 iterations a setup, 1 worker (under a minute)",
    )
    parser.add_argument(
        "--num-envs",
        type=int,
        default=None,
        help="environments of a setup (default 64; 16 with --quick)",
    )
    parser.add_argument(
        "--chain-deadline-s",
        type=float,
        default=180.0,
        help="give up on the service chain if its first update takes longer",
    )
    args = parser.parse_args()
    num_envs = args.num_envs or (16 if args.quick else 64)
    iterations = 2 if args.quick else 3
    steps = QUICK_STEPS if args.quick else FULL_STEPS
    worker_counts = (1,) if args.quick else (1, 2)
    with TemporaryDirectory() as run_dir:
        sim = stage_config("easy", num_envs=num_envs)
        config = RunConfig(sim=sim, run_dir=Path(run_dir), steps_per_rollout=steps)
        inprocess, overlapped_s, _ = loop_rate(config, iterations)
        progress(f"in-process, overlapped groups: {inprocess:.0f} env steps/s")
        float32_config = dataclasses.replace(config, encoder_precision="float32",
                                             ppo=dataclasses.replace(config.ppo, precision="float32"))  # fmt: skip
        float32, float32_s, _ = loop_rate(float32_config, iterations)
        progress(f"in-process, float32: {float32:.0f} env steps/s")
        sequential_config = RunConfig(
            sim=sim, run_dir=Path(run_dir), overlap=False, steps_per_rollout=steps
        )
        sequential, sequential_s, runner = loop_rate(sequential_config, iterations)
        progress(f"in-process, one group: {sequential:.0f} env steps/s")
        shares = shares_of(sequential_s)
        progress(f"shares of a sequential step: {shares}")
        progress(f"seconds an update, overlapped: {overlapped_s}; sequential: {sequential_s}")
        ceiling = physics_ceiling(runner, 5 if args.quick else 30)
        progress(f"physics ceiling: {ceiling:.0f} env steps/s")
        streamed, streamed_s = {}, {}
        for workers in worker_counts:
            streamed[workers], streamed_s[workers] = streamed_rate(
                sim, workers, steps, iterations, Path(run_dir) / f"workers{workers}"
            )
            progress(
                f"trainer + {workers} rollout worker(s) over Zenoh: {streamed[workers]:.0f} env steps/s"
            )
        while_learning, while_learning_s = streamed_rate(
            sim, 1, steps, iterations, Path(run_dir) / "workers-lag", lag=LEARNING_LAG
        )
        progress(
            f"trainer + 1 rollout worker acting while it learns: {while_learning:.0f} env steps/s"
        )
        chained = chain_rate(sim, steps, iterations, Path(run_dir) / "chain", args.chain_deadline_s)
        chain, chain_s = (None, None) if chained is None else chained
        progress("trainer + service chain: " + (
            f"{chain:.0f} env steps/s" if chain is not None
            else f"no update within {args.chain_deadline_s:.0f} s"))  # fmt: skip
    services = None if chain is None else chain / inprocess
    samples = num_envs * steps
    acting = {
        "inprocess": acting_rate(samples, overlapped_s),
        "float32": acting_rate(samples, float32_s),
        "sequential": acting_rate(samples, sequential_s),
        **{f"workers_{w}": acting_rate(samples, streamed_s[w]) for w in worker_counts},
    }
    update_s = {
        "inprocess": overlapped_s["learner"],
        "float32": float32_s["learner"],
        "sequential": sequential_s["learner"],
        **{f"workers_{w}": streamed_s[w]["learner"] for w in worker_counts},
        "workers_acting_while_learning": while_learning_s["learner"],
        "services": None if chain_s is None else chain_s["learner"],
    }
    best_workers = max(acting[f"workers_{w}"] for w in worker_counts)
    return {
        **header("training", args.quick),
        "num_envs": num_envs,
        "samples_per_update": num_envs * steps,
        "stage": config.stage,
        "architecture": config.architecture,
        "inprocess_env_steps_per_s": round(inprocess, 1),
        "native_bfloat16": native_bfloat16(),
        "inprocess_float32_env_steps_per_s": round(float32, 1),
        "precision_speedup": round(inprocess / float32, 3),
        "sequential_env_steps_per_s": round(sequential, 1),
        "overlap_speedup": round(inprocess / sequential, 3),
        "physics_ceiling_env_steps_per_s": round(ceiling, 1),
        "inprocess_vs_physics_ceiling": round(inprocess / ceiling, 3),
        "shares": shares,
        "seconds_per_update": {"overlapped": overlapped_s, "sequential": sequential_s},
        "overlap_busy": overlap_busy(overlapped_s),
        "workers_1_env_steps_per_s": round(streamed[1], 1),
        "workers_2_env_steps_per_s": round(streamed[2], 1) if 2 in streamed else None,
        "workers_vs_inprocess": round(max(streamed.values()) / inprocess, 3),
        "update_s": update_s,
        "acting_env_steps_per_s": acting,
        "workers_vs_inprocess_acting": round(best_workers / acting["inprocess"], 3),
        "workers_acting_while_learning_env_steps_per_s": round(while_learning, 1),
        "workers_acting_while_learning_vs_inprocess": round(while_learning / inprocess, 3),
        "workers_acting_while_learning_vs_physics_ceiling": round(while_learning / ceiling, 3),
        "acting_note": "acting rates leave the update out (the iteration less it), and with "
        "it the spread of how many steps a fresh policy's update keeps; the chain acts while "
        "its trainer learns, so it has none",
        "services_env_steps_per_s": None if chain is None else round(chain, 1),
        "services_vs_inprocess": None if services is None else round(services, 3),
        "services_note": f"the chain steps on while the trainer learns: its chunks lag up to "
        f"{CHAIN_LAG} versions (the other setups are synchronous)",
        "not_measured": None
        if chain is not None
        else (f"the service chain: no update within {args.chain_deadline_s:.0f} s"),
        "goals": {
            "inprocess_vs_physics_ceiling_at_least_0.33": inprocess / ceiling >= 0.33,
            "workers_vs_inprocess_at_least_0.9": max(streamed.values()) / inprocess >= 0.9,
            "services_vs_inprocess_at_least_0.8": None if services is None else services >= 0.8,
        },
        "cpus": os.cpu_count(),
    }


if __name__ == "__main__":
    report(main())
