"""Which rollout workers an iteration of the streamed trainer waits for, and what each one
delivered: the trainer's view of its workers, without Zenoh.

Consumes liveliness changes (`token`: a service's `alive/<service>/<w>` token appeared or went
away), arrivals (`arrived`: a fitting chunk of worker `w`, sent by service `source`) and the
workers whose chunks are queued (`takes`); produces the workers to learn from, in the order of
their environments, their rows in the learner's batch (`rows`) and per-worker figures
(`metrics`, `progress`).

The first iteration waits for one chunk from each of `workers` workers: they get a slot each
(sorted by id), worker-slot s's environments are the learner's rows [s E, (s + 1) E), so the
reward scaler and episode tracker follow every environment across iterations. Afterwards an
iteration waits for the slot workers whose token is present when it begins. One whose token
goes away (it stopped, or its link was cut and Zenoh's lease ran out), or that sends nothing
for `timeout_s` (hung), drops out of that iteration: what it collected for it is lost, counted
in `dropped_partial_rollouts`, and the others' chunks are learned from. It is waited for again
from the first iteration that begins while its token is back. A fitting chunk of a slot worker
that is already queued is always taken, waited for or not. With `drop_out` False (several
learner ranks, whose batches must keep their shapes) every slot worker is always waited for.
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from dataclasses import dataclass

import torch
from torch import Tensor

log = logging.getLogger(__name__)


@dataclass
class WorkerFigures:
    """What one slot worker delivered."""

    slot: int
    """Its place among the learner's environments."""
    dropped_partial: int = 0
    """Iterations it dropped out of before its chunk arrived."""
    env_steps_per_s: float = math.nan
    """Env steps of its latest chunk over the time it took to arrive (since the iteration's
    announcement or its previous chunk, whichever is later), steps/s."""
    policy_lag: float = math.nan
    """Versions between the weights that acted in its latest chunk learned from and the learner's."""
    taken: bool = False
    """Whether the current iteration learns from it."""


class Roster:
    """The slot workers, which of them are alive, and whom the current iteration waits for."""

    def __init__(
        self, workers: int, envs_per_worker: int, drop_out: bool = True, timeout_s: float = math.inf
    ) -> None:
        if workers < 1 or envs_per_worker < 1 or timeout_s <= 0:
            raise ValueError("workers and envs_per_worker must be >= 1, timeout_s > 0")
        self.workers, self.envs_per_worker = workers, envs_per_worker
        self.drop_out, self.timeout_s = drop_out, timeout_s
        self.figures: dict[str, WorkerFigures] = {}
        """Slot workers by id (empty until the first iteration has its workers)."""
        self.sources: dict[str, str] = {}
        """Worker id -> the identity (`service/worker`) that sends its chunks."""
        self.received: Counter[str] = Counter()
        """Fitting chunks received per worker id (learned from or dropped as stale)."""
        self.alive: set[str] = set()
        """Identities whose liveliness token is present."""
        self.waiting: set[str] = set()
        """Slot workers the current iteration still waits for."""
        self.began_s = 0.0
        self.dropped_partial = 0
        """Partial rollouts discarded: (worker, iteration) pairs it dropped out of."""

    def is_alive(self, worker: str) -> bool:
        """Whether the token of the service that sends `worker`'s chunks is present."""
        return self.sources.get(worker, f"rollout/{worker}") in self.alive

    def token(self, identity: str, alive: bool) -> None:
        """The token of `identity` (`service/worker`) appeared (`alive`) or went away; a
        change of a worker's is logged."""
        if alive == (identity in self.alive):
            return
        (self.alive.add if alive else self.alive.discard)(identity)
        worker = next((w for w, s in self.sources.items() if s == identity), None)
        if worker is None and identity.startswith("rollout/"):
            worker = identity.split("/", 1)[1]
        if worker is not None:
            log.info("rollout worker %s (%s) is %s", worker, identity, "up" if alive else "gone")

    def arrived(self, worker: str, source: str) -> None:
        """A fitting chunk of `worker`, sent by the service `source`, was queued."""
        self.sources[worker], self.received[worker] = source, self.received[worker] + 1

    def begin(self, now_s: float) -> None:
        """A new iteration (at `now_s`, monotonic s): wait for the slot workers alive now."""
        self.began_s = now_s
        self.waiting = {w for w in self.figures if not self.drop_out or self.is_alive(w)}
        for figures in self.figures.values():
            figures.taken = False

    def takes(self, ready: set[str], now_s: float) -> list[str] | None:
        """The workers to take one queued chunk each from now, in slot order, or None while
        the iteration waits; `ready`: workers with a fitting chunk queued."""
        if not self.figures:
            if len(ready) < self.workers:
                return None
            for slot, worker in enumerate(sorted(ready)[: self.workers]):
                self.figures[worker] = WorkerFigures(slot)
            return list(self.figures)
        for worker in sorted(self.waiting - ready) if self.drop_out else ():
            if not self.is_alive(worker):
                self._drop(worker, "its token is gone")
            elif now_s - self.began_s >= self.timeout_s:
                self._drop(worker, f"it sent nothing for {self.timeout_s:.0f} s")
        taken = sorted(ready & set(self.figures), key=lambda w: self.figures[w].slot)
        if self.waiting - ready:
            return None
        if not taken:  # everyone it waited for dropped out: wait for whoever is alive now
            self.begin(now_s)
            return None
        return taken

    def _drop(self, worker: str, why: str) -> None:
        """`worker` drops out of the iteration: what it collected for it is lost."""
        log.warning(
            "rollout worker %s dropped out of this iteration (%s): its partial rollout "
            "is discarded, the others' are learned from",
            worker,
            why,
        )
        self.waiting.discard(worker)
        self.figures[worker].dropped_partial += 1
        self.dropped_partial += 1

    def took(self, worker: str, policy_lag: int, env_steps_per_s: float) -> None:
        """The iteration learns from `worker`'s chunk acted `policy_lag` versions ago."""
        figures = self.figures[worker]
        figures.taken, figures.policy_lag = True, policy_lag
        figures.env_steps_per_s = env_steps_per_s

    def rows(self, taken: list[str]) -> Tensor | None:
        """The learner's environment rows of `taken` workers' chunks side by side (B_taken,);
        None when every slot worker is taken (all rows, in order)."""
        if len(taken) == self.workers:
            return None
        size = self.envs_per_worker
        return torch.cat(
            [
                torch.arange(self.figures[w].slot * size, (self.figures[w].slot + 1) * size)
                for w in taken
            ]
        )

    def metrics(self) -> dict[str, float]:
        """`workers_alive`, `dropped_partial_rollouts` and `workers/<w>/...` of every slot
        worker (rate and lag only for those the iteration learns from)."""
        out: dict[str, float] = {
            "workers_alive": sum(self.is_alive(w) for w in self.figures),
            "dropped_partial_rollouts": self.dropped_partial,
        }
        for worker, figures in self.figures.items():
            prefix = f"workers/{worker}/"
            out[prefix + "alive"] = int(self.is_alive(worker))
            out[prefix + "chunks"] = self.received[worker]
            out[prefix + "dropped_partial_rollouts"] = figures.dropped_partial
            if figures.taken:
                out[prefix + "env_steps_per_s"] = figures.env_steps_per_s
                out[prefix + "policy_lag"] = figures.policy_lag
        return out
