"""The skills analysis on synthetic embeddings: three well-separated Gaussian blobs of z_tau,
visited by every episode in three phases (as reach, lift, translate), must come out as three
clusters with each episode's timeline following its phases; the files are written.

UMAP runs once for the module (about 10 s with numba's cache warm, N = 300).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from hamnet.evaluation.skills import NOISE, Skills, SkillsConfig, SkillSteps, find_skills
from hamnet.evaluation.skills_view import write_skills

LENGTHS = (40, 50, 60, 45, 55, 50)
"""Policy steps of the six synthetic episodes (300 steps in all)."""

CONFIG = SkillsConfig(min_cluster_share=0.1, timeline_episodes=4, view_episodes=3)
"""A blob holds a third of the steps: clusters of at least 10% keep each blob whole."""


def phases(length: int) -> np.ndarray:
    """(T,) blob per step: the first 40% in blob 0, the next 30% in 1, the rest in 2."""
    return np.repeat([0, 1, 2], [int(0.4 * length), int(0.3 * length), length - int(0.7 * length)])


def synthetic_steps(seed: int = 0) -> tuple[SkillSteps, np.ndarray]:
    """Steps of the six episodes, rows shuffled, and the (N,) blob each step came from."""
    rng = np.random.default_rng(seed)
    blob = np.concatenate([phases(length) for length in LENGTHS])  # (N,)
    centres = 10.0 * np.eye(3, 16)  # (3, Z): 10 apart per axis, noise std 0.5
    embeddings = (centres[blob] + rng.normal(0.0, 0.5, (len(blob), 16))).astype(np.float32)
    episode = np.repeat(np.arange(len(LENGTHS)), LENGTHS)
    step = np.concatenate([np.arange(length) for length in LENGTHS])
    suite = np.where(episode % 2, "sink", "procedural")
    order = rng.permutation(len(blob))  # the runner's rows need not be in step order
    steps = SkillSteps(embeddings[order], episode[order], step[order], suite[order])
    return steps, blob[order]


@pytest.fixture(scope="module")
def skills() -> tuple[Skills, np.ndarray]:
    """The skills of `synthetic_steps` and the blob of each step."""
    steps, blob = synthetic_steps()
    return find_skills(steps, CONFIG), blob


@pytest.mark.timeout(120)
def test_three_blobs_give_three_clusters(skills) -> None:
    """HDBSCAN on the UMAP projection finds exactly the three blobs: three clusters, no
    noise, and each cluster holds the steps of one blob only."""
    found, blob = skills
    assert found.projection.shape == (300, CONFIG.components)
    assert found.num_clusters == 3 and NOISE not in found.labels
    for label in range(3):
        assert len(set(blob[found.labels == label])) == 1


@pytest.mark.timeout(120)
def test_timelines_follow_each_episode_in_step_order(skills) -> None:
    """One timeline per episode, as long as the episode, its labels in step order: three
    runs of constant label in the phases' order (shuffled rows would scramble them)."""
    found, _ = skills
    timelines = found.timelines()
    assert list(timelines) == list(range(len(LENGTHS)))
    for episode, length in enumerate(LENGTHS):
        timeline = timelines[episode]
        assert len(timeline) == length
        boundaries = np.flatnonzero(np.diff(timeline)) + 1
        assert boundaries.tolist() == [int(0.4 * length), int(0.7 * length)]


@pytest.mark.timeout(120)
def test_skill_files_are_written(skills, tmp_path) -> None:
    """skills.png is a PNG, skills.rrd a non-empty Rerun recording, skills.json holds every
    episode's timeline and the cluster sizes."""
    found, _ = skills
    png, rrd, summary = write_skills(found, tmp_path, CONFIG)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert rrd.read_bytes()[:4] == b"RRF2" and rrd.stat().st_size > 1000
    data = json.loads(summary.read_text())
    assert data["clusters"] == 3 and sum(data["cluster_steps"].values()) == 300
    assert [len(e["skills"]) for e in data["episodes"]] == list(LENGTHS)
    assert data["episodes"][1]["suite"] == "sink"


def test_steps_round_trip_through_npz(tmp_path) -> None:
    """SkillSteps.save then load gives the same arrays (the analysis reruns from the file)."""
    steps, _ = synthetic_steps()
    loaded = SkillSteps.load(steps.save(tmp_path / "steps.npz"))
    for name in ("embeddings", "episode", "step", "suite"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(steps, name))


def test_steps_reject_mismatched_lengths() -> None:
    with pytest.raises(ValueError):
        SkillSteps(np.zeros((4, 2)), np.zeros(3, int), np.zeros(4, int), np.array(["sink"] * 4))
