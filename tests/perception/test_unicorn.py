"""The UniCORN encoder (shapes, [EMB] last, invariance to the order of the points,
batch independence), its checkpoints (round trip, clear errors) and the cached core."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hamnet.perception.checkpoint import (
    CheckpointError,
    load_checkpoint,
    save_checkpoint,
    write_random_checkpoint,
)
from hamnet.perception.cloud_ops import pose_points
from hamnet.perception.config import CloudConfig, EncoderConfig
from hamnet.perception.core import EpisodeScenes, Perception
from hamnet.perception.scene_cloud import Cuboids
from hamnet.perception.unicorn import PatchTokenizer, UniCORN, patchify

SMALL = EncoderConfig(num_points=128, num_patches=8, patch_size=16, width=32, depth=2, heads=4)


def test_encoder_gives_one_emb_token_plus_one_per_patch() -> None:
    encoder = UniCORN().eval()
    with torch.no_grad():
        tokens = encoder(torch.rand(3, 512, 3))
    assert tokens.shape == (3, 17, 128) and tokens.dtype == torch.float32
    assert bool(torch.isfinite(tokens).all())


def test_tokens_do_not_depend_on_the_order_of_the_points() -> None:
    torch.manual_seed(0)
    encoder = UniCORN(SMALL).eval()
    points = torch.rand(4, 128, 3)
    shuffled = points[:, torch.randperm(128)]
    with torch.no_grad():
        torch.testing.assert_close(encoder(shuffled), encoder(points), atol=1e-5, rtol=0)


def test_each_cloud_is_encoded_on_its_own() -> None:
    """Batching must not mix clouds: a cloud's tokens are the same alone or in a batch."""
    encoder = UniCORN(SMALL).eval()
    points = torch.rand(3, 128, 3)
    with torch.no_grad():
        torch.testing.assert_close(encoder(points)[1:2], encoder(points[1:2]), atol=1e-5, rtol=0)


def test_patches_are_knn_groups_of_fps_seeds_centred_on_their_mean() -> None:
    """The authors re-centre each patch on its mean (point_mae.py:1074-1075)."""
    points = torch.rand(2, 128, 3)
    centres, patches = patchify(points, 8, 16)
    assert centres.shape == (2, 8, 3) and patches.shape == (2, 8, 16, 3)
    torch.testing.assert_close(patches.mean(dim=2), torch.zeros(2, 8, 3), atol=1e-6, rtol=0)
    seed = patches[:, :, :1]  # the FPS seed is its own nearest neighbour: first
    radius = (patches - seed).norm(dim=-1)  # (B, K, k): sorted, nearest to the seed first
    assert bool((radius[..., 1:] >= radius[..., :-1] - 1e-6).all())


def test_tokenizer_is_an_mlp_over_the_flattened_patch() -> None:
    """Paper: an MLP over the flattened patch, not a max-pooled PointNet: swapping two points
    of a patch changes its token (a pooled tokenizer would give the same one)."""
    torch.manual_seed(0)
    tokenizer = PatchTokenizer(SMALL)
    assert tokenizer.mlp[0].in_features == 3 * SMALL.patch_size
    patches = torch.rand(1, 2, SMALL.patch_size, 3)
    swapped = patches[:, :, [1, 0, *range(2, SMALL.patch_size)]]
    assert not torch.allclose(tokenizer(patches), tokenizer(swapped))


def test_emb_is_the_last_token() -> None:
    """The authors append [EMB] after the patches (unicorn.py:153-154); the policy reads the
    last token. Before the transformer, the last token is the learned [EMB] itself."""
    encoder = UniCORN(SMALL).eval()
    captured = {}
    hook = encoder.layers[0].register_forward_pre_hook(lambda m, args: captured.update(x=args[0]))
    with torch.no_grad():
        encoder(torch.rand(2, 128, 3))
    hook.remove()
    torch.testing.assert_close(captured["x"][:, -1], encoder.emb[0].expand(2, -1))


def test_wrong_cloud_shape_is_a_clear_error() -> None:
    with pytest.raises(ValueError, match=r"\(B, 512, 3\)"):
        UniCORN()(torch.rand(1, 100, 3))


def test_checkpoint_round_trip_keeps_weights_and_version(tmp_path) -> None:
    encoder = UniCORN(SMALL).eval()
    save_checkpoint(tmp_path / "e.safetensors", encoder, 7)
    loaded, version = load_checkpoint(tmp_path / "e.safetensors", SMALL)
    assert version == 7
    points = torch.rand(2, 128, 3)
    with torch.no_grad():
        torch.testing.assert_close(loaded(points), encoder(points))


def test_random_checkpoint_is_version_zero(tmp_path) -> None:
    write_random_checkpoint(tmp_path / "r.safetensors")
    _, version = load_checkpoint(tmp_path / "r.safetensors")
    assert version == 0


def test_bad_checkpoints_fail_with_a_message_that_says_why(tmp_path) -> None:
    with pytest.raises(CheckpointError, match="does not exist"):
        load_checkpoint(tmp_path / "none.safetensors")
    (tmp_path / "junk.safetensors").write_bytes(b"not a safetensors file")
    with pytest.raises(CheckpointError, match="not a readable"):
        load_checkpoint(tmp_path / "junk.safetensors")
    save_checkpoint(tmp_path / "small.safetensors", UniCORN(SMALL), 1)
    with pytest.raises(CheckpointError, match="another encoder architecture.*width"):
        load_checkpoint(tmp_path / "small.safetensors", EncoderConfig())
    from safetensors.torch import save_file

    tensors = {k: v for k, v in UniCORN(SMALL).state_dict().items() if k != "emb"}
    save_file(tensors, str(tmp_path / "cut.safetensors"),
              metadata={"hamnet.encoder.config": SMALL.to_json(), "hamnet.encoder.version": "2"})  # fmt: skip
    with pytest.raises(CheckpointError, match=r"missing \['emb'\]"):
        load_checkpoint(tmp_path / "cut.safetensors", SMALL)


