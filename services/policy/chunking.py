"""Rollout chunks from the service chain: what the policy service served, step by step,
joined with the sim's transitions by step and episode ids (no Zenoh).

The policy service (via `hamnet.policy.rollouts`) serves step k of B environments (inputs, raw
action, log-probability, values per reward term, weights version) and later receives the
sim's transition k (`sim/<w>/transition`: the outcome of the command answering state k,
with the episode ids before any reset). A chunk of T steps k..k+T-1 is complete when those
T steps and their T transitions are in, with the same episode ids, and step k+T has been
served (its values are `next_values`). Chunks do not overlap: step k+T starts the next one.

A gap (a step the policy never served, a transition that did not come within `window`
served steps, episode ids or batch sizes that disagree) drops the partial chunk, counted
by reason, and the next chunk starts after the gap; nothing older than the window is kept.
A new weights version in the middle of a chunk is fine: the chunk carries the oldest
version that acted, so the trainer's policy lag is never understated.

Timeouts: the chain never sees the final state of a truncated episode (the sim resets it
in the same step and perception only sees the new episode), so a truncated episode is
bootstrapped with V(its last acted state), the values of that step, where a rollout worker
uses V(final state). That is one step early: it overestimates the return by about the last
step's reward (gamma V(s_T-1) against r_T-1 + gamma V(s_T)), a small bias at timeouts of
100-300 steps. Shapes: T steps, B environments, A action, R reward terms.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from hamnet.policy.networks import PolicyInputs
from hamnet.policy.rollout_record import Rollout, cat_rows
from hamnet.runtime.trees import zip_trees

DROP_REASONS = ("missing_step", "missing_transition", "episode_mismatch", "batch_size", "restart")
"""Why a partial chunk was dropped."""


@dataclass(frozen=True)
class Served:
    """What the policy computed when it served one step."""

    episode_ids: np.ndarray
    """(B,) int64."""
    inputs: PolicyInputs
    """(B, ...) the inputs it acted on, on the CPU."""
    action: Tensor
    """(B, A) raw action."""
    log_prob: Tensor
    """(B,)."""
    values: Tensor
    """(B, R)."""
    version: int
    """The weights that acted."""


@dataclass(frozen=True)
class Outcome:
    """The sim's transition of one step."""

    episode_ids: np.ndarray
    """(B,) int64, before any reset."""
    reward_terms: Tensor
    """(B, R) float32."""
    terminated: Tensor
    """(B,) bool."""
    truncated: Tensor
    """(B,) bool."""
    success: Tensor
    """(B,) bool."""


@dataclass(frozen=True)
class Chunk:
    """A complete chunk, ready for `hamnet.trainer.storage.rollout_chunks.encode_rollout`."""

    rollout: Rollout
    version: int
    """The oldest weights version that acted in it."""
    first_step: int
    """k, the step of its first row."""


def _cpu_copy(tree: object) -> object:
    """A CPU copy of every tensor of a tree (the assembler keeps them across steps)."""
    return zip_trees([tree], lambda leaves: leaves[0].detach().to("cpu", copy=True))


