"""Safety benchmark: time per command of the safety pipeline, stage by stage, for 1 robot and
for 64 environments batched, against the 100 ms policy period and a 1 ms real-time tick.

Consumes the safety core only (no networking). For each environment count it builds one
`SafetyFilter` per control rate (80 Hz: the sim's references, S = 8; 1 kHz: the real FR3's,
S = 100), drives it in closed loop (measured q = the last reference, dq its backward
difference; actions N(0, 1), so stages clip as in training) and times, call by call and
interleaved round by round:

- each stage on its own, with the inputs that stage sees: 1 guard, 2 scaling + magnitude
  (schedule included), 3 Cartesian clip (batched Jacobians included), 4 EMA, 5 joint
  limits, 7 torque pre-clip against the target; stage 6 (`TrajectoryGenerator.step`) at
  80 Hz and 1 kHz, each followed by stage 7's recheck against its samples;
- stages 1-5/7 as the core runs them (`SafetyCore.filter`, statistics included), and the whole
  pipeline per command (`SafetyFilter.command`) at both rates;
- two baselines in the same run. `copy`: numpy copying the command's arrays (action, q, dq),
  the floor of any numpy call at that size: the numpy stages cost a few of these, so their
  figures are mostly call overhead. `raw ruckig`: the same plans without our wrapper (one
  `Ruckig.calculate` per environment from the previous period's end to a target at rest,
  then `Trajectory.at_time` at the S sample times, nothing else): stage 6 dominates the
  pipeline, and this is what any Ruckig-based stage 6 must pay; the gap is our wrapper's
  (range guard over the plan's extrema, arrays, plan codes).

Produces a table on stdout (median and p99 per command in us, and the medians as fractions of
the 100 ms policy period and of 1 ms), progress on stderr and, as the last stdout line, one JSON
object: `fraction_of_policy_period_64` (whole pipeline, 64 environments, 80 Hz references as in
the sim), `fraction_of_1ms_1robot` (whole pipeline, 1 robot, 1 kHz references as on the FR3),
their p99 and other-rate variants, the training and finetune profiles' whole command at 64
and 1024 environments (`training_profile_ms_1024`, `training_profile_fraction_1024`: of the
policy period; likewise for finetune), and every row under `results`.

    .venv/bin/python benchmarks/safety.py --quick     # < 1 min
    .venv/bin/python benchmarks/safety.py             # more samples
"""

from __future__ import annotations

import os
import platform
import time
from collections.abc import Callable
from dataclasses import dataclass
from importlib import metadata

import numpy as np
import ruckig
import tyro

# Run as a script, so benchmarks/ is on sys.path: the helpers every benchmark shares.
from common import header, median_p99, print_header, progress, report, timer

from hamnet.fr3.limits import Q_HOME
from hamnet.safety import stages
from hamnet.safety.cartesian import JACOBIAN_ROWS, cartesian_clip
from hamnet.safety.config import SafetyConfig, with_profile
from hamnet.safety.filter import SafetyFilter
from hamnet.safety.pipeline import target_bounds, tau_limit
from hamnet.safety.references import TrajectoryConfig
from hamnet.safety.ruckig_references import TrajectoryGenerator
from hamnet.safety.schedule import per_joint, schedule_values

POLICY_PERIOD_S = 0.1
"""10 Hz policy."""
CONTROL_PERIOD_S = 1e-3
"""libfranka's real-time tick."""
RATES_HZ = {"80Hz": 80.0, "1kHz": 1000.0}
"""Stage 6's reference rates: the sim's torque ticks and the FR3's control loop."""


@dataclass(frozen=True)
class SafetyBenchConfig:
    """What to sweep and for how long."""

    quick: bool = False
    """A short run (fewer samples per row) for smoke tests, under a minute."""
    num_envs: tuple[int, ...] = (1, 64)
    """Environment counts (batched in one call)."""
    samples: int = 400
    """Timed calls per row and environment count (quick: 100)."""
    rounds: int = 8
    """Rows alternate this many times, sharing `samples`."""
    warmup: int = 5
    """Closed-loop periods before timing."""
    step: int = 0
    """env_transitions for the annealed bounds (0: xi_max, eps_x_max, the widest)."""
    profile_envs: tuple[int, ...] = (64, 1024)
    """Environment counts for the training and finetune profiles (80 Hz, as in the sim)."""
    seed: int = 0

    @property
    def measured_samples(self) -> int:
        """Timed calls per row."""
        return 100 if self.quick else self.samples