def one_scene(num_envs: int) -> Cuboids:
    """A table (slot 0) and a block on it, in every environment."""
    centre = torch.tensor([[0.5, 0.0, 0.3], [0.6, 0.1, 0.45]]).expand(num_envs, 2, 3)
    half = torch.tensor([[0.4, 0.4, 0.1], [0.05, 0.05, 0.05]]).expand(num_envs, 2, 3)
    quat = torch.tensor([1.0, 0.0, 0.0, 0.0]).expand(num_envs, 2, 4)
    return Cuboids.from_quat(centre, quat, half, torch.ones(num_envs, 2, dtype=torch.bool))


def test_core_caches_scene_and_object_tokens_and_follows_the_object() -> None:
    config = CloudConfig(num_points=128, scene_pool=512, num_keypoints=16)
    core = Perception(UniCORN(SMALL), 3, config)
    object_points = torch.rand(3, 128, 3) * 0.05
    assert core.missing(torch.tensor([0, 1, 2])).tolist() == [0, 1, 2]
    core.start_episodes(EpisodeScenes(torch.arange(3), torch.tensor([0, 1, 2]), one_scene(3), object_points))
    assert core.missing(torch.tensor([0, 1, 2])).numel() == 0
    assert core.missing(torch.tensor([0, 5, 2])).tolist() == [1]
    pose = torch.tensor([[0.5, 0.0, 0.45, 1.0, 0.0, 0.0, 0.0]]).repeat(3, 1)
    first = core.step(pose)
    pose[0, 0] = 0.2
    second = core.step(pose)
    torch.testing.assert_close(second.object_cloud, pose_points(object_points, pose))
    torch.testing.assert_close(second.global_tokens, first.global_tokens)
    torch.testing.assert_close(second.object_tokens, first.object_tokens)
    assert not torch.equal(second.local_tokens[0], first.local_tokens[0])  # moved: new local cloud
    torch.testing.assert_close(second.local_tokens[1:], first.local_tokens[1:])
    keypoints = pose_points(core.keypoints, pose)
    near = torch.cdist(second.local_cloud, keypoints).min(-1).values.max(-1).values  # (B,)
    far = torch.cdist(core.scene_pool, keypoints).min(-1).values  # (B, S)
    assert bool((near <= far.sort(-1).values[:, 128 - 1] + 1e-6).all())  # the nearest 128
    # a new episode in environment 1 only: its scene changes, the others keep theirs
    table = one_scene(1)
    moved = Cuboids(table.centre + 0.1, table.rotation, table.half_extent, table.active)
    core.start_episodes(EpisodeScenes(torch.tensor([1]), torch.tensor([9]), moved, object_points[:1]))
    third = core.step(pose)
    torch.testing.assert_close(third.global_tokens[[0, 2]], first.global_tokens[[0, 2]])
    assert not torch.allclose(third.global_tokens[1], first.global_tokens[1])
    np.testing.assert_array_equal(core.episode_ids.numpy(), [0, 9, 2])


def test_a_checkpoint_of_the_pooled_tokenizer_fails_with_the_reason(tmp_path) -> None:
    """Checkpoints written before the flattened-patch MLP (tokenizer_hidden was one int)
    must not load, and the error must name the field."""
    from safetensors.torch import save_file

    old = SMALL.to_json().replace('"tokenizer_hidden": [256, 256]', '"tokenizer_hidden": 64')
    save_file({"emb": torch.zeros(1, 1, 32)}, str(tmp_path / "old.safetensors"),
              metadata={"hamnet.encoder.config": old, "hamnet.encoder.version": "1"})  # fmt: skip
    with pytest.raises(CheckpointError, match="invalid encoder metadata.*tokenizer_hidden"):
        load_checkpoint(tmp_path / "old.safetensors")


def test_a_step_of_some_environments_equals_those_rows_of_a_full_step() -> None:
    """The trainer bootstraps timed-out episodes from a step of those environments only: it
    must see exactly their rows of a full step (noise off, so the two are comparable)."""
    config = CloudConfig(num_points=128, scene_pool=512, num_keypoints=16, noise_std=0.0, dropout=0.0)
    core = Perception(UniCORN(SMALL), 3, config)
    core.start_episodes(EpisodeScenes(torch.arange(3), torch.arange(3), one_scene(3), torch.rand(3, 128, 3) * 0.05))
    pose = torch.tensor([[0.5, 0.0, 0.45, 1.0, 0.0, 0.0, 0.0]]).repeat(3, 1)
    pose[:, 0] += torch.tensor([0.0, 0.1, -0.1])
    whole, some = core.step(pose), core.step(pose[[2, 0]], torch.tensor([2, 0]))
    for name in ("object_cloud", "environment_cloud", "local_cloud", "object_tokens", "local_tokens", "global_tokens"):
        torch.testing.assert_close(getattr(some, name), getattr(whole, name)[[2, 0]], atol=1e-5, rtol=1e-5)
