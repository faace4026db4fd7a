"""The skills HAMnet's modulation embedding falls into (paper Sec. sec:qualitative-analysis).

The runner collects z_tau, the modulation embedding that decides every module's weight
(`modulation_embedding`), at each policy step of many episodes into `SkillSteps`.
`find_skills` projects them with UMAP and clusters the projection with HDBSCAN, as the paper
does with 25,000 episodes; each cluster is a skill (reach, lift, reorient, translate, drop,
...), and an episode's timeline is the skill it used at each step (paper Fig.
inter-phase-route). Produces `Skills`: the projection, a label per step (-1 for steps no
cluster holds) and the timelines; `skills_view` draws and records them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from hamnet.policy.networks import HAMNet, PolicyInputs
from hamnet.policy.policy import Policy

NOISE = -1
"""HDBSCAN's label of a step that belongs to no cluster (black in the paper's Fig. qual-umap)."""


@dataclass(frozen=True)
class SkillsConfig:
    """How the embeddings are projected, clustered and shown."""

    components: int = 3
    """Dimensions of the UMAP projection: the paper projects z_tau "into a three-dimensional
    manifold" (Sec. sec:qualitative-analysis); 2 draws a flat map."""
    min_cluster_share: float = 0.01
    """Smallest share of all steps that HDBSCAN calls a cluster. The paper's Fig. qual-umap
    shows about ten skills (a tenth of the steps each on average); 1% keeps skills ten times
    rarer than that, where HDBSCAN's own default (5 steps) would call a handful of steps
    among the millions of the paper's 25,000 episodes a skill."""
    seed: int = 0
    """UMAP's random state: the same steps give the same projection."""
    timeline_episodes: int = 8
    """Episodes whose timelines the PNG draws (the paper's Fig. inter-phase-route shows two)."""
    view_episodes: int = 100
    """Episodes the Rerun view logs one by one (the projection shows every step): the viewer
    slows down with thousands of entities, and skills.json keeps every timeline."""

    def __post_init__(self) -> None:
        if self.components not in (2, 3):
            raise ValueError("components must be 2 or 3 (a map a person can look at)")
        if not 0.0 < self.min_cluster_share < 1.0:
            raise ValueError("min_cluster_share must lie in (0, 1)")
        if min(self.timeline_episodes, self.view_episodes) < 0:
            raise ValueError("timeline_episodes and view_episodes must be >= 0")


@dataclass(frozen=True)
class SkillSteps:
    """Modulation embeddings of N policy steps and where each one comes from."""

    embeddings: np.ndarray
    """(N, Z) float32 z_tau per step."""
    episode: np.ndarray
    """(N,) int64 episode id: the index of the episode's `EpisodeRecord` in the run, so a
    cluster leads back to its suite, object, pose pair and robot initialisation."""
    step: np.ndarray
    """(N,) int64 policy step within its episode, from 0."""
    suite: np.ndarray
    """(N,) str suite of the step's episode (`records.SUITES`)."""

    def __post_init__(self) -> None:
        n = len(self.embeddings)
        if self.embeddings.ndim != 2:
            raise ValueError(f"embeddings must be (N, Z), got {self.embeddings.shape}")
        if any(array.shape != (n,) for array in (self.episode, self.step, self.suite)):
            raise ValueError("episode, step and suite must be (N,) like the embeddings")

    def episode_suites(self) -> dict[int, str]:
        """Episode id -> its suite, episodes in ascending order."""
        pairs = dict(zip(self.episode.tolist(), self.suite.tolist()))
        return dict(sorted(pairs.items()))

    def save(self, path: Path) -> Path:
        """Write the steps to `path` (.npz), so the analysis can be rerun without playing."""
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, **{name: getattr(self, name) for name in _STEP_FIELDS})
        return path

    @classmethod
    def load(cls, path: Path) -> SkillSteps:
        """The steps `save` wrote to `path`."""
        with np.load(path) as data:
            return cls(**{name: data[name] for name in _STEP_FIELDS})


_STEP_FIELDS = ("embeddings", "episode", "step", "suite")


def modulation_embedding(policy: Policy, inputs: PolicyInputs) -> Tensor:
    """z_tau of HAMnet for one batch, without gradients: (B, Z).

    Reads the network's `value_features` (the same modulation network and, for the student,
    the same GRU step that `Policy.act` runs), so it costs a second forward pass of what
    precedes the base networks. For a recurrent student, pass the inputs given to `act`
    (their `memory` the state before the step).

    Args:
        policy: a HAMnet policy (hamnet, hamnet-paper, hamnet-nogate, hamnet-envcode,
            student); the baselines have no modulation embedding.
        inputs: one batch of B policy inputs, raw (the policy standardises them).
    Returns:
        (B, Z) z_tau, Z = `ModelConfig.modulation_hidden[-1]`.
    """
    if not isinstance(policy.network, HAMNet):
        raise TypeError(f"{policy.architecture!r} has no modulation embedding (not HAMnet)")
    with torch.no_grad():
        _, z = policy.value_features(inputs)  # (B, E + S [+ H]), (B, Z)
    return z


@dataclass(frozen=True)
class Skills:
    """The projection and clustering of `SkillSteps`."""

    steps: SkillSteps
    """What was projected."""
    projection: np.ndarray
    """(N, C) UMAP coordinates per step, C = `SkillsConfig.components`."""
    labels: np.ndarray
    """(N,) int cluster (skill) per step, `NOISE` for steps no cluster holds."""

    @property
    def num_clusters(self) -> int:
        """Clusters found (noise not counted)."""
        return len(set(self.labels.tolist()) - {NOISE})

    def timelines(self) -> dict[int, np.ndarray]:
        """Episode id -> (T,) label per step in step order, episodes in ascending order."""
        order = np.lexsort((self.steps.step, self.steps.episode))  # by episode, then step
        episodes, starts = np.unique(self.steps.episode[order], return_index=True)
        runs = np.split(self.labels[order], starts[1:])
        return dict(zip(episodes.tolist(), runs))


def find_skills(steps: SkillSteps, config: SkillsConfig | None = None) -> Skills:
    """Project `steps` with UMAP and cluster the projection with HDBSCAN.

    Args:
        steps: N steps' embeddings (N, Z), N above UMAP's n_neighbors (umap-learn's default 15).
        config: projection and clustering settings (defaults: `SkillsConfig()`).
    Returns:
        `Skills` with the (N, C) projection and (N,) labels.
    """
    config = config or SkillsConfig()
    import umap  # numba compiles on import: seconds, paid only by the skills analysis
    from sklearn.cluster import HDBSCAN

    # A fixed random_state makes UMAP single-threaded; n_jobs=1 says so instead of warning.
    reducer = umap.UMAP(n_components=config.components, random_state=config.seed, n_jobs=1)
    projection = reducer.fit_transform(steps.embeddings)  # (N, C)
    smallest = max(2, round(config.min_cluster_share * len(projection)))
    labels = HDBSCAN(min_cluster_size=smallest, copy=True).fit_predict(projection)  # (N,)
    return Skills(steps, np.asarray(projection, dtype=np.float32), labels.astype(np.int64))
