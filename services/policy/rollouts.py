"""Rollout chunks of what the policy service served, without Zenoh: the hooks between the
service and `hamnet.policy.chunking`.

Consumes each served step (inputs, action, weights version) and the sim's transitions
(`hamnet.messages.transition.TransitionIn`); hands each complete RolloutChunk of T steps to `send`
(the shell's `trainer/<w>/rollout` publisher; `header.policy_version` = the oldest version
that acted, `header.step` counts the chunks sent). Steps join chunks only once the trainer is heard (its first weights
announcement or schedule): chunks acted before would only queue up at the trainer while it
starts and make every later update learn from older data.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from hamnet.messages.transition import TransitionIn
from hamnet.policy.chunking import Chunk, ChunkAssembler
from hamnet.policy.networks import PolicyInputs
from hamnet.policy.policy import Action
from hamnet.proto.trainer_pb2 import RolloutChunk
from hamnet.trainer.chunks import encode_rollout


class RolloutFeed:
    """The chunk assembler of one sim worker and the count of chunks sent."""

    def __init__(self, horizon: int, send: Callable[[RolloutChunk], None]) -> None:
        self.assembler, self.send = ChunkAssembler(horizon), send
        self.sent = 0
        """RolloutChunks sent so far (the next one's `header.step`)."""
        self.trainer_heard = False
        """A weights announcement or schedule has arrived: steps served now join chunks."""

    def served(
        self, step: int, episode_ids: np.ndarray, inputs: PolicyInputs, action: Action, version: int
    ) -> None:
        """Send the chunks completed by served step `step` (none before the trainer is heard)."""
        if self.trainer_heard:
            self._send(self.assembler.add_step(
                step, episode_ids, inputs, action.action, action.log_prob, action.values, version))  # fmt: skip

    def transition(self, t: TransitionIn) -> None:
        """Send the chunks completed by the sim's transition `t`."""
        self._send(self.assembler.add_transition(
            t.step, t.episode_ids, t.reward_terms, t.terminated, t.truncated, t.success))  # fmt: skip

    def restart(self) -> None:
        """The sim restarted: drop the partial chunk."""
        self.assembler.restart()

    def _send(self, chunks: list[Chunk]) -> None:
        for chunk in chunks:
            self.send(encode_rollout(chunk.rollout, chunk.version, self.sent))
            self.sent += 1
