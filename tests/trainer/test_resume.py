"""Resuming a run: a run stopped after its snapshot and continued by a new `Runner` must
give, bit for bit, what the uninterrupted run gives (in-process, fixed seed, CPU)."""

from __future__ import annotations

import dataclasses
import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch

from hamnet.policy.weights import read_checkpoint
from hamnet.sim.stages import stage_config
from hamnet.trainer.cli import main
from hamnet.trainer.runners import runner as runner_module
from hamnet.trainer.runners.run_config import RunConfig
from hamnet.trainer.runners.runner import Runner
from hamnet.trainer.runners.snapshots import ResumeError

B = 2
STEPS = 2
COMPARED = ("iteration", "env_transitions", "approx_kl", "policy_loss", "value_loss",
            "bound_loss", "learning_rate", "episodes", "success_rate")  # fmt: skip


def tiny_run(
    run_dir: Path, iterations: int, timeout: int = 300, architecture: str = "hamnet"
) -> RunConfig:
    """B environments of the easy stage, two objects, one physics thread; `iterations` updates."""
    sim = stage_config("easy", num_envs=B, num_objects=2, nthread=1)
    sim = dataclasses.replace(sim, task=dataclasses.replace(sim.task, timeout=timeout))
    return RunConfig(architecture=architecture, sim=sim, steps_per_rollout=STEPS, run_dir=run_dir,
                     max_env_transitions=iterations * B * STEPS, eval_episodes=0)  # fmt: skip


def rows(run_dir: Path) -> list[dict[str, float]]:
    return [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]


def assert_resumes_exactly(tmp_path: Path, timeout: int, architecture: str = "hamnet") -> None:
    """4 iterations in one go vs 2, a snapshot, and 2 more in a new Runner; metrics rows
    written after the snapshot (by a run that crashed later) make way for the resumed ones."""
    whole = Runner(tiny_run(tmp_path / "whole", 4, timeout, architecture))
    whole.run()
    Runner(tiny_run(tmp_path / "split", 2, timeout, architecture)).run()
    with (tmp_path / "split" / "metrics.jsonl").open("a") as metrics:  # a crash after the snapshot
        metrics.write('{"iteration": 3, "env_transitions": -1}\n{"iterat')
    resumed = Runner(tiny_run(tmp_path / "split", 4, timeout, architecture), resume=True)
    assert resumed.iteration == 2
    resumed.run()
    expected, got = rows(tmp_path / "whole"), rows(tmp_path / "split")
    assert [row["iteration"] for row in got] == [1, 2, 3, 4]
    for want, have in zip(expected[2:], got[2:], strict=True):
        keys = [k for k in want if k in COMPARED or k.startswith("return/")]
        assert {k: have[k] for k in keys} == {k: want[k] for k in keys}
    for name, tensor in whole.policy.state_dict().items():
        assert torch.equal(resumed.policy.state_dict()[name], tensor), name


@pytest.mark.parametrize("architecture", ["hamnet", "state-mlp"])
def test_a_resumed_run_equals_the_uninterrupted_one(tmp_path: Path, architecture: str) -> None:
    """Iterations 3-4 and the final weights must be equal: any state the snapshot misses (an
    RNG, Adam's moments, a cache, the sim's warm start) changes some metric or weight.
    HAMnet collects in two overlapped groups with perception, the state baseline in one
    group without."""
    assert_resumes_exactly(tmp_path, timeout=300, architecture=architecture)


def test_episodes_that_end_between_snapshot_and_resume_resume_exactly(tmp_path: Path) -> None:
    """A 3-step timeout ends episodes inside and across the rollouts around the snapshot, so
    the sim's episode draws, the carry's resets, the tracker and the returns scaler all
    carry over (the episode tracker's rows appear in return/*)."""
    assert_resumes_exactly(tmp_path, timeout=3)
    assert rows(tmp_path / "split")[-1]["episodes"] > 0


