"""The episodes a run has finished: returns per reward term, lengths and outcomes over a
window of the latest, the figures of every progress line and metrics row (success rate,
mean return, episode length), resumable with the run.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

import numpy as np
import torch

from hamnet.policy.rollout_record import Rollout
from hamnet.task.rewards import REWARD_NAMES
from hamnet.trainer.runners.snapshots import Arrays, Snapshot


class EpisodeTracker:
    """Returns per reward term, lengths and outcomes of the episodes that ended."""

    def __init__(self, num_envs: int, num_terms: int, window: int = 200) -> None:
        self.returns = np.zeros((num_envs, num_terms))
        self.lengths = np.zeros(num_envs, dtype=np.int64)
        self.finished: deque[tuple[np.ndarray, int, bool]] = deque(maxlen=window)
        """The last `window` episodes: (returns (R,), length, success)."""

    def add(self, rollout: Rollout, envs: torch.Tensor | None = None) -> None:
        """Fold in T steps of sim rewards and ends of the environments `envs` (B,) (None:
        all, in order)."""
        rewards, dones, success = (
            rollout.rewards.numpy(),
            rollout.dones.numpy(),
            rollout.success.numpy(),
        )
        rows = np.arange(len(self.lengths)) if envs is None else envs.numpy()  # (B,)
        for t in range(len(rewards)):
            self.returns[rows] += rewards[t]
            self.lengths[rows] += 1
            for i in np.flatnonzero(dones[t]):
                env = rows[i]
                self.finished.append(
                    (self.returns[env].copy(), int(self.lengths[env]), bool(success[t, i]))
                )
                self.returns[env], self.lengths[env] = 0.0, 0

    def snapshot(self) -> Snapshot:
        """Running returns and lengths (B, ...) and the recorded episodes, for `restore`."""
        finished, width = list(self.finished), self.returns.shape[1]  # E episodes, R terms
        arrays = {
            "returns": self.returns,
            "lengths": self.lengths,
            "finished.returns": np.array([r for r, _, _ in finished]).reshape(len(finished), width),
            "finished.lengths": np.array([n for _, n, _ in finished], dtype=np.int64),
            "finished.success": np.array([s for _, _, s in finished], dtype=bool),
        }
        return arrays, {}

    def restore(self, arrays: Arrays, meta: dict[str, Any]) -> None:
        """Continue from `snapshot`'s arrays."""
        self.returns[...], self.lengths[...] = arrays["returns"], arrays["lengths"]
        self.finished.clear()
        returns, lengths = arrays["finished.returns"], arrays["finished.lengths"]
        records = zip(returns, lengths, arrays["finished.success"])
        self.finished.extend((np.array(r), int(n), bool(s)) for r, n, s in records)

    def summary(self) -> dict[str, float]:
        """Means over the recorded episodes (NaN before the first one ends)."""
        if not self.finished:
            return {"episodes": 0, "success_rate": math.nan, "episode_length": math.nan}
        returns = np.stack([r for r, _, _ in self.finished])  # (E, R)
        out = {f"return/{name}": float(returns[:, i].mean()) for i, name in enumerate(REWARD_NAMES)}
        out["return/total"] = float(returns.sum(1).mean())
        out["episodes"] = len(self.finished)
        out["success_rate"] = float(np.mean([s for _, _, s in self.finished]))
        out["episode_length"] = float(np.mean([n for _, n, _ in self.finished]))
        return out
