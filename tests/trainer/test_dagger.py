"""DAgger (issue 15) at tiny sizes on the real cores: beta's schedule, the teacher's labels,
the student's imitation update, exact resume, and `hamnet trainer --algo dagger` with its
refusals. The teacher is a freshly initialised HAMnet: what is checked is the machinery,
not a distillation result (that is the proof run, docs/trainer.md "DAgger")."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import pytest
import torch

from hamnet.policy.registry import build, with_changes
from hamnet.policy.weights import policy_from, read_checkpoint, save_checkpoint
from hamnet.sim.stages import stage_config
from hamnet.trainer.algorithms.dagger import (
    VelocityReadout,
    beta_at,
    imitation_loss,
    lr_at,
    update_student,
)
from hamnet.trainer.algorithms.dagger_learner import Dagger
from hamnet.trainer.algorithms.recurrent_unroll import episode_starts, evaluate_sequence
from hamnet.trainer.algorithms.teacher import load_teacher
from hamnet.trainer.cli import main
from hamnet.trainer.collection.dagger_worker import build_dagger_worker
from hamnet.trainer.collection.sources import Collected, build_workers
from hamnet.trainer.config import DaggerConfig
from hamnet.trainer.rollout_cli import main as rollout_main
from hamnet.trainer.runners.progress import dagger_line
from hamnet.trainer.runners.run_config import RunConfig
from hamnet.trainer.runners.runner import Runner
from hamnet.trainer.runners.snapshots import ResumeError
from tests.policy.inputs import informed

B = 4
STEPS = 4


def tiny_run(run_dir: Path, iterations: int = 1, timeout: int = 300, seed: int = 0) -> RunConfig:
    """B environments of the easy stage, two objects, one physics thread, the student."""
    sim = stage_config("easy", num_envs=B, num_objects=2, nthread=1, seed=seed)
    sim = dataclasses.replace(sim, task=dataclasses.replace(sim.task, timeout=timeout))
    return RunConfig(architecture="student", sim=sim, steps_per_rollout=STEPS, run_dir=run_dir,
                     max_env_transitions=iterations * B * STEPS, eval_episodes=0)  # fmt: skip


@pytest.fixture(scope="module")
def teacher_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A random teacher at PyTorch's initialization, whose means differ from state to state
    (an orthogonally initialized actor's start near 0, nothing to imitate)."""
    path = tmp_path_factory.mktemp("teacher") / "teacher.safetensors"
    save_checkpoint(path, build("hamnet", with_changes("hamnet", init="torch"), seed=1), 7)
    return path


def test_beta_and_the_rate_fall_linearly_then_stay() -> None:
    config = DaggerConfig(beta_initial=1.0, beta_final=0.2, beta_decay_transitions=100)
    assert [beta_at(n, config) for n in (0, 50, 100, 1000)] == pytest.approx([1.0, 0.6, 0.2, 0.2])
    assert beta_at(5, DaggerConfig(beta_decay_transitions=0)) == 0.0
    rates = DaggerConfig(lr=1e-3, lr_final=1e-4, lr_decay_transitions=100)
    assert [lr_at(n, rates) for n in (0, 50, 200)] == pytest.approx([1e-3, 5.5e-4, 1e-4])
    with pytest.raises(ValueError, match="beta_initial"):
        DaggerConfig(beta_initial=1.5)
    with pytest.raises(ValueError, match="weight_average"):
        DaggerConfig(weight_average=1.0)  # an average that never moves


