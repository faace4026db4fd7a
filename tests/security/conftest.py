"""Certificates for the security tests: one CA with a few identities, and a stranger whose
certificate another CA signed but who trusts ours (the strongest outsider: it knows the
public CA certificate, not the CA's key)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from hamnet.cli import COMMANDS
from hamnet.runtime.contract import OPERATOR
from hamnet.security.certs import init_ca, issue

STACK = tuple(sorted({command.name for command in COMMANDS} | {OPERATOR, "intruder"}))
"""Every name a certificate of a stack's CA could carry: each command's (a process of
`hamnet <command>` presents it), the operator's, and `intruder`, no identity of the stack."""

IDENTITIES = ("alice", "bob", *STACK)
"""Identities the stack's CA issues in these tests (alice and bob: two peers of test_tls)."""


@pytest.fixture(scope="session")
def certs(tmp_path_factory) -> Path:
    """A folder with ca.pem and one certificate per name of IDENTITIES."""
    directory = tmp_path_factory.mktemp("certs")
    init_ca(directory, days=1)
    for name in IDENTITIES:
        issue(directory, name, days=1)
    return directory


@pytest.fixture(scope="session")
def stranger(tmp_path_factory, certs: Path) -> Path:
    """A folder where `stranger`'s certificate comes from another CA, next to our ca.pem."""
    other = tmp_path_factory.mktemp("other-ca")
    init_ca(other, days=1)
    issue(other, "stranger", days=1)
    (other / "ca.pem").unlink()
    shutil.copy(certs / "ca.pem", other / "ca.pem")
    return other
