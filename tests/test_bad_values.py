"""Bad values on the command line: each is one line on stderr naming what is wrong, exit
status 2 and no traceback (issue 13 found a traceback or silent acceptance for each). The
checks live in the configs' `__post_init__` and `hamnet.runtime.transport`; `parse` and
`hamnet`'s entry turn them into that one line, so every service behaves the same."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from safetensors.torch import save as save_tensors

from hamnet.policy.registry import build
from hamnet.policy.weights import from_bytes, to_bytes

pytestmark = pytest.mark.stack  # each test runs `hamnet` commands as processes


def refused(*args: str) -> str:
    """Run `hamnet <args>`; assert it failed with one line on stderr and return that line."""
    result = subprocess.run([sys.executable, "-m", "hamnet", *args], check=False, capture_output=True,
                            text=True, timeout=120)  # fmt: skip
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2, result.stderr
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    return lines[0]


@pytest.mark.parametrize(
    "args, message",
    [
        (["sim", "--num-envs", "0"], "num_envs must be >= 1, got 0"),
        (["sim", "--num-envs", "-1"], "num_envs must be >= 1, got -1"),
        (["sim", "--worker", "a/b"], "worker must be one key segment"),
        (["policy", "--random-init", "mlp", "--worker", "a*"], "worker must be one key segment"),
        (["safety", "--namespace", "a/b"], "namespace must be one key segment"),
        (["sim", "--rendezvous", "garbage"], "rendezvous endpoint 'garbage' is not a Zenoh locator"),
        (["monitor", "--save", "x.rrd", "--connect", "tcp"], "connect endpoint 'tcp' is not"),
        (["sim", "--zenoh-config", "missing.json5"], "Zenoh config file not found: missing.json5"),
        (["sim", "--report-period-s", "-1"], "--report-period-s must be > 0 s, got -1.0"),
        (["perception", "--random-init", "--report-period-s", "0"], "--report-period-s must be > 0"),
        # Refused by a nested config or by tyro itself: a box of 5-9 lines before issue 29.
        (["trainer", "--ppo.epochs", "0"], "epochs and minibatches must be >= 1"),
        (["trainer", "--ppo.lr", "-1"], "lr must be > 0, got -1.0"),
        (["replay", "--speed", "0", "x.mcap"], "speed must be > 0, got 0.0"),
        (["record", "--rotate-mb", "-1"], "rotate_mb and rotate_s must be >= 0"),
        (["safety", "--watchdog-s", "-1"], "watchdog_s must be > 0, got -1.0"),
        (["monitor", "--max-rate-hz", "0", "--save", "x.rrd"], "max_rate_hz must be > 0, got 0.0"),
        (["sim", "--num-envs", "abc"], "--num-envs: invalid literal for int() with base 10: 'abc'"),
        (["sim", "--no-such-flag", "3"], "Unrecognized options: --no-such-flag"),
    ],
    ids=lambda v: " ".join(v) if isinstance(v, list) else None,
)
def test_a_bad_flag_is_one_line_and_exit_2(args: list[str], message: str) -> None:
    line = refused(*args)
    assert line.startswith(f"hamnet {args[0]}: ") and message in line, line


def test_a_zenoh_config_file_zenoh_refuses_is_one_line_without_build_paths(tmp_path: Path) -> None:
    path = tmp_path / "zenoh.json5"
    path.write_text("{ mode: 42 }")
    line = refused("sim", "--zenoh-config", str(path))
    assert line.startswith("hamnet sim: Zenoh config: ") and ".rs:" not in line, line


def test_a_session_zenoh_cannot_open_is_one_line(tmp_path: Path) -> None:
    """A router must listen where asked; an address of no interface fails the open."""
    line = refused("router", "--listen", "tcp/192.0.2.1:7", "--rendezvous", "")
    assert line.startswith("hamnet router: cannot open the Zenoh session: "), line
    assert ".rs:" not in line and "/root/" not in line, line


def _checkpoint(tmp_path: Path, **changes) -> Path:
    """A state-mlp checkpoint whose metadata config has `changes` (the tensors are real)."""
    weights = from_bytes(to_bytes(build("state-mlp", seed=0), 1))
    config = {**json.loads(weights.config.to_json()), **changes}
    metadata = {"format": "hamnet-policy/1", "architecture": "state-mlp", "version": "1",
                "config": json.dumps(config)}  # fmt: skip
    path = tmp_path / "policy.safetensors"
    path.write_bytes(save_tensors(weights.tensors, metadata=metadata))
    return path


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"log_std": 5}, "log_std must be a JSON object, got 5"),
        ({"log_std": {"initial": 5.0}}, "log_std.initial must be in [-20, 2], got 5.0"),
        ({"state_hidden": [2**40, 256]}, "describes 734,473,767,361,484 parameters, the file holds 178,124"),
        ({"state_hidden": "wide"}, "state_hidden must be a JSON list"),
        ({"action_dim": True}, "action_dim must be of type int, got True"),
    ],
    ids=["log_std-type", "log_std-range", "2^40-wide", "widths-type", "bool-for-int"],
)
def test_a_checkpoint_with_bad_metadata_is_refused_before_building(tmp_path, changes, message) -> None:
    """The 2^40-wide layer would need petabytes: the parameter count implied by the config is
    compared with the file's tensors on a meta-device build, so nothing is allocated."""
    path = _checkpoint(tmp_path, **changes)
    line = refused("policy", "--checkpoint", str(path))
    assert message in line, line


def test_a_stack_file_that_is_not_yaml_is_one_line_with_where(tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text("services:\n  sim: {args: {num-envs: 2}\n")
    for args in (["up", str(path)], ["up", "--check", str(path)]):
        line = refused(*args)
        assert line.startswith(f"hamnet up: {path}: not valid YAML: expected ',' or '}}'"), line
        assert "at line 3, column 1" in line, line