def test_labels_are_the_teachers_mean_where_it_acts_and_where_the_student_does(
    tmp_path: Path, teacher_file: Path
) -> None:
    """Beta 1: the teacher acts every step, so the states are those a plain rollout worker
    visits acting with the teacher's mean (same seed, same encoder), and the labels are that
    worker's actions. Beta 0: the student acts everything, and the labels are still what the
    teacher says (not the student's actions)."""
    teacher, student = load_teacher(teacher_file).policy, build("student", seed=0).eval()
    config = tiny_run(tmp_path)
    always = DaggerConfig(beta_initial=1.0, beta_final=1.0)
    worker = build_dagger_worker(config, teacher)
    first_velocity = torch.as_tensor(worker.observation.object_velocity).clone()
    demos = worker.collect(teacher, student, STEPS, 0, always)
    assert demos.object_velocity.shape == (STEPS, B, 6)
    torch.testing.assert_close(demos.object_velocity[0], first_velocity)
    (plain,), _ = build_workers(dataclasses.replace(config, architecture="hamnet"), groups=1)
    reference = plain.collect(teacher, STEPS, 0, deterministic=True)
    assert demos.teacher_acted.all()
    torch.testing.assert_close(demos.labels, reference.actions, rtol=1e-5, atol=1e-5)
    never = DaggerConfig(beta_initial=0.0, beta_final=0.0)
    demos = build_dagger_worker(config, teacher).collect(teacher, student, STEPS, 0, never)
    assert not demos.teacher_acted.any()
    with torch.no_grad():
        own = evaluate_sequence(
            student, demos.inputs, demos.labels, episode_starts(demos.dones, demos.first)
        ).mean
    assert not torch.allclose(own, demos.labels, atol=1e-3)


def test_the_imitation_loss_falls_on_a_fixed_batch_and_on_held_states(
    tmp_path: Path, teacher_file: Path
) -> None:
    """Steps on one batch lower its loss; a short training on the teacher's labels brings
    the student's means nearer the teacher's on states of other episodes (another seed)."""
    teacher, student = load_teacher(teacher_file).policy, build("student", seed=0)
    mixed = DaggerConfig(beta_initial=0.5, beta_final=0.5, epochs=10)
    train = build_dagger_worker(tiny_run(tmp_path), teacher)
    held = build_dagger_worker(tiny_run(tmp_path, seed=5), teacher).collect(
        teacher, student.eval(), STEPS, 0, mixed
    )

    def held_loss() -> float:
        with torch.no_grad():
            starts = episode_starts(held.dones, held.first)
            return imitation_loss(
                evaluate_sequence(student, held.inputs, held.labels, starts).mean, held.labels
            ).item()

    before = held_loss()
    optimizer = torch.optim.Adam(student.parameters())
    batch = train.collect(teacher, student.eval(), STEPS, 0, mixed)
    stats = update_student(student, optimizer, batch, mixed)
    assert stats.imitation_loss_after < 0.5 * stats.imitation_loss
    for _ in range(2):
        update_student(
            student, optimizer, train.collect(teacher, student.eval(), STEPS, 0, mixed), mixed
        )
    assert held_loss() < 0.5 * before


def test_replayed_windows_are_learned_beside_the_newest_and_reported_apart(
    tmp_path: Path, teacher_file: Path
) -> None:
    """From the same weights, an update that replays an older window starts from the same
    reported loss (the newest window's own) and ends nearer the teacher on the older window
    than one on the newest window alone; the `Dagger` keeps `replay_windows - 1` windows."""
    teacher, student = informed("hamnet"), build("student", seed=0)
    config = DaggerConfig(beta_initial=0.0, beta_final=0.0, epochs=30)
    older, newest = (
        build_dagger_worker(tiny_run(tmp_path, seed=seed), teacher).collect(
            teacher, student.eval(), STEPS, 0, config
        )
        for seed in (5, 0)
    )

    def loss_on(policy: torch.nn.Module, batch) -> float:
        with torch.no_grad():
            starts = episode_starts(batch.dones, batch.first)
            mean = evaluate_sequence(policy, batch.inputs, batch.labels, starts).mean
            return imitation_loss(mean, batch.labels).item()

    alone, replaying = build("student", seed=0), build("student", seed=0)
    firsts = [
        update_student(policy, torch.optim.Adam(policy.parameters()), newest, config, None,
                       replayed).imitation_loss
        for policy, replayed in ((alone, list), (replaying, lambda: [older]))
    ]  # fmt: skip
    assert firsts[0] == firsts[1] == pytest.approx(loss_on(student, newest))
    assert loss_on(replaying, older) < 0.9 * loss_on(alone, older)
    dagger = Dagger(load_teacher(teacher_file), DaggerConfig(replay_windows=2, replay_draw=1))
    dagger.start(student, B)
    for window in (older, newest, older):
        dagger.learn(Collected(window), window, 0)
    assert len(dagger.replay) == 1 and len(dagger.replayed()) == 1


