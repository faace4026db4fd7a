"""Zenoh configuration: loopback-only peer mode by default, files and flags on top."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest

from hamnet.runtime.errors import ConfigError
from hamnet.runtime.transport import TransportConfig, free_port, open_session, zenoh_config


def settings(config) -> dict:
    return {
        key: json.loads(config.get_json(key))
        for key in ("mode", "scouting/multicast/enabled", "listen/endpoints", "connect/endpoints")
    }


def test_default_is_a_loopback_peer_without_multicast() -> None:
    """Zenoh's own default listens on every interface and scouts by multicast: a test run
    would then reach the network. Every endpoint must be on 127.0.0.1."""
    values = settings(zenoh_config(TransportConfig()))
    assert values["mode"] == "peer" and values["scouting/multicast/enabled"] is False
    endpoints = values["listen/endpoints"] + values["connect/endpoints"]
    assert endpoints and all(e.startswith("tcp/127.0.0.1:") for e in endpoints)


def test_router_listens_on_loopback_unless_told_otherwise() -> None:
    """A router used to listen on tcp/0.0.0.0:7447, open to every network the host is on:
    its default endpoint must be the Zenoh port on 127.0.0.1, and --listen replaces it."""
    values = settings(zenoh_config(TransportConfig(mode="router")))
    assert values["mode"] == "router" and values["listen/endpoints"] == ["tcp/127.0.0.1:7447"]
    told = TransportConfig(mode="router", listen=("tcp/192.168.1.2:7447",))
    assert settings(zenoh_config(told))["listen/endpoints"] == ["tcp/192.168.1.2:7447"]


def test_flags_add_endpoints_to_a_config_file(tmp_path: Path) -> None:
    path = tmp_path / "zenoh.json5"
    path.write_text('{ mode: "client", connect: { endpoints: ["tcp/10.0.0.1:7447"] } }')
    from_file = settings(zenoh_config(TransportConfig(mode="client", zenoh_config=path)))
    assert from_file["connect/endpoints"] == ["tcp/10.0.0.1:7447"]
    flagged = TransportConfig(mode="client", zenoh_config=path, connect=("tcp/10.0.0.2:7447",))
    assert settings(zenoh_config(flagged))["connect/endpoints"] == ["tcp/10.0.0.2:7447"]


def test_shared_memory_settings_reach_zenoh() -> None:
    config = zenoh_config(TransportConfig(shm_pool_mb=32, shm_threshold=4096))
    optimization = json.loads(config.get_json("transport/shared_memory/transport_optimization"))
    assert optimization["pool_size"] == 32 << 20 and optimization["message_size_threshold"] == 4096
    off = zenoh_config(TransportConfig(shared_memory=False))
    assert json.loads(off.get_json("transport/shared_memory/enabled")) is False


def test_bad_settings_fail_with_clear_errors(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="namespace"):
        TransportConfig(namespace="a/b")
    with pytest.raises(ConfigError, match="Zenoh config file not found"):
        TransportConfig(zenoh_config=tmp_path / "missing.json5")
    for endpoint in ("garbage", "tcp/", "/127.0.0.1:7447", "tcp/127.0.0.1:7447 x"):
        with pytest.raises(ConfigError, match="not a Zenoh locator"):
            TransportConfig(connect=(endpoint,))


def test_locators_zenoh_accepts_pass() -> None:
    endpoints = ("tcp/127.0.0.1:7447", "tcp/[::1]:7447", "udp/10.0.0.1:7447#iface=eth0",
                 "tls/example.org:7447?prio=1", "unixsock-stream//tmp/zenoh.sock")  # fmt: skip
    zenoh_config(TransportConfig(mode="client", rendezvous="", connect=endpoints))


def test_a_peer_joins_an_endpoint_that_comes_up_after_it() -> None:
    """A peer that starts before what it connects to (a router, or the rendezvous while its
    holder starts) keeps trying in the background and is connected once that is up."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    early = open_session(TransportConfig(rendezvous="", connect=(endpoint,)))
    try:
        time.sleep(1.5)  # its first try has failed
        late = open_session(TransportConfig(rendezvous="", listen=(endpoint,)))
        try:
            deadline = time.monotonic() + 20
            while late.info.zid() not in list(early.info.peers_zid()):
                assert time.monotonic() < deadline, "the early peer never joined"
                time.sleep(0.1)
        finally:
            late.close()
    finally:
        early.close()