class Loop:
    """One `SafetyFilter` at one reference rate in closed loop: the robot tracks perfectly."""

    def __init__(
        self,
        num_envs: int,
        rate_hz: float,
        rng: np.random.Generator,
        safety: SafetyConfig | None = None,
    ) -> None:
        q = np.tile(Q_HOME, (num_envs, 1))  # (B, J)
        self.rng = rng
        self.config = TrajectoryConfig(control_rate_hz=rate_hz)
        self.filter = SafetyFilter(q, safety, trajectory=self.config)
        self.q, self.dq = q, np.zeros_like(q)  # (B, J) measured, rad and rad/s
        self.action = self.next_action()

    def next_action(self) -> np.ndarray:
        return self.rng.normal(size=(len(self.q), stages.ACTION_DIM))  # (B, 21)

    def advance(self, q_ref: np.ndarray) -> None:
        """The robot is where the period's references end, (B, S, J) -> (B, J)."""
        self.q = q_ref[:, -1].copy()
        self.dq = (q_ref[:, -1] - q_ref[:, -2]) / self.config.control_period_s
        self.action = self.next_action()


class RawRuckig:
    """The baseline for stage 6: Ruckig's calculate and at_time per environment, nothing else."""

    def __init__(self, q: np.ndarray, config: TrajectoryConfig) -> None:
        b = len(q)
        self.otg = [ruckig.Ruckig(7) for _ in range(b)]
        self.inputs = [ruckig.InputParameter(7) for _ in range(b)]
        self.trajectories = [ruckig.Trajectory(7) for _ in range(b)]
        for inp in self.inputs:
            inp.max_velocity = config.dq_max.tolist()
            inp.max_acceleration = config.ddq_max.tolist()
            inp.max_jerk = config.jerk_max.tolist()
            inp.synchronization = ruckig.Synchronization.Phase
        self.times = [config.control_period_s * (k + 1) for k in range(config.samples_per_period)]
        self.state = [(row.tolist(), [0.0] * 7, [0.0] * 7) for row in q]

    def step(self, q_target: np.ndarray) -> list:
        """Plan each environment from its last sample to its target; sample one period."""
        samples = []
        for i, target in enumerate(q_target.tolist()):
            inp = self.inputs[i]
            inp.current_position, inp.current_velocity, inp.current_acceleration = self.state[i]
            inp.target_position = target
            self.otg[i].calculate(inp, self.trajectories[i])
            period = [self.trajectories[i].at_time(t) for t in self.times]
            self.state[i] = period[-1]
            samples.append(period)
        return samples


@dataclass
class Row:
    """One timed thing: its name, its stage, and a call that does it once and returns the
    seconds the timed part took (inputs for the next call are prepared outside the timer)."""

    name: str
    stage: str
    call: Callable[[], float]
    seconds: list[float]


