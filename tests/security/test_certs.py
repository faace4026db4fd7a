"""`hamnet certs`: a local CA and one certificate per identity, keys private, clear errors."""

from __future__ import annotations

import stat
from pathlib import Path

import pytest
from cryptography import x509

from hamnet.launcher.certs_cli import main
from hamnet.security.certs import common_name


def certs(*argv: str) -> int:
    return main(list(argv))


def test_issued_certificate_names_the_identity_and_is_signed_by_the_ca(tmp_path: Path) -> None:
    """Access control matches the certificate's common name: it must be NAME exactly, the
    CA must have signed it, and loopback plus the given hosts must be in its names."""
    assert certs("init", "--dir", str(tmp_path)) == 0
    assert certs("issue", "safety", "--dir", str(tmp_path), "--host", "hub.lan", "10.0.0.5") == 0
    ca = x509.load_pem_x509_certificate((tmp_path / "ca.pem").read_bytes())
    issued = x509.load_pem_x509_certificate((tmp_path / "safety.pem").read_bytes())
    issued.verify_directly_issued_by(ca)
    assert common_name(tmp_path / "safety.pem") == "safety"
    names = issued.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert set(names.get_values_for_type(x509.DNSName)) == {"localhost", "hub.lan"}
    assert {str(a) for a in names.get_values_for_type(x509.IPAddress)} == {"127.0.0.1", "10.0.0.5"}


def test_private_keys_are_readable_by_their_owner_only(tmp_path: Path) -> None:
    assert certs("init", "--dir", str(tmp_path)) == 0
    assert certs("issue", "trainer", "--dir", str(tmp_path)) == 0
    for key in ("ca.key", "trainer.key"):
        assert stat.S_IMODE((tmp_path / key).stat().st_mode) == 0o600


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (("issue", "safety"), "no CA in"),
        (("init",), "exists: pass --force"),
        (("issue", "a b"), "identity 'a b' must be"),
        (("issue", "ca"), "identity 'ca' must be"),
        (("issue", "x", "--days", "0"), "days must be >= 1"),
        (("issue", "x", "--host", "bad host"), "neither a host name nor an IP address"),
        (("renew",), "expected init, issue or stack"),
        (("stack", "absent.yaml"), "absent.yaml: cannot read the stack file"),
    ],
)
def test_bad_requests_are_one_line(tmp_path: Path, capsys, argv, message) -> None:
    if argv != ("issue", "safety"):
        assert certs("init", "--dir", str(tmp_path)) == 0
        capsys.readouterr()
    assert certs(*argv, "--dir", str(tmp_path)) == 2
    error = capsys.readouterr().err
    assert message in error and "Traceback" not in error
    assert error.startswith("hamnet certs")


def test_existing_certificate_is_replaced_only_with_force(tmp_path: Path, capsys) -> None:
    assert certs("init", "--dir", str(tmp_path)) == 0
    assert certs("issue", "operator", "--dir", str(tmp_path)) == 0
    first = (tmp_path / "operator.pem").read_bytes()
    assert certs("issue", "operator", "--dir", str(tmp_path)) == 2
    assert "operator.pem exists: pass --force" in capsys.readouterr().err
    assert certs("issue", "operator", "--dir", str(tmp_path), "--force") == 0
    assert (tmp_path / "operator.pem").read_bytes() != first


def test_one_command_makes_every_certificate_a_stack_needs(tmp_path: Path, capsys) -> None:
    """`hamnet certs stack FILE`: the CA in the stack's tls_dir, then the router (with
    --host), the launcher, each service's command and the operator; run again, it keeps
    what exists."""
    stack = tmp_path / "stack.yaml"
    stack.write_text(f"secure: {{tls_dir: {tmp_path / 'keys'}}}\n"
                     "services: {sim: {workers: [0, 1]}, watch: {command: echo}}\n")  # fmt: skip
    assert certs("stack", str(stack), "--host", "hub.lan") == 0
    names = ["echo", "operator", "router", "sim", "up"]
    assert sorted(p.stem for p in (tmp_path / "keys").glob("*.pem")) == ["ca", *names]
    assert {common_name(tmp_path / "keys" / f"{name}.pem") for name in names} == set(names)
    router = x509.load_pem_x509_certificate((tmp_path / "keys" / "router.pem").read_bytes())
    hosts = router.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert "hub.lan" in hosts.get_values_for_type(x509.DNSName)
    first = (tmp_path / "keys" / "sim.pem").read_bytes()
    capsys.readouterr()
    assert certs("stack", str(stack)) == 0
    assert capsys.readouterr().out.count("kept ") == len(names)
    assert (tmp_path / "keys" / "sim.pem").read_bytes() == first