def test_a_snapshot_of_another_run_is_refused(tmp_path: Path) -> None:
    """A snapshot made with other environments or another rollout length cannot continue
    this run: the refusal names what differs, on one line, before anything is built."""
    Runner(tiny_run(tmp_path, 1)).run()
    other = dataclasses.replace(tiny_run(tmp_path, 2), steps_per_rollout=3)
    with pytest.raises(ResumeError, match="steps_per_rollout: 2 there, 3 here") as error:
        Runner(other, resume=True)
    assert "\n" not in str(error.value)
    with pytest.raises(ResumeError, match="no snapshot"):
        Runner(tiny_run(tmp_path / "empty", 1), resume=True)


def test_hamnet_trainer_resume_continues_the_folder_or_refuses_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """`--resume RUN_DIR` appends to RUN_DIR's metrics and the summary names both commands
    that made the run; other flags than the snapshot's exit with status 2 and one line on
    stderr instead of a traceback."""
    tiny = ["--inprocess", "--architecture", "state-mlp", "--sim.num-envs", "2", "--sim.num-objects",
            "2", "--sim.nthread", "1", "--steps-per-rollout", "2", "--eval-episodes", "0"]  # fmt: skip
    start = [*tiny, "--max-env-transitions", "4", "--run-dir", str(tmp_path)]
    resume = [*tiny, "--max-env-transitions", "8", "--resume", str(tmp_path)]
    for argv in (start, resume):
        monkeypatch.setattr(sys, "argv", ["hamnet", "trainer", *argv])  # as a user types them
        assert main(argv) == 0
    assert [row["env_transitions"] for row in rows(tmp_path)] == [4, 8]
    commands = json.loads((tmp_path / "summary.json").read_text())["commands"]
    assert commands == [" ".join(["hamnet", "trainer", *argv]) for argv in (start, resume)]
    capsys.readouterr()
    changed = [*tiny, "--sim.num-envs", "4", "--resume", str(tmp_path)]
    assert main(changed) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and "sim.num_envs: 2 there, 4 here" in error


@pytest.mark.parametrize(("allowed", "where"), [(2, "rollout"), (STEPS + 3, "update")])
def test_a_run_stopped_mid_iteration_goes_back_to_its_start_and_resumes_exactly(
    tmp_path: Path, allowed: int, where: str
) -> None:
    """`running()` turns False inside the third iteration (after one of its steps, or after
    its update's first minibatch): the run goes back to the end of the second, checkpoints
    that, and a resumed run then equals the uninterrupted one bit for bit."""
    whole = Runner(tiny_run(tmp_path / "whole", 4))
    whole.run()
    stopped = Runner(tiny_run(tmp_path / "split", 4))
    calls = 0

    def running() -> bool:
        nonlocal calls
        calls += stopped.iteration >= 2  # the loop's own check, then collect's and update's
        return calls <= allowed

    stopped.run(running=running)
    assert stopped.interrupted and stopped.iteration == 2, where
    assert [row["iteration"] for row in rows(tmp_path / "split")] == [1, 2]
    resumed = Runner(tiny_run(tmp_path / "split", 4), resume=True)
    resumed.run()
    expected, got = rows(tmp_path / "whole"), rows(tmp_path / "split")
    for want, have in zip(expected[2:], got[2:], strict=True):
        keys = [k for k in want if k in COMPARED or k.startswith("return/")]
        assert {k: have[k] for k in keys} == {k: want[k] for k in keys}
    for name, tensor in whole.policy.state_dict().items():
        assert torch.equal(resumed.policy.state_dict()[name], tensor), name


@pytest.mark.parametrize("schedule", ["fixed", "adaptive"])
def test_a_resumed_run_learns_at_its_own_rates_unless_the_rate_is_adapted(
    tmp_path: Path, schedule: str
) -> None:
    """`--ppo.lr` and `--ppo.value-lr` given on resume are the rates it learns at (the
    snapshot's Adam state kept); an adapted actor rate goes on from the snapshot's value."""
    first = tiny_run(tmp_path, 3, architecture="state-mlp")  # the first only fills statistics
    first = dataclasses.replace(first, ppo=dataclasses.replace(first.ppo, lr_schedule=schedule))
    Runner(first).run()
    saved = json.loads((tmp_path / "checkpoints" / "state.json").read_text())
    adapted = saved["algorithm"]["optimizer"]["param_groups"][0]["lr"]
    changed = dataclasses.replace(first.ppo, lr=1e-5, value_lr=2e-5)
    resumed = Runner(dataclasses.replace(first, ppo=changed), resume=True)
    rates = [group["lr"] for group in resumed.algorithm.optimizer.param_groups]
    assert rates == [1e-5 if schedule == "fixed" else adapted, 2e-5]
    assert resumed.algorithm.optimizer.state  # Adam's moments came back


