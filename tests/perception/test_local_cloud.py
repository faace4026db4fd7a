"""The local cloud ranked over a shortlist (`hamnet.perception.local_cloud`): at every step
the same points as ranking the whole pool, while an object moving a little reuses its
shortlist and a jump, a new scene or a restore ranks the whole pool again."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hamnet.perception.checkpoint import SHIPPED_ENCODER, load_checkpoint
from hamnet.perception.cloud_ops import nearest_points
from hamnet.perception.config import CloudConfig
from hamnet.perception.core import EpisodeScenes, Perception
from hamnet.perception.local_cloud import LocalClouds
from hamnet.perception.scene_cloud import Cuboids
from hamnet.perception.unicorn import UniCORN

B, S, K, P, M = 3, 600, 9, 40, 80


def pools_and_keypoints(seed: int) -> tuple[torch.Tensor, torch.Tensor]:
    """(B, S, 3) pools over a 1 m square table and (B, K, 3) keypoints of a 0.1 m object on
    it, float64 so that no two distances tie within rounding."""
    g = torch.Generator().manual_seed(seed)
    pool = torch.rand(B, S, 3, generator=g, dtype=torch.float64) * torch.tensor([1.0, 1.0, 0.02])
    keypoints = torch.rand(B, K, 3, generator=g, dtype=torch.float64) * 0.1 + 0.45
    return pool, keypoints


def point_sets(clouds: torch.Tensor) -> list[np.ndarray]:
    """Each cloud's points (B, P, 3) in lexicographic order: float32 distances from matrix
    products of different shapes may order two points at the same distance either way."""
    return [cloud[np.lexsort(cloud.T[::-1])] for cloud in clouds.numpy()]


def test_a_moving_object_gets_the_full_rankings_points_from_its_shortlist() -> None:
    pool, keypoints = pools_and_keypoints(0)
    clouds = LocalClouds(B, P, M, torch.device("cpu"))
    g = torch.Generator().manual_seed(1)
    for _ in range(30):
        keypoints = (
            keypoints + (torch.rand(B, 1, 3, generator=g, dtype=torch.float64) - 0.5) * 0.004
        )
        torch.testing.assert_close(
            clouds.nearest(pool, keypoints), nearest_points(pool, keypoints, P), rtol=0, atol=0
        )
    assert B <= clouds.full_rankings < 3 * B  # the first step, and a refresh or two


def test_a_jump_ranks_the_whole_pool_again_and_stays_exact() -> None:
    pool, keypoints = pools_and_keypoints(2)
    clouds = LocalClouds(B, P, M, torch.device("cpu"))
    clouds.nearest(pool, keypoints)
    jumped = keypoints + torch.tensor([0.3, 0.0, 0.0], dtype=torch.float64) * torch.tensor(
        [[[1.0]], [[0.0]], [[0.0]]], dtype=torch.float64
    )  # only the first environment's object jumps
    torch.testing.assert_close(clouds.nearest(pool, jumped), nearest_points(pool, jumped, P))
    assert clouds.full_rankings == B + 1


def test_forgotten_environments_and_no_shortlist_rank_the_whole_pool() -> None:
    pool, keypoints = pools_and_keypoints(3)
    clouds = LocalClouds(B, P, M, torch.device("cpu"))
    clouds.nearest(pool, keypoints)
    clouds.forget(torch.tensor([1]))
    clouds.nearest(pool, keypoints)
    assert clouds.full_rankings == B + 1
    clouds.forget()
    clouds.nearest(pool, keypoints)
    assert clouds.full_rankings == 2 * B + 1
    every_step = LocalClouds(B, P, 0, torch.device("cpu"))
    for _ in range(3):
        torch.testing.assert_close(
            every_step.nearest(pool, keypoints), nearest_points(pool, keypoints, P)
        )
    assert every_step.full_rankings == 3 * B


def test_a_subset_of_environments_reads_and_refreshes_only_its_own_shortlists() -> None:
    pool, keypoints = pools_and_keypoints(4)
    clouds = LocalClouds(B, P, M, torch.device("cpu"))
    clouds.nearest(pool, keypoints)
    bound = clouds.bound.clone()
    rows = torch.tensor([2, 0])
    far = keypoints[rows] + torch.tensor([0.0, 0.3, 0.0], dtype=torch.float64)
    got = clouds.nearest(pool[rows], far, rows)
    torch.testing.assert_close(got, nearest_points(pool[rows], far, P))
    assert clouds.full_rankings == B + 2
    assert clouds.bound[1] == bound[1] and not torch.equal(clouds.bound[[0, 2]], bound[[0, 2]])


def test_a_shortlist_shorter_than_the_cloud_is_refused() -> None:
    with pytest.raises(ValueError, match="local_shortlist"):
        CloudConfig(num_points=512, local_shortlist=100)
    assert CloudConfig(local_shortlist=0).local_shortlist == 0


def shipped_encoder_and_table_scenes() -> tuple[UniCORN, Cuboids]:
    """The shipped encoder and two scenes of a table with a block on it."""
    encoder, _ = load_checkpoint(SHIPPED_ENCODER)
    centre = torch.tensor([[0.5, 0.0, 0.3], [0.6, 0.1, 0.45]]).expand(2, 2, 3)
    half_extent = torch.tensor([[0.4, 0.4, 0.1], [0.05, 0.05, 0.05]]).expand(2, 2, 3)
    quat = torch.tensor([1.0, 0.0, 0.0, 0.0]).expand(2, 2, 4)
    return encoder, Cuboids.from_quat(centre, quat, half_extent, torch.ones(2, 2, dtype=torch.bool))


def test_perception_with_and_without_shortlists_sees_the_same_local_clouds() -> None:
    """Real perception on one scene pool per environment, the object pushed 2 mm a step,
    then a new episode: the local clouds equal those of ranking the whole pool each step."""
    encoder, scene = shipped_encoder_and_table_scenes()
    object_points = torch.rand(2, 512, 3, generator=torch.Generator().manual_seed(0)) * 0.1 - 0.05
    cores = [
        Perception(encoder, 2, CloudConfig(local_shortlist=shortlist)) for shortlist in (1024, 0)
    ]
    pose = torch.tensor([[0.6, 0.1, 0.45, 1.0, 0.0, 0.0, 0.0]]).repeat(2, 1)
    for episode in range(2):
        scenes = EpisodeScenes(torch.arange(2), torch.arange(2) + 2 * episode, scene, object_points)
        for core in cores:
            core.start_episodes(scenes)
        # A new episode's pool starts without a shortlist: the old indices point elsewhere.
        assert torch.equal(cores[0].local_clouds.bound, torch.full((2,), -torch.inf).double())
        for step in range(8):
            moved = pose + torch.tensor([0.002 * step, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
            short, full = (core.step(moved).local_cloud for core in cores)
            for a, b in zip(point_sets(short), point_sets(full), strict=True):
                np.testing.assert_array_equal(a, b)
    assert cores[0].local_clouds.full_rankings < cores[1].local_clouds.full_rankings == 32


def test_a_point_left_out_that_the_move_brings_nearer_sends_the_step_to_a_full_ranking() -> None:
    """One keypoint at 0 on a line of points at 10, 20, 30 mm (the shortlist of 3, local
    cloud 2) and -35 mm (left out: bound 35 mm). Moved to -12 mm, the shortlist's own second
    point (32 mm) is still nearer than the bound, but the left-out point (23 mm) is now
    nearer than it: only the keypoints' displacement tells, and the step ranks in full."""
    pool = torch.tensor([[[0.010, 0, 0], [0.020, 0, 0], [0.030, 0, 0], [-0.035, 0, 0]]])
    clouds = LocalClouds(1, 2, 3, torch.device("cpu"))
    assert clouds.nearest(pool.double(), torch.zeros(1, 1, 3, dtype=torch.float64)).tolist() == [
        [0, 1]
    ]
    moved = torch.tensor([[[-0.012, 0.0, 0.0]]], dtype=torch.float64)
    assert clouds.nearest(pool.double(), moved).tolist() == [[0, 3]]
    assert clouds.full_rankings == 2


def test_a_restored_perception_starts_without_shortlists() -> None:
    """Shortlists are derived, not saved (`Perception.snapshot`): after `restore` every
    environment ranks its whole pool again."""
    encoder, scene = shipped_encoder_and_table_scenes()
    core = Perception(encoder, 2, CloudConfig())
    core.start_episodes(
        EpisodeScenes(torch.arange(2), torch.arange(2), scene, torch.zeros(2, 512, 3))
    )
    core.step(torch.tensor([[0.6, 0.1, 0.45, 1.0, 0.0, 0.0, 0.0]]).repeat(2, 1))
    assert torch.isfinite(core.local_clouds.bound).all()
    arrays, meta = core.snapshot()
    core.restore({name: value.numpy() for name, value in arrays.items()}, meta)
    assert torch.isinf(core.local_clouds.bound).all()