def make_rows(num_envs: int, config: SafetyBenchConfig) -> list[Row]:
    """Every row for one environment count, each with closed-loop inputs of its own."""
    rng = np.random.default_rng(config.seed)
    loops = {rate: Loop(num_envs, hz, rng) for rate, hz in RATES_HZ.items()}
    for loop in loops.values():
        for _ in range(config.warmup):
            loop.advance(loop.filter.command(loop.action, loop.q, loop.dq, config.step).q_ref)
    sim = loops["80Hz"]
    safety = sim.filter.config
    core = sim.filter.core
    state = core.state
    # Inputs of the stage-by-stage rows: one closed-loop period of the sim loop.
    values = schedule_values(config.step, safety.action_magnitude, safety.cartesian_clip)
    magnitude = safety.action_magnitude
    xi = per_joint(values.xi_large, values.xi_small, magnitude.num_large_joints)  # (J,)
    raw, _ = stages.nonfinite_guard(sim.action, num_envs)  # (B, 21)
    dq_step, kp, rho, _ = stages.action_magnitude(raw, xi, magnitude)  # (B, J) each
    q, dq = sim.q, sim.dq  # (B, J)
    jacobian_rows = JACOBIAN_ROWS[safety.cartesian_clip.rows]
    dq_clipped = cartesian_clip(dq_step, core.jacobians(q)[:, jacobian_rows], values.eps_x, 0.01)[0]
    lo, hi = target_bounds(safety)
    q_target = np.clip(q + dq_clipped, lo, hi)  # (B, J)
    limit = np.tile(tau_limit(safety), (num_envs, 1))  # (B, J)
    cartesian = safety.cartesian_clip

    def stage_2() -> object:
        v = schedule_values(config.step, magnitude, cartesian)
        xi = per_joint(v.xi_large, v.xi_small, magnitude.num_large_joints)  # (J,)
        return stages.action_magnitude(raw, xi, magnitude)

    def stage_3() -> object:
        return cartesian_clip(
            dq_step,
            core.jacobians(q)[:, jacobian_rows],
            values.eps_x,
            cartesian.damping,
            cartesian.iterations,
        )

    def copy() -> object:
        return sim.action.copy(), q.copy(), dq.copy()

    alpha, memory = safety.residual_smoothing.alpha, state.dq_smoothed  # (B, J) EMA memory
    torque_inputs = (q_target, q, dq, kp, rho, limit)

    def bounds() -> tuple[np.ndarray, np.ndarray]:
        return target_bounds(safety)  # as the core computes them every call

    rows = [
        Row("copy (baseline)", "numpy floor", timer(copy), []),
        Row("1 guard", "1", timer(lambda: stages.nonfinite_guard(sim.action, num_envs)), []),
        Row("2 scaling+magnitude", "2", timer(stage_2), []),
        Row("3 cartesian clip", "3", timer(stage_3), []),
        Row("  of which jacobians", "3", timer(lambda: core.jacobians(q)), []),
        Row("4 ema", "4", timer(lambda: stages.residual_smoothing(dq_clipped, memory, alpha)), []),
        Row("5 joint limits", "5", timer(lambda: stages.joint_limits(q + dq_clipped, *bounds())), []),
        Row("7 torque pre-clip", "7", timer(lambda: stages.torque_preclip(*torque_inputs)), []),
        Row("1-5,7 core.filter", "1-5,7", timer(lambda: _core_filter(sim, config.step)), []),
    ]  # fmt: skip
    for rate, loop in loops.items():
        rows += _stage_6_rows(rate, loop, q_target, kp, rho, limit, rng)
    for rate, loop in loops.items():
        rows.append(Row(f"whole pipeline {rate}", "all", _whole(loop, config.step), []))
    return rows


def _core_filter(loop: Loop, step: int) -> object:
    """Stages 1-5/7 on the loop's state, memory restored so every call sees the same inputs."""
    core = loop.filter.core
    state = core.state
    result = core.filter(loop.action, loop.q, loop.dq, step)
    core.state = state
    return result