def test_the_velocity_loss_is_in_the_teachers_standardised_units() -> None:
    """A read-out that gives the teacher's mean velocity scores the velocities' spread in the
    teacher's units (1 where they spread as the teacher's statistics say), an exact one 0."""
    teacher = informed("hamnet")
    readout = VelocityReadout(8, teacher)
    assert readout.mean.shape == readout.std.shape == (6,)
    memories = torch.randn(64, 32, 8)
    as_the_teacher_saw = readout.mean + readout.std * torch.randn(64, 32, 6)
    with torch.no_grad():
        readout.linear.weight.zero_()
        readout.linear.bias.zero_()
        assert readout.loss(memories, as_the_teacher_saw).item() == pytest.approx(1.0, abs=0.05)
        twice_the_spread = 2 * as_the_teacher_saw - readout.mean
        assert readout.loss(memories, twice_the_spread).item() == pytest.approx(4.0, abs=0.3)
        readout.linear.weight.normal_(std=0.1)  # within the clip
        exact = readout.mean + readout.std * readout.linear(memories)
        assert readout.loss(memories, exact).item() < 1e-10


def test_the_velocity_loss_teaches_the_students_memory(tmp_path: Path, teacher_file: Path) -> None:
    """Its gradient reaches the student's recurrent layers, and updates with it on lower it
    on their batch; without a read-out the update reports NaN. (A random teacher hardly
    moves the objects in 4 steps: the targets are a linear function of the student's first
    memories, spread as the teacher's statistics say, which a read-out can learn.)"""
    teacher, student = informed("hamnet"), build("student", seed=0)
    config = DaggerConfig(beta_initial=0.5, beta_final=0.5, epochs=30, lr=1e-3, velocity_coef=1.0)
    batch = build_dagger_worker(tiny_run(tmp_path, timeout=3), teacher).collect(
        teacher, student.eval(), STEPS, 0, config
    )
    readout = VelocityReadout(student.memory_width, teacher)
    starts = episode_starts(batch.dones, batch.first)
    with torch.no_grad():
        memories = evaluate_sequence(student, batch.inputs, batch.labels, starts).memories
        drawn = torch.nn.Linear(student.memory_width, 6)(memories)
        drawn = (drawn - drawn.mean((0, 1))) / drawn.std((0, 1))
    batch = dataclasses.replace(batch, object_velocity=readout.mean + readout.std * drawn)

    def loss() -> torch.Tensor:
        out = evaluate_sequence(student, batch.inputs, batch.labels, starts)
        return readout.loss(out.memories, batch.object_velocity)

    recurrent = [p for name, p in student.named_parameters() if "gru" in name]
    assert recurrent and any(g.abs().sum() > 0 for g in torch.autograd.grad(loss(), recurrent))
    before = loss().item()
    optimizer = torch.optim.Adam([*student.parameters(), *readout.parameters()], lr=1e-3)
    update_student(student, optimizer, batch, config, readout)
    assert loss().item() < 0.5 * before
    assert math.isnan(update_student(student, optimizer, batch, DaggerConfig()).velocity_loss)


def rows(run_dir: Path) -> list[dict[str, float]]:
    return [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]


