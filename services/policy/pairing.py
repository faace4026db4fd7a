"""Pairs each robot state with the perception tokens of the same step, without Zenoh.

States and tokens of one sim worker arrive in any order. A pair is complete when both
halves of step k are here; it is handed out at once, and every half of an older step still
waiting is dropped (its partner will never matter again: the sim has moved on). At most
`capacity` steps wait; beyond that the oldest is dropped, so a state whose tokens never come
blocks nothing. Drops are counted under a reason.
"""

from __future__ import annotations

from collections import Counter
from typing import Generic, TypeVar

S = TypeVar("S")
T = TypeVar("T")


class Pairing(Generic[S, T]):
    """Bounded buffer of half pairs keyed by step."""

    def __init__(self, capacity: int) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        self.capacity = capacity
        self.states: dict[int, S] = {}
        self.tokens: dict[int, T] = {}
        self.dropped: Counter[str] = Counter()
        """Dropped halves by reason: superseded (an older step than a completed pair),
        overflow (more than `capacity` steps waiting), or what `clear` was given."""

    def add_state(self, step: int, state: S) -> tuple[S, T] | None:
        """Add the state of `step`; returns the pair when its tokens are here."""
        self.states[step] = state
        return self._complete(step)

    def add_tokens(self, step: int, tokens: T) -> tuple[S, T] | None:
        """Add the tokens of `step`; returns the pair when its state is here."""
        self.tokens[step] = tokens
        return self._complete(step)

    def clear(self, reason: str) -> None:
        """Drop every waiting half, counted under `reason` (the producer restarted: none of
        them will ever be paired)."""
        for halves in (self.states, self.tokens):
            self.dropped[reason] += len(halves)
            halves.clear()

    @property
    def waiting(self) -> int:
        """Steps with one half waiting."""
        return len(set(self.states) | set(self.tokens))

    def _complete(self, step: int) -> tuple[S, T] | None:
        if step in self.states and step in self.tokens:
            pair = self.states.pop(step), self.tokens.pop(step)
            self._drop_before(step, "superseded")
            return pair
        while self.waiting > self.capacity:
            self._drop_before(min(set(self.states) | set(self.tokens)) + 1, "overflow")
        return None

    def _drop_before(self, step: int, reason: str) -> None:
        for halves in (self.states, self.tokens):
            for old in [k for k in halves if k < step]:
                del halves[old]
                self.dropped[reason] += 1