def _stage_6_rows(
    rate: str,
    loop: Loop,
    q_target: np.ndarray,
    kp: np.ndarray,
    rho: np.ndarray,
    limit: np.ndarray,
    rng: np.random.Generator,
) -> list[Row]:
    """Stage 6 (ours and raw Ruckig) with new targets every call, and stage 7's recheck."""
    num_envs = len(q_target)
    lo, hi = target_bounds(loop.filter.config)
    generator = TrajectoryGenerator(loop.q, loop.config)
    raw = RawRuckig(loop.q, loop.config)
    offsets = rng.uniform(-0.2, 0.2, (64, num_envs, 7))  # (K, B, J) policy-sized moves, rad
    count = [0, 0]
    last = {"q_ref": generator.step(q_target).q_ref}

    def ours() -> float:
        count[0] += 1
        target = np.clip(generator.state.q + offsets[count[0] % 64], lo, hi)  # (B, J)
        started = time.perf_counter_ns()
        last["q_ref"] = generator.step(target).q_ref
        return (time.perf_counter_ns() - started) * 1e-9

    def baseline() -> float:
        count[1] += 1
        start = np.array([s[0] for s in raw.state])  # (B, J)
        target = np.clip(start + offsets[count[1] % 64], lo, hi)
        started = time.perf_counter_ns()
        raw.step(target)
        return (time.perf_counter_ns() - started) * 1e-9

    def recheck() -> object:
        return stages.torque_preclip(last["q_ref"], loop.q, loop.dq, kp, rho, limit)

    samples = loop.config.samples_per_period
    return [
        Row(f"6 ruckig {rate} (S={samples})", "6", ours, []),
        Row(f"  raw ruckig {rate} (baseline)", "ruckig floor", baseline, []),
        Row(f"7 torque recheck {rate}", "7", timer(recheck), []),
    ]


def _whole(loop: Loop, step: int) -> Callable[[], float]:
    """`SafetyFilter.command` (timed), then the robot moves to its references and the policy
    draws the next action (not timed)."""

    def call() -> float:
        started = time.perf_counter_ns()
        out = loop.filter.command(loop.action, loop.q, loop.dq, step)
        seconds = (time.perf_counter_ns() - started) * 1e-9
        loop.advance(out.q_ref)
        return seconds

    return call


PROFILES_TIMED = ("training", "finetune")
"""The profiles of the rollout workers, timed as whole `SafetyFilter.command` calls."""


def measure_profiles(config: SafetyBenchConfig) -> list[dict]:
    """`SafetyFilter.command` of each profile in PROFILES_TIMED at 80 Hz, per environment
    count of `profile_envs`, in closed loop; rows named "<profile> profile"."""
    results = []
    for num_envs in config.profile_envs:
        rng = np.random.default_rng(config.seed)
        rows = []
        for profile in PROFILES_TIMED:
            loop = Loop(num_envs, RATES_HZ["80Hz"], rng, with_profile(profile))
            call = _whole(loop, config.step)
            for _ in range(config.warmup):
                call()
            rows.append(Row(f"{profile} profile", "all", call, []))
        results += interleaved(rows, num_envs, config)
        progress(", ".join(f"{num_envs} envs: {r['row']} {r['median_us']:.0f} us" for r in
                           results[-len(rows):]))  # fmt: skip
    return results


def profile_figures(results: list[dict]) -> dict:
    """`<profile>_profile_ms_<B>` and `..._fraction_<B>` (of the 100 ms policy period)."""
    figures = {}
    for r in results:
        name = f"{r['row'].replace(' ', '_')}_ms_{r['num_envs']}"
        figures[name] = round(r["median_us"] * 1e-3, 3)
        figures[name.replace("_ms_", "_fraction_")] = r["fraction_of_policy_period"]
    return figures


def measure(num_envs: int, config: SafetyBenchConfig) -> list[dict]:
    """Every row for one environment count, interleaved round by round."""
    return interleaved(make_rows(num_envs, config), num_envs, config)