def test_a_resumed_dagger_run_equals_the_uninterrupted_one(
    tmp_path: Path, teacher_file: Path
) -> None:
    """4 iterations in one go vs 2, a snapshot, 2 more in a new runner: equal metrics and
    student weights. A 3-step timeout and a beta that falls within the run make episodes end
    and who acts them be drawn on both sides of the snapshot; the velocity loss's read-out
    is resumed too, and the windows the update replays (two kept by then, one drawn at each
    step). PPO, another teacher and another velocity loss are refused."""
    dagger = DaggerConfig(
        beta_decay_transitions=3 * B * STEPS, velocity_coef=0.5, replay_windows=3, replay_draw=1
    )
    teacher = load_teacher(teacher_file)
    whole = Runner(tiny_run(tmp_path / "whole", 4, timeout=3), algorithm=Dagger(teacher, dagger))
    whole.run()
    Runner(tiny_run(tmp_path / "split", 2, timeout=3), algorithm=Dagger(teacher, dagger)).run()
    resumed = Runner(
        tiny_run(tmp_path / "split", 4, timeout=3), resume=True, algorithm=Dagger(teacher, dagger)
    )
    assert resumed.iteration == 2
    resumed.run()
    expected, got = rows(tmp_path / "whole"), rows(tmp_path / "split")
    assert [row["iteration"] for row in got] == [1, 2, 3, 4]
    assert 0 < got[-1]["student_share"] and got[-1]["student_episodes"] > 0
    for want, have in zip(expected, got, strict=True):
        for key in ("env_transitions", "beta", "student_share", "imitation_loss",
                    "imitation_loss_after", "episodes", "success_rate", "return/total",
                    "student_episodes", "velocity_loss"):  # fmt: skip
            assert have[key] == want[key], key
    assert len(whole.algorithm.replay) == len(resumed.algorithm.replay) == 2
    for name, tensor in whole.policy.state_dict().items():
        assert torch.equal(resumed.policy.state_dict()[name], tensor), name
    other = tmp_path / "other.safetensors"
    save_checkpoint(other, build("hamnet", seed=2), 7)
    as_ppo = dataclasses.replace(tiny_run(tmp_path / "split", 4, timeout=3), overlap=False)
    with pytest.raises(ResumeError, match="it is not a ppo run"):
        Runner(as_ppo, resume=True)
    with pytest.raises(ResumeError, match="distils the teacher"):
        Runner(
            tiny_run(tmp_path / "split", 4, timeout=3),
            resume=True,
            algorithm=Dagger(load_teacher(other), dagger),
        )
    with pytest.raises(ResumeError, match="with a velocity loss"):
        Runner(
            tiny_run(tmp_path / "split", 4, timeout=3),
            resume=True,
            algorithm=Dagger(teacher, dataclasses.replace(dagger, velocity_coef=0.0)),
        )


def same_state(a: torch.nn.Module, b: torch.nn.Module) -> bool:
    """Whether two networks hold equal parameters and buffers."""
    theirs = b.state_dict()
    return all(torch.equal(tensor, theirs[name]) for name, tensor in a.state_dict().items())


def test_the_student_is_the_moving_average_of_the_stepped_weights(
    tmp_path: Path, teacher_file: Path
) -> None:
    """With `weight_average` w the optimizer steps a copy: after one window the student is
    w x its start + (1 - w) x the stepped copy, parameter by parameter. A resume puts back
    the student, the stepped copy and Adam's state exactly as the snapshot held them (the
    steps after it agree to rounding only: the update's matrix products round differently
    with the memory they get); a run that turns averaging on at its resume starts the copy
    at the restored student."""
    teacher, w = load_teacher(teacher_file), 0.75
    dagger = DaggerConfig(weight_average=w, replay_windows=1)
    one = Runner(tiny_run(tmp_path / "one", 1), algorithm=Dagger(teacher, dagger))
    start = {k: v.clone() for k, v in one.policy.named_parameters()}
    one.run()
    stepped = dict(one.algorithm.trained.named_parameters())
    assert not same_state(one.policy, one.algorithm.trained)
    for name, value in one.policy.named_parameters():
        torch.testing.assert_close(value, w * start[name] + (1 - w) * stepped[name])
    resumed = Runner(tiny_run(tmp_path / "one", 2), resume=True, algorithm=Dagger(teacher, dagger))
    assert same_state(resumed.policy, one.policy)
    assert same_state(resumed.algorithm.trained, one.algorithm.trained)
    saved, restored = (r.algorithm.optimizer.state_dict()["state"] for r in (one, resumed))
    assert all(torch.equal(restored[i][k], v) for i in saved for k, v in saved[i].items())
    resumed.run()
    assert not same_state(resumed.policy, one.policy)
    plain = dataclasses.replace(dagger, weight_average=0.0)
    Runner(tiny_run(tmp_path / "plain", 1), algorithm=Dagger(teacher, plain)).run()
    turned_on = Runner(
        tiny_run(tmp_path / "plain", 2), resume=True, algorithm=Dagger(teacher, dagger)
    )
    assert same_state(turned_on.algorithm.trained, turned_on.policy)


