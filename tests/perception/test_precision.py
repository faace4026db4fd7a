"""UniCORN's layers in bfloat16 (`CloudConfig.encoder_precision`): the shipped encoder's
tokens stay near float32's because the patches are still found in float32, and "auto"
picks bfloat16 only on a CPU that has it natively."""

from __future__ import annotations

import pytest
import torch

from hamnet.perception.checkpoint import SHIPPED_ENCODER, load_checkpoint
from hamnet.perception.config import CloudConfig
from hamnet.perception.core import EpisodeScenes, Perception, encode
from hamnet.perception.scene_cloud import Cuboids
from hamnet.runtime.compute import native_bfloat16, use_bfloat16


def table_top_clouds(count: int) -> torch.Tensor:
    """(count, 512, 3) a 0.6 m square of table and a 0.1 m block on it, 0.4 m up."""
    generator = torch.Generator().manual_seed(0)
    table = torch.rand(count, 400, 3, generator=generator) * torch.tensor([0.6, 0.6, 0.0])
    block = torch.rand(count, 112, 3, generator=generator) * 0.1 + torch.tensor([0.25, 0.25, 0.0])
    return torch.cat([table, block], 1) + torch.tensor([0.3, -0.3, 0.4])


def relative_error(tokens: torch.Tensor, reference: torch.Tensor) -> float:
    return float((tokens - reference).norm() / reference.norm())


def test_bfloat16_tokens_of_the_shipped_encoder_are_near_float32s() -> None:
    """Measured 0.5% (relative norm); ranking the patches' neighbours in bfloat16 as well,
    which an autocast around the whole encoder does, moved patch points by up to 0.27 m and
    the tokens by far more than the bound."""
    encoder, _ = load_checkpoint(SHIPPED_ENCODER)
    clouds = table_top_clouds(8)
    with torch.no_grad():
        full, half = encode(encoder, clouds, False), encode(encoder, clouds, True)
    assert half.dtype == torch.float32
    assert 0.0 < relative_error(half, full) < 0.02
    assert torch.nn.functional.cosine_similarity(half, full, dim=-1).min() > 0.999


def test_perception_at_either_precision_sees_the_same_clouds() -> None:
    """Only the tokens' arithmetic changes: the same seed gives the same clouds."""
    encoder, _ = load_checkpoint(SHIPPED_ENCODER)
    centre = torch.tensor([[0.5, 0.0, 0.3], [0.6, 0.1, 0.45]]).expand(2, 2, 3)
    half_extent = torch.tensor([[0.4, 0.4, 0.1], [0.05, 0.05, 0.05]]).expand(2, 2, 3)
    quat = torch.tensor([1.0, 0.0, 0.0, 0.0]).expand(2, 2, 4)
    scene = Cuboids.from_quat(centre, quat, half_extent, torch.ones(2, 2, dtype=torch.bool))
    object_points = table_top_clouds(2) * 0.1
    pose = torch.tensor([[0.6, 0.1, 0.45, 1.0, 0.0, 0.0, 0.0]]).repeat(2, 1)
    percepts = []
    for precision in ("float32", "bfloat16"):
        core = Perception(encoder, 2, CloudConfig(encoder_precision=precision))
        assert core.bfloat16 == (precision == "bfloat16")
        core.start_episodes(EpisodeScenes(torch.arange(2), torch.arange(2), scene, object_points))
        percepts.append(core.step(pose))
    full, half = percepts
    torch.testing.assert_close(half.local_cloud, full.local_cloud, rtol=0, atol=0)
    torch.testing.assert_close(half.environment_cloud, full.environment_cloud, rtol=0, atol=0)
    for name in ("local_tokens", "global_tokens", "object_tokens"):
        assert 0.0 < relative_error(getattr(half, name), getattr(full, name)) < 0.02, name


def test_auto_is_bfloat16_on_a_native_cpu_only() -> None:
    cpu, cuda = torch.device("cpu"), torch.device("cuda")
    assert use_bfloat16("bfloat16", cpu) and not use_bfloat16("float32", cpu)
    assert use_bfloat16("auto", cpu) == native_bfloat16()
    assert not use_bfloat16("auto", cuda)


def test_an_unknown_precision_is_refused() -> None:
    with pytest.raises(ValueError, match="encoder_precision"):
        CloudConfig(encoder_precision="float16")
