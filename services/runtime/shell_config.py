"""The config blocks every service loop shares, flattened into each service's own config
(`Annotated[ReportConfig, Flattened]`), so `--report-period-s`, `--device`, `--threads` and
`--seed` mean one thing, with one docstring, in every `hamnet <service> --help`. It holds
no Zenoh, so a core's config (e.g. the safety supervisor's) can nest the blocks too.
"""

from __future__ import annotations

from dataclasses import dataclass

import tyro

Flattened = tyro.conf.OmitArgPrefixes
"""Annotate a nested config field with this to expose its options without a prefix."""


@dataclass(frozen=True)
class ReportConfig:
    """How often a loop says how it is doing (`hamnet.runtime.loop_report`)."""

    report_period_s: float = 10.0
    """Seconds between rate lines in the log."""


@dataclass(frozen=True)
class ComputeConfig:
    """Where a service that runs a network computes (`hamnet.runtime.compute`)."""

    device: str = "cpu"
    """torch device of the network: cpu, cuda, cuda:1, ..."""
    threads: int = 1
    """torch CPU threads (1: the services of a stack share the machine's cores)."""
    seed: int = 0
    """Seed of the service's random draws (sampling noise, cloud sampling)."""
