"""Hot reload of the policy service's weights, without Zenoh.

Consumes WeightsAnnouncements and the trainer's Schedule counter; holds the serving network
and its version. An announcement is checked (sha256, metadata, architecture, config, tensor
shapes, finiteness: `hamnet.policy.weights`) and loaded into a second copy of the network,
which replaces the serving one between two batches; a bad one is logged as an error and the
old weights keep serving. Every batch comes from one version and carries it. The log std
follows the schedule's `env_transitions`; until one arrives, the weights' own log std serves.
"""

from __future__ import annotations

import logging

import torch

from hamnet.policy.policy import Policy
from hamnet.policy.registry import build
from hamnet.policy.weights import WeightsError, from_announcement, load_into
from hamnet.proto.trainer_pb2 import WeightsAnnouncement

log = logging.getLogger(__name__)


class HotReload:
    """The serving network, its version, and the spare copy the next weights load into."""

    def __init__(self, policy: Policy, version: int, device: torch.device) -> None:
        self.policy, self.version, self.device = policy.to(device).eval(), version, device
        self.spare: Policy | None = None
        """The second copy that the next weights are loaded into."""
        self.env_transitions: int | None = None
        """The trainer's counter (hamnet.runtime.counter), None before its first Schedule."""

    def schedule(self, env_transitions: int) -> None:
        """Follow the trainer's Schedule: the log std at its `env_transitions`."""
        self.env_transitions = env_transitions
        self.policy.set_env_transitions(env_transitions)

    def announce(self, message: WeightsAnnouncement) -> bool:
        """Serve the announced weights from the next batch on; False when they were
        rejected (logged; the old ones keep serving). A repeat of the served version is
        ignored."""
        version = message.version
        if version == self.version and version > 0:
            return True  # a repeat of what is served (a trainer's last announcement, an answer to a late worker)
        try:
            self._load_spare(message)
        except WeightsError as error:
            log.error(
                "rejected weights version %d: %s; still serving version %d",
                version,
                error,
                self.version,
            )
            return False
        self.policy, self.spare, self.version = self.spare, self.policy, version
        if self.env_transitions is not None:
            self.policy.set_env_transitions(self.env_transitions)
        log.info("serving weights version %d", version)
        return True

    def _load_spare(self, message: WeightsAnnouncement) -> None:
        """Check an announcement and load it into the spare copy (WeightsError if unfit)."""
        if message.version <= self.version:
            raise WeightsError(f"version {message.version} is not newer")
        weights = from_announcement(message)
        if self.spare is None:
            self.spare = build(self.policy.architecture, self.policy.config).to(self.device).eval()
        load_into(self.spare, weights)