def interleaved(rows: list[Row], num_envs: int, config: SafetyBenchConfig) -> list[dict]:
    """Summaries of `rows` timed in turn, `config.rounds` rounds sharing the samples, so that
    load from other processes on a shared machine hits every row alike."""
    chunk = max(config.measured_samples // config.rounds, 1)
    for _ in range(config.rounds):
        for row in rows:
            row.seconds += [row.call() for _ in range(chunk)]
    return [summary(row, num_envs) for row in rows]


def summary(row: Row, num_envs: int) -> dict:
    median, p99 = median_p99(row.seconds, 1e6)

    def fraction(microseconds: float, period_s: float) -> float:
        return float(f"{microseconds * 1e-6 / period_s:.4g}")

    return {
        "num_envs": num_envs,
        "row": row.name.strip(),
        "stage": row.stage,
        "median_us": round(median, 2),
        "p99_us": round(p99, 2),
        "fraction_of_policy_period": fraction(median, POLICY_PERIOD_S),
        "fraction_of_1ms": fraction(median, CONTROL_PERIOD_S),
        "p99_fraction_of_policy_period": fraction(p99, POLICY_PERIOD_S),
        "p99_fraction_of_1ms": fraction(p99, CONTROL_PERIOD_S),
        "calls": len(row.seconds),
    }


def print_table(results: list[dict]) -> None:
    print_header(
        f"{'envs':>4}  {'row':<30} {'median us':>10} {'p99 us':>10} "
        f"{'of 100 ms':>10} {'of 1 ms':>9} {'p99/1 ms':>9}"
    )
    for r in results:
        print(
            f"{r['num_envs']:>4}  {r['row']:<30} {r['median_us']:>10.1f} {r['p99_us']:>10.1f} "
            f"{r['fraction_of_policy_period']:>10.2e} {r['fraction_of_1ms']:>9.3f} "
            f"{r['p99_fraction_of_1ms']:>9.3f}"
        )
    print("(per command, all environments of the batch together; 'of 100 ms'/'of 1 ms': the "
          "median as a fraction of the policy period / of one real-time tick)")  # fmt: skip


def main(config: SafetyBenchConfig) -> dict:
    """Run the sweep; returns the JSON figures."""
    started = time.monotonic()
    results = []
    for num_envs in config.num_envs:
        rows = measure(num_envs, config)
        whole = {r["row"]: r for r in rows}
        progress(
            f"{num_envs} envs: whole pipeline {whole['whole pipeline 80Hz']['median_us']:.0f} us "
            f"(80 Hz), {whole['whole pipeline 1kHz']['median_us']:.0f} us (1 kHz)"
        )
        results += rows
    profiles = measure_profiles(config)
    results += profiles
    print_table(results)
    at = {(r["num_envs"], r["row"]): r for r in results}
    largest, smallest = max(config.num_envs), min(config.num_envs)
    batch_sim = at[(largest, "whole pipeline 80Hz")]
    batch_khz = at[(largest, "whole pipeline 1kHz")]
    one_khz, one_sim = at[(smallest, "whole pipeline 1kHz")], at[(smallest, "whole pipeline 80Hz")]
    figures = {
        **header("safety", config.quick),
        f"fraction_of_policy_period_{largest}": batch_sim["fraction_of_policy_period"],
        f"fraction_of_policy_period_{largest}_p99": batch_sim["p99_fraction_of_policy_period"],
        f"fraction_of_policy_period_{largest}_1khz": batch_khz["fraction_of_policy_period"],
        f"fraction_of_1ms_{smallest}robot": one_khz["fraction_of_1ms"],
        f"fraction_of_1ms_{smallest}robot_p99": one_khz["p99_fraction_of_1ms"],
        f"fraction_of_1ms_{smallest}robot_80hz": one_sim["fraction_of_1ms"],
        f"whole_us_{largest}": batch_sim["median_us"],
        f"whole_us_{smallest}_1khz": one_khz["median_us"],
        f"ruckig_over_raw_{largest}_1khz": round(
            at[(largest, "6 ruckig 1kHz (S=100)")]["median_us"]
            / at[(largest, "raw ruckig 1kHz (baseline)")]["median_us"],
            3,
        ),
        f"ruckig_over_raw_{smallest}_1khz": round(
            at[(smallest, "6 ruckig 1kHz (S=100)")]["median_us"]
            / at[(smallest, "raw ruckig 1kHz (baseline)")]["median_us"],
            3,
        ),
        **profile_figures(profiles),
        "results": results,
        "samples": config.measured_samples,
        "step": config.step,
        "seed": config.seed,
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "numpy": metadata.version("numpy"),
        "ruckig": metadata.version("ruckig"),
        "elapsed_s": round(time.monotonic() - started, 1),
    }
    return figures


if __name__ == "__main__":
    report(main(tyro.cli(SafetyBenchConfig, description=__doc__)))
