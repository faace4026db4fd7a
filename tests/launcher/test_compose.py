"""The files of compose/ and the Dockerfile agree with the launcher and with each other.

No Docker engine runs on the test machines, so the container files are checked by reading
them: the same processes with the same command lines as `hamnet up compose/train.yaml`,
and an image that installs what pyproject.toml declares.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import tomllib
import yaml
from packaging.requirements import Requirement
from packaging.specifiers import SpecifierSet

from hamnet.launcher.argv import service_argv
from hamnet.launcher.cli import main
from hamnet.launcher.stack import load
from hamnet.perception.config import student_clouds
from hamnet.policy.shipped import read_card

ROOT = Path(__file__).resolve().parents[2]
COMPOSE = ROOT / "compose"
STACKS = sorted(COMPOSE.glob("*.yaml"))


def test_the_expected_stacks_exist() -> None:
    assert {p.name for p in STACKS} >= {"demo.yaml", "train.yaml", "eval.yaml", "real.yaml"}


@pytest.mark.parametrize("path", STACKS, ids=lambda p: p.name)
def test_every_stack_file_passes_check(path: Path, capsys) -> None:
    assert main(["--check", str(path)]) == 0, capsys.readouterr()


def test_real_differs_from_eval_only_where_the_real_robot_needs_it() -> None:
    """Swapping the simulator for the real robot changes the robot, adds the cameras that
    perception reads instead of the sim's scene, and sets safety's references to the FR3's
    1 kHz loop; the policy, the recording, the monitor and the security stay the same."""
    eval_stack, real_stack = load(COMPOSE / "eval.yaml"), load(COMPOSE / "real.yaml")
    assert eval_stack.namespace != real_stack.namespace  # their outputs do not overwrite each other
    assert (eval_stack.secure, eval_stack.outputs) == (real_stack.secure, real_stack.outputs)
    differ = {name for name in eval_stack.services.keys() | real_stack.services.keys()
              if eval_stack.services.get(name) != real_stack.services.get(name)}  # fmt: skip
    assert differ == {"robot", "camera", "perception", "safety"}
    robot = real_stack.services["robot"]
    assert (eval_stack.services["robot"].command, robot.command) == ("sim", "bridge")
    assert dict(real_stack.services["perception"].args)["clouds-from"] == "cameras"
    assert dict(real_stack.services["safety"].args)["trajectory.control-rate-hz"] == 1000
    assert dict(robot.args)["policy-period-s"] == dict(real_stack.services["safety"].args)[
        "trajectory.policy-period-s"]  # fmt: skip


@pytest.mark.parametrize("name", ["eval.yaml", "real.yaml"])
def test_evaluation_stacks_serve_the_student(name: str) -> None:
    """The deployable student is the default (issue 15), shipped in the package so that a
    fresh clone serves it (issue 28), by its mean, through a safety filter reading its
    action space (a filter in another space drops every action)."""
    services = load(COMPOSE / name).services
    assert services["policy"].args["weights"] == "easy-push-student"
    assert services["policy"].args["deterministic"] is True
    space = services["safety"].args["safety.action-magnitude.space"]
    assert space == read_card("easy-push-student")["action_space"]


def test_the_simulated_evaluation_gives_the_student_the_clouds_it_was_distilled_on() -> None:
    """In simulation the clouds are made as `student_clouds()` makes them (cameras' view,
    noise, dropout); on the real robot the cameras make them."""
    services = load(COMPOSE / "eval.yaml").services
    clouds = student_clouds()
    assert dict(services["perception"].args) == {
        "clouds.visibility": clouds.visibility,
        "clouds.noise-std": clouds.noise_std,
        "clouds.dropout": clouds.dropout,
    }


@pytest.mark.parametrize("name", ["eval.yaml", "real.yaml"])
def test_evaluation_stacks_are_secure_by_default(name: str) -> None:
    """A real robot must obey only its own safety service (issue 16): the stacks that drive
    one start their own router with the contract's access rules, on loopback."""
    secure = load(COMPOSE / name).secure
    assert secure is not None and (ROOT / secure.access).is_file()
    assert secure.access == "compose/secure/router.json5" and secure.listen.startswith(
        "tls/127.0.0.1:"
    )


def docker_name(service: str, worker: str, workers: tuple[str, ...]) -> str:
    """Container service name of one process: `sim-0`, or `trainer` for a single worker."""
    return f"{service}-{worker}" if len(workers) > 1 else service


def test_docker_compose_runs_the_processes_of_train_yaml() -> None:
    stack = load(COMPOSE / "train.yaml")
    expected = {
        docker_name(name, worker, spec.workers): (
            service_argv(spec, worker, stack.namespace, {}),
            f"on-failure:{spec.restart.max_restarts}",
        )
        for name, spec in stack.services.items()
        for worker in spec.workers
    }
    compose = yaml.safe_load((COMPOSE / "docker-compose.yml").read_text())
    actual = {
        name: ([str(arg) for arg in service["command"]], service["restart"])
        for name, service in compose["services"].items()
    }
    assert actual == expected
    for name, service in compose["services"].items():
        assert service["network_mode"] == "host", name
        assert service["stop_grace_period"] == f"{stack.stop_grace_s:g}s", name
        assert service["build"]["dockerfile"] == "Dockerfile"
        assert (COMPOSE / service["build"]["context"] / "Dockerfile").is_file()


def dockerfile_instructions() -> list[tuple[str, str]]:
    """(INSTRUCTION, arguments) of the Dockerfile, continuation lines joined."""
    text = re.sub(r"\\\n\s*", " ", (ROOT / "Dockerfile").read_text())
    return [
        (line.split(None, 1)[0].upper(), line.split(None, 1)[1])
        for line in text.splitlines()
        if line.strip() and not line.lstrip().startswith("#")
    ]


def test_dockerfile_installs_what_pyproject_declares() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    instructions = dockerfile_instructions()
    runs = [args for op, args in instructions if op == "RUN"]
    copied = {path for op, args in instructions if op == "COPY" for path in args.split()[:-1]}

    base = next(args for op, args in instructions if op == "FROM")
    python = re.fullmatch(r"python:(\d+\.\d+)-slim", base)
    assert python and SpecifierSet(project["project"]["requires-python"]).contains(python[1])

    torch_pin = next(re.search(r"torch==(\S+)", r)[1] for r in runs if "torch==" in r)
    torch = next(
        Requirement(d) for d in project["project"]["dependencies"] if d.startswith("torch")
    )
    assert torch.specifier.contains(torch_pin), (torch_pin, str(torch))
    assert runs.index(next(r for r in runs if "torch==" in r)) < runs.index(
        next(r for r in runs if r.endswith("pip install --no-cache-dir ."))
    )

    needed = {"pyproject.toml", project["project"]["readme"]}
    needed |= set(project["tool"]["setuptools"]["package-dir"].values())
    assert needed <= copied
    assert any("libusb-1.0-0" in r for r in runs)  # open3d cannot import without it

    entrypoint = next(args for op, args in instructions if op == "ENTRYPOINT")
    assert entrypoint == '["hamnet"]' and "hamnet" in project["project"]["scripts"]
