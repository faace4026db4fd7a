"""The contract's publishers and readers against what the services declare: a service with
ports publishes exactly the topics of its outputs and reads exactly those of its inputs, so
the access rules generated from the contract (`hamnet.security.acl`) cannot drift from the
code."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import hamnet
from hamnet.cli import COMMANDS
from hamnet.runtime import contract
from hamnet.runtime.ports import Ports

DECLARES_PORTS = re.compile(r"^PORTS = Ports\(", re.MULTILINE)


def shells_with_ports() -> dict[str, Ports]:
    """Every module of the package that declares `PORTS`, by the command that runs it (the
    module's package: `hamnet.sim.shell` is `hamnet sim`)."""
    root = Path(hamnet.__file__).parent
    found: dict[str, Ports] = {}
    for path in sorted(root.rglob("*.py")):
        if not DECLARES_PORTS.search(path.read_text()):
            continue
        parts = path.relative_to(root).with_suffix("").parts
        module = importlib.import_module(".".join(("hamnet", *parts)))
        assert parts[0] not in found, f"two modules of {parts[0]} declare ports"
        found[parts[0]] = module.PORTS
    return found


def test_every_service_with_ports_is_in_the_contract_as_its_ports_say() -> None:
    """Outputs: the service is among the topic's publishers; inputs: among its readers, or,
    for a queryable (safety's e-stop, the bridge's reset), among its servers. And the other
    way round: every topic (but health and liveliness, which every service has) that the
    contract says such a service publishes or reads is one of its ports."""
    shells = shells_with_ports()
    assert set(shells) >= {"sim", "bridge", "camera", "perception", "policy", "safety", "monitor"}
    commands = {command.name for command in COMMANDS}
    for name, ports in shells.items():
        assert name in commands, name
        served = {p for p in ports.inputs.values() if contract.topic(p).queryable}
        publishes = set(ports.outputs.values()) | served
        reads = set(ports.inputs.values()) - served
        own = [t for t in contract.TOPICS if "service" not in t.placeholders]
        assert {t.path for t in own if name in t.publishers} == publishes, name
        assert {t.path for t in own if name in t.readers} == reads, name


def test_every_identity_of_the_contract_is_a_command_or_the_operator() -> None:
    """A misspelt name would give its rights to no one (and take them from the service)."""
    commands = {command.name for command in COMMANDS}
    for topic in contract.TOPICS:
        assert topic.publishers and topic.readers, topic.path
        assert set(topic.publishers) | set(topic.readers) <= commands | {contract.OPERATOR}
        if topic.message is not None:
            assert set(contract.OBSERVERS) <= set(topic.readers), topic.path
    assert set(contract.SERVICES) <= commands


def test_the_prose_publisher_is_derived_from_the_publishers() -> None:
    """`hamnet topics` shows who publishes each key, from the same tuple the rules use."""
    assert contract.topic("sim/<w>/state").publisher == "sim or bridge"
    assert contract.topic("trainer/<w>/demonstrations").publisher == "rollout (--algo dagger)"
    assert contract.topic("health/<service>/<w>").publisher == "every service, under its own name"
