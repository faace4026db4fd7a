"""Stack files: what loads, the defaults it gets, and the messages of what does not load."""

from __future__ import annotations

from pathlib import Path

import pytest

from hamnet.launcher.stack import RestartPolicy, Stack, StackError, load

GOOD = """
name: demo
namespace: demo-ns
duration_s: 20
until: trainer
outputs: [runs/<namespace>/stack.mcap]
services:
  sim:
    workers: [0, 1]
    args: {num-envs: 4, render: false, seeds: [1, 2]}
    restart: {max_restarts: 5, backoff_s: 0.1, backoff_max_s: 1}
  trainer: {}
  watch:
    command: echo
    args: {period-s: 5}
"""


def write(tmp_path: Path, text: str, name: str = "stack.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def error_of(tmp_path: Path, text: str) -> str:
    with pytest.raises(StackError) as error:
        load(write(tmp_path, text))
    return str(error.value)


def test_good_file_loads_with_its_values(tmp_path: Path) -> None:
    stack = load(write(tmp_path, GOOD))
    assert (stack.name, stack.namespace, stack.duration_s, stack.until) == (
        "demo", "demo-ns", 20.0, "trainer")
    assert list(stack.services) == ["sim", "trainer", "watch"]
    sim = stack.services["sim"]
    assert sim.command == "sim" and sim.workers == ("0", "1")
    assert sim.args == {"num-envs": 4, "render": False, "seeds": (1, 2)}
    assert sim.restart == RestartPolicy(max_restarts=5, backoff_s=0.1, backoff_max_s=1.0)
    assert stack.services["watch"].command == "echo"
    assert stack.output_paths == (Path("runs/demo-ns/stack.mcap"),)


def test_defaults_come_from_the_file_name_and_service_names(tmp_path: Path) -> None:
    stack = load(write(tmp_path, "services: {echo: {}}", name="mystack.yaml"))
    assert (stack.name, stack.namespace) == ("mystack", "mystack")
    echo = stack.services["echo"]
    assert (echo.command, echo.workers, echo.args, echo.restart) == (
        "echo", ("0",), {}, RestartPolicy())
    assert (stack.duration_s, stack.until, stack.outputs) == (None, None, ())


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("services: {echo: {}}\ndurations_s: 3", "durations_s: unknown key (did you mean 'duration_s'?)"),
        ("services: {echo: {}}\nfoo: 1", "foo: unknown key (expected one of name,"),
        ("services: {echo: {argz: {}}}", "services.echo.argz: unknown key (did you mean 'args'?)"),
        ("services: {echo: {restart: {max_restart: 1}}}",
         "services.echo.restart.max_restart: unknown key (did you mean 'max_restarts'?)"),
    ],
)
def test_unknown_keys_are_named_with_their_path(tmp_path: Path, text: str, expected: str) -> None:
    assert expected in error_of(tmp_path, text)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("services: {echo: {}}\nduration_s: long", "duration_s: expected a number or null, got the string 'long'"),
        ("services: {echo: {workers: 0}}", "services.echo.workers: expected a list, got the number 0"),
        ("services: {echo: {args: [a, b]}}", "services.echo.args: expected a mapping, got a list"),
        ("services: {echo: {args: {x: {y: 1}}}}", "services.echo.args.x: expected"),
        ("services: {echo: {restart: {max_restarts: 1.5}}}", "max_restarts: expected an integer"),
        ("services: {echo: {restart: {max_restarts: true}}}", "max_restarts: expected an integer, got the boolean true"),
        ("services: [echo]", "services: expected a mapping, got a list"),
        ("- echo", "expected a mapping of stack keys, got a list"),
        ("name: x", "services: missing key"),
        ("services: {}", "the stack needs at least one service"),
        ("services: {echo: {}}\nduration_s: -1", "duration_s must be a positive number"),
        ("services: {echo: {}}\nuntil: sim", "until: 'sim' is not one of the services"),
        ("services: {echo: {}}\nnamespace: a/b", "namespace must be one key segment"),
        ("services: {echo: {workers: ['*']}}", "worker must be one key segment"),
        ("services: {echo: {workers: [1, 1]}}", "workers must be distinct"),
        ("services: {echo: {args: {worker: 1}}}", "'worker' is set by the launcher from the service's `workers` key"),
        ("services: {echo: {args: {namespace: x}}}", "'namespace' is set by the launcher"),
        ("services: {echo: {args: {--period-s: 1}}}", "not a flag name"),
        ("services: {echo: {restart: {backoff_s: 9}}}", "need 0 <= backoff_s <= backoff_max_s"),
        ("services: {a: {command: echo}, b: {command: echo}}",
         "services 'a' and 'b' both run `echo` as worker '0': their liveliness tokens would collide"),
        ("services: {echo: {}\n", "not valid YAML"),
    ],
)
def test_bad_values_fail_with_a_clear_message(tmp_path: Path, text: str, expected: str) -> None:
    message = error_of(tmp_path, text)
    assert message.startswith(str(tmp_path / "stack.yaml"))
    assert expected in message


def test_missing_file_is_a_stack_error(tmp_path: Path) -> None:
    with pytest.raises(StackError, match="cannot read the stack file"):
        load(tmp_path / "absent.yaml")


def test_restart_backoff_doubles_up_to_its_bound() -> None:
    policy = RestartPolicy(max_restarts=5, backoff_s=0.5, backoff_max_s=3.0)
    assert [policy.delay_s(n) for n in range(5)] == [0.5, 1.0, 2.0, 3.0, 3.0]


def test_stack_is_frozen(tmp_path: Path) -> None:
    stack: Stack = load(write(tmp_path, GOOD))
    with pytest.raises(AttributeError):
        stack.namespace = "other"  # type: ignore[misc]
