"""Mutual TLS between real Zenoh sessions on loopback: peers with certificates from the
stack's CA talk; a certificate from another CA, or none, gets no link at all."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
import zenoh

from hamnet.cli import main as hamnet
from hamnet.launcher.argv import forwarded
from hamnet.runtime.cli import CommonConfig, parse_service
from hamnet.runtime.errors import ConfigError
from hamnet.runtime.transport import TransportConfig, free_port, open_session, zenoh_config
from hamnet.tools.router import RouterConfig


def tls_peer(directory: Path, identity: str, **endpoints: tuple[str, ...]) -> zenoh.Session:
    return open_session(TransportConfig(rendezvous="", tls_dir=directory, identity=identity,
                                        **endpoints))  # fmt: skip


def no_certificate_peer(certs: Path, endpoint: str) -> zenoh.Session:
    """A TLS client that trusts the CA but presents no certificate of its own."""
    config = zenoh.Config()
    settings = {"mode": "peer", "scouting/multicast/enabled": False, "listen/endpoints": [],
                "connect/endpoints": [endpoint],
                "transport/link/tls/root_ca_certificate": str(certs / "ca.pem")}  # fmt: skip
    for key, value in settings.items():
        config.insert_json5(key, json.dumps(value))
    return zenoh.open(config)


def test_peers_with_the_stacks_certificates_exchange_and_strangers_get_nothing(
    certs: Path, stranger: Path
) -> None:
    """Alice listens on tls/; bob (same CA), a stranger (another CA) and a peer without a
    certificate all connect and subscribe. Alice publishes until bob has a message: by
    then the others had the same chance, and must have neither a message nor a link."""
    endpoint = f"tls/127.0.0.1:{free_port()}"
    alice = tls_peer(certs, "alice", listen=(endpoint,))
    bob = tls_peer(certs, "bob", connect=(endpoint,))
    outsiders = {"stranger": tls_peer(stranger, "stranger", connect=(endpoint,)),
                 "no certificate": no_certificate_peer(certs, endpoint)}  # fmt: skip
    received: dict[str, list[bytes]] = {"bob": [], "stranger": [], "no certificate": []}
    for name, session in {"bob": bob, **outsiders}.items():
        session.declare_subscriber("secure/**", lambda s, n=name: received[n].append(s.payload))
    deadline = time.monotonic() + 30
    while not received["bob"] and time.monotonic() < deadline:
        alice.put("secure/hello", b"hello")
        time.sleep(0.1)
    assert received["bob"], "bob (same CA) never received alice's message"
    assert received["stranger"] == [] and received["no certificate"] == []
    assert set(alice.info.peers_zid()) == {bob.info.zid()}
    for session in (alice, bob, *outsiders.values()):
        session.close()


def test_tls_settings_reach_zenoh_and_plain_endpoints_are_refused(certs: Path) -> None:
    """With --tls-dir every link is mutual TLS: the rendezvous moves to tls/, tcp/ links
    are not allowed at all, and a tcp/ endpoint on the command line is one clear error."""
    transport = TransportConfig(rendezvous="tcp/127.0.0.1:7448", tls_dir=certs, identity="safety")
    config = zenoh_config(transport)
    tls = json.loads(config.get_json("transport/link/tls"))
    assert tls["enable_mtls"] is True and tls["root_ca_certificate"] == str(certs / "ca.pem")
    assert tls["connect_certificate"] == tls["listen_certificate"] == str(certs / "safety.pem")
    assert json.loads(config.get_json("transport/link/protocols")) == ["tls", "quic"]
    assert json.loads(config.get_json("connect/endpoints")) == ["tls/127.0.0.1:7448"]
    router = zenoh_config(TransportConfig(mode="router", tls_dir=certs, identity="router"))
    assert json.loads(router.get_json("listen/endpoints")) == ["tls/127.0.0.1:7447"]
    with pytest.raises(ConfigError, match="must be tls/ or quic/"):
        TransportConfig(tls_dir=certs, identity="safety", connect=("tcp/127.0.0.1:7447",))
    with pytest.raises(ConfigError, match="TLS file not found: .*nobody.pem"):
        TransportConfig(tls_dir=certs, identity="nobody")
    with pytest.raises(ConfigError, match="needs --identity"):
        zenoh_config(TransportConfig(tls_dir=certs))


def test_a_service_presents_its_own_certificate_unless_told_otherwise(certs: Path) -> None:
    """`hamnet safety --tls-dir D` presents D/safety.pem; a stack's `hamnet up --tls-dir D`
    forwards the folder but not its own identity, or every service would present one."""
    config, _ = parse_service(RouterConfig, ["--tls-dir", str(certs)], "safety", "")
    assert config.common.transport.identity == "safety"
    told, _ = parse_service(RouterConfig, ["--tls-dir", str(certs), "--identity", "bob"], "x", "")
    assert told.common.transport.identity == "bob"
    launcher = CommonConfig(transport=TransportConfig(tls_dir=certs, identity="alice"))
    assert forwarded(launcher) == {"tls-dir": str(certs)}


def test_hamnet_up_presents_its_own_certificate(certs: Path, tmp_path: Path, capsys) -> None:
    """`hamnet up --tls-dir D` joins as `up` (D/up.pem), like a service under its name: a
    folder without up.pem is one line and exit 2, one with it passes."""
    stack = tmp_path / "stack.yaml"
    stack.write_text("services: {watch: {command: echo}}\n")
    assert hamnet(["up", "--check", str(stack), "--tls-dir", str(certs)]) == 0
    (tmp_path / "ca.pem").write_bytes((certs / "ca.pem").read_bytes())
    assert hamnet(["up", "--check", str(stack), "--tls-dir", str(tmp_path)]) == 2
    assert capsys.readouterr().err.strip().endswith(f"{tmp_path / 'up.pem'} (`hamnet certs` makes "
                                                    "it; docs/security.md)")  # fmt: skip
