"""Certificates for the security tests: one CA with a few identities, and a stranger whose
certificate another CA signed but who trusts ours (the strongest outsider: it knows the
public CA certificate, not the CA's key)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from hamnet.security.certs import init_ca, issue

IDENTITIES = (
    "alice", "bob", "router", "up", "safety", "trainer", "operator", "sim", "policy", "intruder",
    "bridge", "perception", "rollout",
)  # fmt: skip
"""Identities the stack's CA issues in these tests; `intruder` is no identity of the stack."""


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