class TickingClock:
    """`time` for the runner alone: `monotonic()` advances one second per call, so where a
    budget runs out depends on the run's own checks, not on how fast this machine is."""

    perf_counter = staticmethod(time.perf_counter)

    def __init__(self) -> None:
        self.now = 0.0

    def monotonic(self) -> float:
        self.now += 1.0
        return self.now


def test_a_wall_clock_budget_ends_the_run_at_its_last_whole_iteration_within_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A budget that runs out inside the third iteration drops that iteration: the run keeps
    two, and its wall_clock_s and checkpoint are those of the second, within the budget (a
    loop that checked the budget only between iterations finished the third past it)."""
    monkeypatch.setattr(runner_module, "time", TickingClock())
    free = Runner(tiny_run(tmp_path / "free", 3))
    free.run()
    ends = [row["wall_clock_s"] for row in rows(tmp_path / "free")]
    budget = (ends[1] + ends[2]) / 2
    monkeypatch.setattr(runner_module, "time", TickingClock())
    bounded = Runner(
        dataclasses.replace(tiny_run(tmp_path / "bounded", 3), max_wall_clock_s=budget)
    )
    bounded.run()
    assert bounded.interrupted and bounded.iteration == 2
    assert [row["wall_clock_s"] for row in rows(tmp_path / "bounded")] == ends[:2]
    assert bounded.wall_clock_s == ends[1] <= budget
    resumed = Runner(tiny_run(tmp_path / "bounded", 3), resume=True)
    assert resumed.iteration == 2 and resumed.wall_clock_s == ends[1]


@pytest.mark.stack  # `hamnet trainer` as a process
def test_sigterm_in_the_middle_of_a_rollout_saves_the_run_and_resume_continues(
    tmp_path: Path,
) -> None:
    """`hamnet trainer` receiving SIGTERM during a long rollout (thousands of steps) leaves it
    at once: exit 0, the checkpoint of the last whole iteration, metrics, and a summary
    saying it was stopped (no held-out evaluation, which the launcher's grace period would
    not allow); `--resume` then continues from that checkpoint."""
    run_dir = tmp_path / "run"
    flags = ["--inprocess", "--architecture", "state-mlp", "--sim.num-envs", "2",
             "--sim.num-objects", "2", "--sim.nthread", "1", "--steps-per-rollout", "3000"]  # fmt: skip
    command = [sys.executable, "-m", "hamnet", "trainer", *flags, "--run-dir", str(run_dir)]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    metrics = run_dir / "metrics.jsonl"
    deadline = time.monotonic() + 300
    while not (metrics.exists() and metrics.read_text().endswith("\n")):  # iteration 1 is in
        assert process.poll() is None and time.monotonic() < deadline, process.communicate()[0]
        time.sleep(0.05)
    process.send_signal(signal.SIGTERM)  # iteration 2's 6000 transitions have barely begun
    output = process.communicate(timeout=60)[0]
    assert process.returncode == 0, output
    assert [row["iteration"] for row in rows(run_dir)] == [1]
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["stopped_by_signal"] and summary["final_success_rate"] is None
    assert summary["env_steps"] == 6000
    assert read_checkpoint(run_dir / "checkpoints" / "latest.safetensors").version == 2
    resumed = [*flags, "--max-env-transitions", "12000",
               "--eval-episodes", "2", "--resume", str(run_dir)]  # fmt: skip
    assert main(resumed) == 0
    assert [row["iteration"] for row in rows(run_dir)] == [1, 2]
    assert json.loads((run_dir / "summary.json").read_text())["final_success_rate"] is not None
