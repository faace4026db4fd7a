"""`hamnet eval` end to end on a random policy: real sim, benchmark domains, safety filter,
report, figure, records and recordings, as a user runs it (a few episodes)."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

from hamnet.evaluation.cli import main
from hamnet.evaluation.config import EvalConfig
from hamnet.evaluation.records import FAILURE_REASONS, read_records
from hamnet.evaluation.skills import SkillSteps
from hamnet.policy.registry import build
from hamnet.policy.weights import save_checkpoint

pytestmark = pytest.mark.stack  # a command-line check: left out of --fast

SUITES = ("procedural", "cabinet", "sink")


@pytest.fixture(scope="module")
def evaluated(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[str], Path, dict]:
    """A random state MLP evaluated with --quick on three suites of the easy stage (whose
    own placement, 15-25 cm pushes keeping the goal's orientation, no domain pair could
    meet: the domains place by their own rule); (out folder, argv, the checkpoint, the last
    printed line as JSON)."""
    folder = tmp_path_factory.mktemp("eval")
    checkpoint = folder / "random.safetensors"
    save_checkpoint(checkpoint, build("mlp", seed=0), 1)
    out = folder / "out"
    argv = [
        "--policy",
        str(checkpoint),
        "--quick",
        "--suites",
        *SUITES,
        "--stage",
        "easy",
        "--out",
        str(out),
    ]
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        status = main(argv)
    assert status == 0
    return out, argv, checkpoint, json.loads(printed.getvalue().strip().splitlines()[-1])


def test_a_quick_eval_writes_a_well_formed_report(evaluated) -> None:
    """Every suite asked for is played with --quick's 2 episodes each and reported with an
    interval that holds its rate; every episode has a known reason; the last line is the
    JSON a script reads; the figure and one recording per suite exist."""
    out, _, _, last = evaluated
    assert set(last) >= {"success_rate", "episodes", "per_domain", "procedural"}
    assert last["episodes"] == 2 * len(SUITES) and list(last["per_domain"]) == list(SUITES[1:])
    report = json.loads((out / "report.json").read_text())
    assert list(report["per_domain"]) == list(SUITES)
    run = report["run"]
    assert (run["stage"], run["pairs"], run["inits"], run["safety_profile"]) == (
        "easy",
        1,
        2,
        "training",
    )
    assert run["suites"] == list(SUITES) and len(run["commit"]) in (0, 40)
    for summary in (*report["per_domain"].values(), report["overall"]):
        assert summary["ci_low"] <= summary["rate"] <= summary["ci_high"]
        assert summary["successes"] + sum(summary["reasons"].values()) == summary["episodes"]
    records = read_records(out / "random.records.jsonl")
    assert [r.suite for r in records] == [s for s in SUITES for _ in range(2)]
    assert all(r.success or r.reason in FAILURE_REASONS for r in records)
    assert all(0 < r.length and r.start_distance > 0 for r in records)
    assert (out / "report.png").read_bytes()[:4] == b"\x89PNG"
    assert sorted(p.name for p in (out / "recordings").iterdir()) == sorted(
        f"{suite}_0.rrd" for suite in SUITES
    )


def test_the_same_seed_plays_the_same_episodes(evaluated, tmp_path: Path) -> None:
    """Two evaluations with one seed give identical records (the plan is the seed's alone),
    and a comparison of the policy with its copy plays both on those episodes: no
    difference in any suite. The same episodes play through the deploy profile's filter."""
    out, argv, checkpoint, _ = evaluated
    copy = tmp_path / "copy.safetensors"
    copy.write_bytes(checkpoint.read_bytes())
    again = tmp_path / "again"
    argv = [*argv[:-1], str(again), "--record", "0"]
    assert main([*argv[:1], str(checkpoint), str(copy), *argv[2:]]) == 0
    deployed = tmp_path / "deployed"
    assert main([*argv[:-3], str(deployed), "--safety-profile", "deploy"]) == 0
    assert (
        EvalConfig(stack=True).filter_profile
        == "deploy"
        == EvalConfig(safety_profile="deploy").filter_profile
    )
    assert EvalConfig().filter_profile == "training"
    assert len(read_records(deployed / "random.records.jsonl")) == len(SUITES) * 2
    first = read_records(out / "random.records.jsonl")
    assert read_records(again / "random.records.jsonl") == first
    assert read_records(again / "copy.records.jsonl") == first
    report = json.loads((again / "report.json").read_text())
    assert report["reference"] == str(checkpoint) and len(report["differences"]) == 4
    assert all(difference["difference"] == 0 for difference in report["differences"])


def test_an_unknown_policy_is_one_line_and_status_2(tmp_path: Path, capsys) -> None:
    assert main(["--policy", "no-such-policy", "--out", str(tmp_path)]) == 2
    assert "no-such-policy" in capsys.readouterr().err
    with pytest.raises(SystemExit) as stopped:
        main(["--policy", "a/x.safetensors", "b/x.safetensors", "--out", str(tmp_path)])
    assert stopped.value.code == 2 and "share a name" in capsys.readouterr().err


def test_over_the_services_the_same_episodes_are_played(evaluated, tmp_path: Path) -> None:
    """--stack serves the policy, its perception (when it reads clouds) and the safety
    filter as processes and plays the same
    episodes (same suites, objects, pairs, inits and starts) as in this process; their
    logs are kept."""
    out, argv, _, _ = evaluated
    stacked = tmp_path / "stacked"
    assert main([*argv[:-1], str(stacked), "--stack", "--record", "0"]) == 0
    here = read_records(out / "random.records.jsonl")
    there = read_records(stacked / "random.records.jsonl")
    key = lambda r: (r.suite, r.object_name, r.pair, r.init, round(r.start_distance, 6))
    assert [key(r) for r in there] == [key(r) for r in here]
    assert all(r.success or r.reason in FAILURE_REASONS for r in there)
    logs = {"policy.log", "safety.log"} | (
        {"perception.log"} if build("mlp").config.clouds else set()
    )
    assert {p.name for p in (stacked / "logs").iterdir()} == logs
    assert "serving mlp" in (stacked / "logs" / "policy.log").read_text()


def test_skills_link_every_counted_step_to_its_episode(tmp_path: Path) -> None:
    """--skills on a random HAMnet: one embedding per counted step, the episode ids are the
    records' lines and each episode's steps run 0 .. length - 1; the figure, view and
    timelines are written."""
    checkpoint = tmp_path / "hamnet.safetensors"
    save_checkpoint(checkpoint, build("hamnet", seed=0), 1)
    out = tmp_path / "out"
    argv = [
        "--policy",
        str(checkpoint),
        "--quick",
        "--suites",
        "procedural",
        "flat",
        "--stage",
        "easy",
        "--record",
        "0",
        "--skills",
        "--out",
        str(out),
    ]
    assert main(argv) == 0
    records = read_records(out / "hamnet.records.jsonl")
    steps = SkillSteps.load(out / "skills" / "steps.npz")
    assert len(steps.embeddings) == sum(r.length for r in records)
    for episode, record in enumerate(records):
        mine = steps.step[steps.episode == episode]
        assert sorted(mine.tolist()) == list(range(record.length))
        assert set(steps.suite[steps.episode == episode].tolist()) == {record.suite}
    assert {p.name for p in (out / "skills").iterdir()} >= {"skills.png", "skills.rrd"}