TINY = ["--algo", "dagger", "--sim.num-envs", "2", "--sim.num-objects", "2", "--sim.nthread", "1",
        "--steps-per-rollout", "2"]  # fmt: skip


def test_hamnet_trainer_algo_dagger_writes_a_student_checkpoint_and_both_success_rates(
    tmp_path: Path, teacher_file: Path
) -> None:
    run = tmp_path / "run"
    args = [*TINY, "--inprocess", "--teacher", str(teacher_file), "--max-env-transitions", "8",
            "--eval-episodes", "2", "--pose-readings", "2", "--run-dir", str(run)]  # fmt: skip
    assert main(args) == 0
    summary = json.loads((run / "summary.json").read_text())
    assert summary["algo"] == "dagger" and summary["architecture"] == "student"
    assert summary["pose_readings"] == 2
    assert summary["teacher_success_rate"] in (0.0, 0.5, 1.0)
    assert summary["student_success_rate"] == summary["final_success_rate"]
    assert [point["beta"] for point in summary["curve"]] == [1.0, 1.0 - 4 / 200_000]
    student = policy_from(read_checkpoint(run / "checkpoints" / "latest.safetensors"))
    assert student.architecture == "student" and student.config.pose_readings == 2
    assert main(["plot", str(run)]) == 0


def test_bad_teachers_and_settings_are_one_line_and_status_2(
    tmp_path: Path, teacher_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    garbage = tmp_path / "garbage.safetensors"
    garbage.write_bytes(b"not a checkpoint at all")
    student = tmp_path / "student.safetensors"
    save_checkpoint(student, build("student", seed=0), 1)
    cases = {
        "cannot read teacher": ["--inprocess", "--teacher", str(tmp_path / "missing")],
        "not a policy checkpoint": ["--inprocess", "--teacher", str(garbage)],
        "a student's architecture": ["--inprocess", "--teacher", str(student)],
        "needs --teacher": ["--inprocess"],
        "is not a student": ["--inprocess", "--teacher", str(teacher_file), "--architecture", "hamnet"],
    }  # fmt: skip
    for message, args in cases.items():
        capsys.readouterr()
        assert main([*TINY, *args, "--run-dir", str(tmp_path / "run")]) == 2, message
        error = capsys.readouterr().err
        assert error.count("\n") == 1 and message in error, error


def test_pose_readings_for_a_teacher_architecture_is_a_usage_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Averaging pose readings is a student's: a privileged policy reads the true pose."""
    args = ["--inprocess", "--architecture", "hamnet", "--pose-readings", "2"]
    with pytest.raises(SystemExit) as stop:
        main([*args, "--run-dir", str(tmp_path / "run")])
    error = capsys.readouterr().err
    assert stop.value.code == 2 and error.count("\n") == 1 and "reads the true pose" in error


def test_a_dagger_worker_without_a_usable_teacher_is_one_line_and_status_2(
    tmp_path: Path, teacher_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`hamnet rollout --algo dagger` checks its teacher and student before joining Zenoh."""
    cases = {
        "needs --teacher": [],
        "cannot read teacher": ["--teacher", str(tmp_path / "missing")],
        "is not a student": ["--teacher", str(teacher_file), "--architecture", "hamnet"],
    }
    for message, args in cases.items():
        capsys.readouterr()
        assert rollout_main([*TINY, *args]) == 2, message
        error = capsys.readouterr().err
        assert error.count("\n") == 1 and message in error, error


def test_the_progress_line_shows_the_velocity_loss_only_when_it_is_on() -> None:
    row = {"iteration": 3, "env_transitions": 1536, "env_steps_per_s": 150.0, "beta": 0.5,
           "student_share": 0.5, "imitation_loss": 0.004, "success_rate": 0.1, "episodes": 20,
           "velocity_loss": math.nan}  # fmt: skip
    assert "velocity" not in dagger_line(row)
    assert "imitation 0.0040 | velocity 0.250 | success" in dagger_line(
        {**row, "velocity_loss": 0.25}
    )
