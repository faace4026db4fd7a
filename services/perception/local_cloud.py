"""The local cloud of objects that move a little each step, ranked over a shortlist while the
shortlist provably holds it.

Every step `Perception.step` needs the P scene-pool points nearest the posed keypoints (the
paper's local cloud). Ranking all S pool points against K keypoints
(`cloud_ops.local_cloud`) was 15 ms of a 39 ms perception step of 64 environments (S 4096,
K 64, one thread), every step, though between two steps an object moves millimetres or not
at all. So a full ranking also keeps, per environment, a shortlist: its M nearest points,
the keypoints it was ranked against and `bound`, the distance of the nearest point left
out. A point's distance to its nearest keypoint changes by at most the largest keypoint
displacement since (triangle inequality), so while the P-th nearest shortlisted point lies
nearer than `bound` less that displacement, no point left out can be among the P nearest,
and ranking the shortlist alone gives the full ranking's points. Environments where that
does not hold are ranked in full again, which refreshes their shortlist.
"""

from __future__ import annotations

import torch
from torch import Tensor

from hamnet.perception.cloud_ops import gather, nearest_points, nearest_squared_distances

MARGIN = 1e-5
"""Metres the shortlist must hold by beyond the bound: the squared distances come from a
matrix product (`cloud_ops.squared_distances`), which rounds them by about 1e-7 m^2, a
micrometre at the local cloud's few centimetres."""


class LocalClouds:
    """The local clouds of B environments with a shortlist each (`shortlist` points; 0:
    every step ranks the whole pool)."""

    def __init__(
        self, num_envs: int, num_points: int, shortlist: int, device: torch.device
    ) -> None:
        self.num_points, self.shortlist = num_points, shortlist
        self.candidates = torch.zeros(num_envs, shortlist, dtype=torch.long, device=device)
        """(B, M) pool indices of each environment's shortlist."""
        self.ranked_at: Tensor | None = None
        """(B, K, 3) the keypoints each shortlist was ranked against (K known at the first
        ranking)."""
        self.bound = torch.full((num_envs,), -torch.inf, dtype=torch.float64, device=device)
        """(B,) distance of the nearest pool point left out of the shortlist, m; -inf: no
        shortlist (the next step ranks the whole pool)."""
        self.full_rankings = 0
        """Environment steps ranked over the whole pool so far (the rest used a shortlist)."""

    def forget(self, env_ids: Tensor | None = None) -> None:
        """Drop the shortlists of `env_ids` (None: all): a new scene pool, or a restored
        perception whose shortlists were not saved."""
        self.bound[slice(None) if env_ids is None else env_ids] = -torch.inf

    def nearest(self, pool: Tensor, keypoints: Tensor, env_ids: Tensor | None = None) -> Tensor:
        """(B', P) indices of the pool points (B', S, 3) nearest the keypoints (B', K, 3),
        nearest first, as `cloud_ops.local_cloud` ranks them.

        Args:
            pool: the scene pools of the environments `env_ids` (None: all B), m.
            keypoints: their object keypoints in the current pose, m.
            env_ids: (B',) which environments the rows are.
        """
        rows = torch.arange(len(self.bound), device=pool.device)
        rows = rows if env_ids is None else rows[env_ids]
        if self.shortlist == 0 or self.shortlist >= pool.shape[1]:
            return self._rank(pool, keypoints, rows, remember=False)
        if self.ranked_at is None:
            self.ranked_at = keypoints.new_zeros(len(self.bound), *keypoints.shape[1:])
        candidates = self.candidates[rows]
        distance = nearest_squared_distances(gather(pool, candidates), keypoints)  # (B', M)
        value, order = distance.topk(self.num_points, dim=1, largest=False, sorted=True)
        index = candidates.gather(1, order)
        moved = (keypoints - self.ranked_at[rows]).norm(dim=-1).amax(-1)  # (B',)
        farthest = value[:, -1].clamp_min(0.0).sqrt()
        stale = torch.nonzero(~(farthest + MARGIN < self.bound[rows] - moved)).flatten()
        if len(stale):
            index[stale] = self._rank(pool[stale], keypoints[stale], rows[stale], remember=True)
        return index

    def _rank(self, pool: Tensor, keypoints: Tensor, rows: Tensor, remember: bool) -> Tensor:
        """(R, P) the whole pools ranked; with `remember`, the shortlists of `rows` refreshed."""
        self.full_rankings += len(rows)
        if not remember:
            return nearest_points(pool, keypoints, self.num_points)
        distance = nearest_squared_distances(pool, keypoints)  # (R, S)
        value, index = distance.topk(self.shortlist + 1, dim=1, largest=False, sorted=True)
        self.candidates[rows] = index[:, : self.shortlist]
        self.bound[rows] = value[:, self.shortlist].clamp_min(0.0).sqrt().to(self.bound.dtype)
        self.ranked_at[rows] = keypoints
        return index[:, : self.num_points]
