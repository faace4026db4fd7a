"""The perception shell: decode/encode round trips, and a scripted loop fed with scenes and
states encoded by the sim's own encoders from a real `VectorEnv`."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from hamnet.messages.tokens import encode as encode_tokens
from hamnet.perception.config import CloudConfig, EncoderConfig
from hamnet.perception.core import Percepts
from hamnet.perception.messages import decode_scene, decode_state
from hamnet.perception.shell import PerceptionLoopConfig, PerceptionShell
from hamnet.perception.unicorn import UniCORN
from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.runtime.codec import encode
from hamnet.runtime.service import ServiceIdentity
from hamnet.runtime.shell_config import ReportConfig
from hamnet.runtime.tensor import PayloadError, from_tensor
from hamnet.sim.config import SimConfig
from hamnet.sim.env import VectorEnv
from hamnet.sim.shell import encode_scene, encode_state
from tests.scripted import ScriptedService, wire

B = 2
ENCODER = EncoderConfig(width=32, depth=1, heads=2, tokenizer_hidden=(16,))
CLOUDS = CloudConfig(scene_pool=1024)


@pytest.fixture(scope="module")
def env() -> VectorEnv:
    env = VectorEnv(SimConfig(num_envs=B, num_objects=2, nthread=1))
    env.reset(seed=0)
    return env


def scene_message(env: VectorEnv, env_ids, step: int):
    return encode_scene(env.scenes(np.asarray(env_ids)), step)


def test_decode_scene_and_state_round_trip(env: VectorEnv) -> None:
    scenes = decode_scene(wire(scene_message(env, [1, 0], 3)), B, 512)
    assert scenes.env_ids.tolist() == [1, 0]
    np.testing.assert_allclose(scenes.cuboids.centre.numpy(), env.scene_arrays["centre"][[1, 0]], atol=1e-6)
    assert scenes.object_points.shape == (2, 512, 3)
    state = decode_state(wire(encode_state(env.observe(), 3)), B)
    assert state.step == 3 and state.privileged.object_pose.shape == (B, 7)
    with pytest.raises(PayloadError, match="range"):
        decode_scene(wire(scene_message(env, [1], 3)), 1, 512)
    with pytest.raises(PayloadError, match="shape"):
        decode_scene(wire(scene_message(env, [1], 3)), B, 256)


def test_state_without_the_object_pose_is_a_clear_missing_drop(env: VectorEnv) -> None:
    message = encode_state(env.observe(), 0)
    message.ClearField("privileged")
    with pytest.raises(PayloadError, match="object_pose.*depth cameras") as error:
        decode_state(message, B)
    assert error.value.reason == "missing"


def test_encode_tokens_round_trip() -> None:
    g = torch.Generator().manual_seed(0)
    clouds = [torch.rand(B, 512, 3, generator=g) for _ in range(3)]
    tokens = [torch.rand(B, 17, 128, generator=g) for _ in range(3)]
    message = wire(encode_tokens(Percepts(*clouds, *tokens), 5, np.array([3, 4]), 0))
    assert message.header.step == 5 and message.encoder_version == 0
    np.testing.assert_array_equal(from_tensor(message.episode_ids, np.int64, (B,)), [3, 4])
    np.testing.assert_array_equal(from_tensor(message.local_tokens, np.float32, (B, 17, 128)), tokens[1].numpy())
    np.testing.assert_array_equal(from_tensor(message.environment_cloud, np.float32, (B, 512, 3)), clouds[1].numpy())


def test_loop_answers_each_state_once_its_scenes_are_in(env: VectorEnv) -> None:
    """Scene + state 0 -> tokens 0; state 0 again -> the same message; a malformed scene and
    a state without object pose are counted drops; after a reset of environment 1 its state
    waits for the new scene (asking the sim for it) and is answered, with the new episode
    ids, as soon as it arrives; the state sent again gets the same answer."""
    obs = env.observe()
    no_pose = encode_state(obs, 1)
    no_pose.ClearField("privileged")
    reset = encode_state(obs, 2)
    new_ids = obs.episode_ids.copy()
    new_ids[1] += 10
    reset.episode_ids.data = new_ids.astype(np.int64).tobytes()
    new_scene = scene_message(env, [1], 2)
    new_scene.episode_ids.data = new_ids[1:].astype(np.int64).tobytes()
    script = [
        ("scene", encode(scene_message(env, range(B), 0))),
        ("state", encode(encode_state(obs, 0))),
        ("state", encode(encode_state(obs, 0))),
        ("scene", b"\x08\xff garbage"),
        ("state", encode(no_pose)),
        ("state", encode(reset)),
        ("scene", encode(new_scene)),
        ("state", encode(reset)),
    ]
    service = ScriptedService(lambda published: script.pop(0) if script else None,
                              identity=ServiceIdentity("perception", "0"))  # fmt: skip
    torch.manual_seed(0)
    config = PerceptionLoopConfig(report=ReportConfig(report_period_s=1e9))
    shell = PerceptionShell(service, UniCORN(ENCODER), 3, config, CLOUDS)
    assert shell.run() == 0
    tokens: list[PerceptionTokens] = [m for t, m in service.published if t == "tokens"]
    assert [m.header.step for m in tokens] == [0, 0, 2, 2]  # state 2 answered on its scene
    assert tokens[0] == tokens[1] and all(m.encoder_version == 3 for m in tokens)
    np.testing.assert_array_equal(from_tensor(tokens[2].episode_ids, np.int64, (B,)), new_ids)
    for m in tokens:
        assert from_tensor(m.object_tokens, np.float32, (B, 17, 32), finite=True).shape == (B, 17, 32)
        object_cloud = from_tensor(m.object_cloud, np.float32, (B, 512, 3))
        centre = object_cloud.mean(1)  # (B, 3): the posed cloud sits at the object
        assert np.linalg.norm(centre - obs.object_pose[:, :3], axis=1).max() < 0.1
    reasons = {reason for (_, reason) in service.drops.counts}
    assert reasons == {"decode", "missing"}
    assert shell.counts["waiting_for_scene"] == 1
    assert service.caught_up == [("scene", "hamnet/t/sim/0/scene")]  # asked the sim once


def test_a_stale_state_is_dropped_and_a_restarted_sim_is_followed(env: VectorEnv) -> None:
    """Perception answers the sim's states as the policy does (`Answered`): before, it
    answered any state that was not the last answered one, so a late copy of an older step
    cost a whole encoder pass for tokens the policy drops as stale. Now that state is
    counted as stale and left unanswered, while state 0 of a restarted sim (another run) is
    answered at once."""
    obs = env.observe()
    restarted = encode_state(obs, 0)
    restarted.header.run = 7
    script = [
        ("scene", encode(scene_message(env, range(B), 0))),
        ("state", encode(encode_state(obs, 0))),
        ("state", encode(encode_state(obs, 1))),
        ("state", encode(encode_state(obs, 0))),  # a late copy: stale
        ("state", encode(restarted)),
        ("state", encode(restarted)),  # sent again: the same answer
    ]
    service = ScriptedService(lambda published: script.pop(0) if script else None)
    config = PerceptionLoopConfig(report=ReportConfig(report_period_s=1e9))
    shell = PerceptionShell(service, UniCORN(ENCODER), 3, config, CLOUDS)
    assert shell.run() == 0
    tokens: list[PerceptionTokens] = [m for t, m in service.published if t == "tokens"]
    assert [m.header.step for m in tokens] == [0, 1, 0, 0] and tokens[2] == tokens[3]
    assert shell.counts["stale"] == 1 and shell.counts["repeated"] == 1
