"""Rollout chunks of what the policy service served, without Zenoh: the hooks between the
service and `hamnet.policy.chunking`.

Consumes each served step (inputs, action, weights version) and the sim's transitions
(`hamnet.messages.transition.TransitionIn`); hands each complete RolloutChunk of T steps to `send`
(the shell's `trainer/<w>/rollout` publisher; `header.policy_version` = the oldest version
that acted, `header.step` counts the chunks sent). Steps join chunks only while the trainer
is heard (its first weights announcement or schedule has come: chunks acted before would only
queue up at the trainer while it starts and make every later update learn from older data)
and a learner subscribes to the chunks (a chunk put before would reach no one). Serving never
waits for either: the steps served meanwhile are simply not learned from.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from hamnet.messages.transition import TransitionIn
from hamnet.policy.chunk_codec import encode_rollout
from hamnet.policy.chunking import Chunk, ChunkAssembler
from hamnet.policy.networks import PolicyInputs
from hamnet.policy.policy import Action
from hamnet.proto.trainer_pb2 import RolloutChunk


class RolloutFeed:
    """The chunk assembler of one sim worker and the count of chunks sent."""

    def __init__(
        self,
        horizon: int,
        send: Callable[[RolloutChunk], None],
        learner_subscribed: Callable[[], bool],
    ) -> None:
        """`learner_subscribed()`: whether a subscriber of `send`'s key is known now (the
        shell's publisher's Zenoh matching status)."""
        self.assembler, self.send = ChunkAssembler(horizon), send
        self.learner_subscribed = learner_subscribed
        self.sent = 0
        """RolloutChunks sent so far (the next one's `header.step`)."""
        self.trainer_heard = False
        """A weights announcement or schedule has arrived."""
        self.unlearned = 0
        """Steps served while the trainer was heard but no learner subscribed (not joined)."""

    def served(
        self, step: int, episode_ids: np.ndarray, inputs: PolicyInputs, action: Action, version: int
    ) -> None:
        """Send the chunks completed by served step `step` (a step joins none before the
        trainer is heard or while no learner subscribes: its chunk would stay partial)."""
        if self.trainer_heard and not self.learner_subscribed():
            self.unlearned += 1
        elif self.trainer_heard:
            self._send(
                self.assembler.add_step(
                    step,
                    episode_ids,
                    inputs,
                    action.action,
                    action.log_prob,
                    action.values,
                    version,
                )
            )

    def transition(self, t: TransitionIn) -> None:
        """Send the chunks completed by the sim's transition `t`."""
        self._send(
            self.assembler.add_transition(
                t.step, t.episode_ids, t.reward_terms, t.terminated, t.truncated, t.success
            )
        )

    def restart(self) -> None:
        """The sim restarted: drop the partial chunk."""
        self.assembler.restart()

    def _send(self, chunks: list[Chunk]) -> None:
        for chunk in chunks:
            self.send(encode_rollout(chunk.rollout, chunk.version, self.sent))
            self.sent += 1
