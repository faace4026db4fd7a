"""Command lines of a stack's processes: flags as tyro reads them, forwarded options."""

from __future__ import annotations

from pathlib import Path

from hamnet.launcher.argv import flags, forwarded, service_argv
from hamnet.launcher.stack import ServiceSpec
from hamnet.runtime.cli import CommonConfig, LogConfig
from hamnet.runtime.transport import TransportConfig


def test_flags_spell_values_as_tyro_reads_them() -> None:
    options = {
        "num-envs": 4,
        "render": True,
        "headless": False,
        "seeds": (1, 2),
        "lr": 0.5,
        "weights": None,
        "connect": (),
    }
    assert flags(options) == [
        "--num-envs",
        "4",
        "--render",
        "--no-headless",
        "--seeds",
        "1",
        "2",
        "--lr",
        "0.5",
        "--weights",
        "None",
        "--connect",
    ]


def test_only_non_default_transport_and_logging_options_are_forwarded(tmp_path: Path) -> None:
    assert forwarded(CommonConfig()) == {}
    zenoh_config = tmp_path / "z.json5"  # a transport refuses a config file that is not there
    zenoh_config.write_text("{}")
    common = CommonConfig(
        worker="7",
        transport=TransportConfig(
            namespace="ns",
            rendezvous="tcp/127.0.0.1:9000",
            connect=("tcp/10.0.0.1:7447",),
            zenoh_config=zenoh_config,
            shared_memory=False,
        ),
        logging=LogConfig(log_format="json"),
    )
    assert forwarded(common) == {
        "rendezvous": "tcp/127.0.0.1:9000",
        "connect": ("tcp/10.0.0.1:7447",),
        "zenoh-config": str(zenoh_config),
        "shared-memory": False,
        "log-format": "json",
    }


def test_service_argv_puts_namespace_first_and_worker_last() -> None:
    spec = ServiceSpec(
        "record", args={"output": "runs/<namespace>/x.mcap", "keys": ("<namespace>/a",)}
    )
    argv = service_argv(spec, "1", "demo", {"rendezvous": "tcp/127.0.0.1:9000"})
    assert argv == [
        "record",
        "--namespace",
        "demo",
        "--rendezvous",
        "tcp/127.0.0.1:9000",
        "--output",
        "runs/demo/x.mcap",
        "--keys",
        "demo/a",
        "--worker",
        "1",
    ]


def test_service_args_win_over_forwarded_options() -> None:
    spec = ServiceSpec("echo", args={"log_level": "debug"})
    argv = service_argv(spec, "0", "demo", {"log-level": "warning", "rendezvous": "r"})
    assert argv == [
        "echo",
        "--namespace",
        "demo",
        "--rendezvous",
        "r",
        "--log_level",
        "debug",
        "--worker",
        "0",
    ]


def test_a_services_remap_becomes_remap_flags_with_the_namespace_filled_in() -> None:
    spec = ServiceSpec("policy", remap={"state": "hamnet/<namespace>-replay/sim/0/state",
                                        "tokens": "perception/1/tokens"})  # fmt: skip
    argv = service_argv(spec, "0", "demo", {})
    assert argv == ["policy", "--namespace", "demo", "--remap", "state=hamnet/demo-replay/sim/0/state",
                    "tokens=perception/1/tokens", "--worker", "0"]  # fmt: skip