class ChunkAssembler:
    """Chunks of `horizon` steps from served steps and transitions, in any arrival order."""

    def __init__(self, horizon: int, window: int | None = None) -> None:
        """
        Args:
            horizon: T, steps per chunk.
            window: served steps after which a missing transition counts as lost
                (default 2 T); it bounds what is held to about T + window steps.
        """
        self.horizon = horizon
        self.window = 2 * horizon if window is None else window
        if horizon < 1 or self.window < 1:
            raise ValueError(f"horizon and window must be >= 1, got {horizon}, {self.window}")
        self.steps: dict[int, Served] = {}
        self.outcomes: dict[int, Outcome] = {}
        self.start: int | None = None
        """k, the first step of the chunk being assembled (None before any step)."""
        self.newest: int | None = None
        """The last step served."""
        self.dropped = dict.fromkeys(DROP_REASONS, 0)
        """Partial chunks dropped, by reason."""
        self.ignored = 0
        """Steps and transitions that arrived too late to join any chunk."""

    def add_step(
        self,
        step: int,
        episode_ids: np.ndarray,
        inputs: PolicyInputs,
        action: Tensor,
        log_prob: Tensor,
        values: Tensor,
        version: int,
    ) -> list[Chunk]:
        """Record step `step` as served (steps come in increasing order); returns the chunks
        it completes.

        Args:
            episode_ids: (B,) int64; inputs: (B, ...); action: (B, A); log_prob: (B,);
            values: (B, R); version: of the weights that acted.
        """
        if self.newest is not None and step <= self.newest:
            self.ignored += 1
            return []
        self.steps[step] = Served(
            np.asarray(episode_ids, np.int64).copy(),
            _cpu_copy(inputs),
            *(_cpu_copy(x).float() for x in (action, log_prob, values)),
            version,
        )
        self.newest = step
        if self.start is None:
            self.start = step
        return self._advance()

    def add_transition(
        self,
        step: int,
        episode_ids: np.ndarray,
        reward_terms: np.ndarray | Tensor,
        terminated: np.ndarray | Tensor,
        truncated: np.ndarray | Tensor,
        success: np.ndarray | Tensor,
    ) -> list[Chunk]:
        """Record the sim's transition `step` (any order); returns the chunks it completes.

        Args:
            episode_ids: (B,) int64; reward_terms: (B, R); the flags (B,) bool.
        """
        if self.start is not None and step < self.start:
            self.ignored += 1
            return []
        flag = lambda x: torch.as_tensor(np.asarray(x, bool))
        self.outcomes[step] = Outcome(
            np.asarray(episode_ids, np.int64).copy(),
            torch.as_tensor(np.asarray(reward_terms, np.float32)),
            flag(terminated),
            flag(truncated),
            flag(success),
        )
        while len(self.outcomes) > self.window + self.horizon:  # none served to join them
            del self.outcomes[min(self.outcomes)]
            self.ignored += 1
        return self._advance()

    def _advance(self) -> list[Chunk]:
        """Emit every chunk now complete and drop every one now known to be broken."""
        chunks: list[Chunk] = []
        while self.start is not None:
            verdict = self._check(self.start)
            if verdict is None:
                return chunks
            if verdict is True:
                chunks.append(self._emit(self.start))
            else:
                self._drop(*verdict)
        return chunks

    def _check(self, start: int) -> bool | tuple[str, int] | None:
        """True: the chunk at `start` is complete; (reason, step): broken at that step;
        None: still waiting."""
        batch = len(self.steps[start].episode_ids)
        for k in range(start, start + self.horizon + 1):
            served = self.steps.get(k)
            if served is None:
                return ("missing_step", k) if self.newest > k else None
            if len(served.episode_ids) != batch:
                return "batch_size", k - 1
            if k == start + self.horizon:
                return True
            outcome = self.outcomes.get(k)
            if outcome is None:
                return ("missing_transition", k) if self.newest - k >= self.window else None
            if not np.array_equal(outcome.episode_ids, served.episode_ids):
                return "episode_mismatch", k
        raise AssertionError("unreachable")

    def restart(self) -> None:
        """The sim restarted and counts its steps from 0 again: the partial chunk (if any)
        is dropped and counted, and the next chunk starts at the next step served."""
        if self.steps or self.outcomes:
            self.dropped["restart"] += 1
        self.steps.clear()
        self.outcomes.clear()
        self.start = self.newest = None

    def _drop(self, reason: str, through: int) -> None:
        """Count a partial chunk as dropped and forget everything up to step `through`."""
        self.dropped[reason] += 1
        self._forget(through)

    def _forget(self, through: int) -> None:
        """Forget steps and transitions up to `through`; the next chunk starts after it."""
        self.steps = {k: v for k, v in self.steps.items() if k > through}
        self.outcomes = {k: v for k, v in self.outcomes.items() if k > through}
        self.start = min(self.steps, default=None)

    def _emit(self, start: int) -> Chunk:
        """The complete chunk at `start`; step start + T starts the next one."""
        steps = [self.steps[k] for k in range(start, start + self.horizon)]
        outcomes = [self.outcomes[k] for k in range(start, start + self.horizon)]
        stack = lambda items, name: torch.stack([getattr(x, name) for x in items])
        values = stack(steps, "values")  # (T, B, R)
        terminated, truncated = stack(outcomes, "terminated"), stack(outcomes, "truncated")
        timed_out = (truncated & ~terminated).unsqueeze(-1)  # (T, B, 1)
        rollout = Rollout(
            inputs=cat_rows([s.inputs for s in steps]),
            actions=stack(steps, "action"),  # (T, B, A)
            log_prob=stack(steps, "log_prob"),  # (T, B)
            values=values,
            rewards=stack(outcomes, "reward_terms"),  # (T, B, R)
            final_values=values * timed_out,  # V(last acted state) of a timeout, else 0
            dones=terminated | truncated,  # (T, B)
            next_values=self.steps[start + self.horizon].values,  # (B, R)
            success=stack(outcomes, "success"),  # (T, B)
        )
        chunk = Chunk(rollout, min(s.version for s in steps), start)
        self._forget(start + self.horizon - 1)
        return chunk
