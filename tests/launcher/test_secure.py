"""A stack file's `secure:` section: its router comes first and every process is placed on
it; what a user could get wrong is one line; `--check` says how the stack runs and which
certificates are missing. (The stack itself runs in tests/security/test_secure_up.py.)"""

from __future__ import annotations

from pathlib import Path

import pytest

from hamnet.cli import main as hamnet
from hamnet.launcher.argv import forwarded, service_argv
from hamnet.launcher.secure import identities, secured
from hamnet.launcher.stack import StackError, load
from hamnet.runtime.cli import CommonConfig
from hamnet.runtime.errors import ConfigError
from hamnet.runtime.transport import TransportConfig

ROOT = Path(__file__).resolve().parents[2]
SECURE = """\
name: lab
secure: {tls_dir: keys, access: compose/secure/router.json5, listen: tls/127.0.0.1:7450}
services:
  sim: {}
  watch: {command: echo}
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "stack.yaml"
    path.write_text(text)
    return path


def test_the_router_comes_first_and_every_process_is_its_client(tmp_path: Path) -> None:
    stack, common = secured(load(write(tmp_path, SECURE)), CommonConfig())
    assert list(stack.services) == ["router", "sim", "watch"]
    forward = forwarded(common)
    assert forward == {"mode": "client", "rendezvous": "", "connect": ("tls/127.0.0.1:7450",),
                       "tls-dir": "keys"}  # fmt: skip
    assert service_argv(stack.services["sim"], "0", "lab", forward) == [
        "sim", "--namespace", "lab", "--mode", "client", "--rendezvous", "", "--connect",
        "tls/127.0.0.1:7450", "--tls-dir", "keys", "--worker", "0"]  # fmt: skip
    # The router listens where the others connect, and connects nowhere itself.
    assert service_argv(stack.services["router"], "0", "lab", forward) == [
        "router", "--namespace", "lab", "--rendezvous", "", "--tls-dir", "keys", "--mode", "router",
        "--connect", "--listen", "tls/127.0.0.1:7450", "--zenoh-config",
        "compose/secure/router.json5", "--worker", "0"]  # fmt: skip
    assert identities(stack) == ["echo", "router", "sim", "up"]


def test_a_stack_without_the_section_is_left_alone(tmp_path: Path) -> None:
    plain = load(write(tmp_path, "services: {sim: {}}\n"))
    common = CommonConfig(transport=TransportConfig(connect=("tcp/10.0.0.1:7447",)))
    assert secured(plain, common) == (plain, common)


def test_options_that_would_place_processes_elsewhere_are_refused(tmp_path: Path) -> None:
    common = CommonConfig(transport=TransportConfig(mode="client", connect=("tcp/10.0.0.1:7447",)))
    with pytest.raises(ConfigError, match="stack lab is secure.*drop --mode, --connect$"):
        secured(load(write(tmp_path, SECURE)), common)


@pytest.mark.parametrize(("text", "expected"), [
    ("secure: {listen: tcp/127.0.0.1:7447}\nservices: {sim: {}}\n",
     "secure: listen must be tls/<host>:<port>, got 'tcp/127.0.0.1:7447'"),
    ("secure: {}\nservices: {hub: {command: router}}\n",
     "services.hub: a secure stack starts its own router; remove this service"),
])  # fmt: skip
def test_bad_secure_sections_fail_with_the_key(tmp_path: Path, text: str, expected: str) -> None:
    with pytest.raises(StackError, match=f"stack.yaml: {expected}"):
        load(write(tmp_path, text))


def test_check_says_how_the_stack_runs_and_what_certificates_are_missing(tmp_path: Path,
                                                                         capsys) -> None:  # fmt: skip
    """Missing certificates are noted, not errors (they are made where the stack runs);
    `hamnet up` itself refuses to start without them, in one line."""
    path = write(tmp_path, SECURE.replace("compose/", f"{ROOT}/compose/"))
    assert hamnet(["up", "--check", str(path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1] == (f"  secure: mutual TLS (certificates in keys), access control by {ROOT}/"
                        "compose/secure/router.json5 on the stack's router at tls/127.0.0.1:7450")  # fmt: skip
    assert lines[2] == (f"  certificates missing in keys: ca, echo, router, sim, up (`hamnet certs "
                        f"stack {path}` makes them)")  # fmt: skip
    assert lines[3].split()[:2] == ["router", "hamnet"]
    assert hamnet(["up", str(path)]) == 2
    assert capsys.readouterr().err == (f"hamnet up: {path}: certificates missing in keys: ca, echo, "
                                       f"router, sim, up; make them with `hamnet certs stack {path}`\n")  # fmt: skip


def test_check_says_when_a_stack_is_not_secure(tmp_path: Path, capsys) -> None:
    path = write(tmp_path, "services: {watch: {command: echo}}\n")
    assert hamnet(["up", "--check", str(path)]) == 0
    assert capsys.readouterr().out.splitlines()[1].startswith("  not secure: plain links")
