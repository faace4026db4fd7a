"""`LatestScenes`: what a replay answers to a scene query, by hand on a known sequence."""

from __future__ import annotations

import numpy as np
import pytest

from hamnet.proto.sim_pb2 import Scene
from hamnet.recorder.scenes import LatestScenes
from hamnet.runtime.tensor import PayloadError, to_tensor

W0, W1 = "hamnet/rp/sim/0/scene", "hamnet/rp/sim/1/scene"


def scene(step: int, env_ids: list[int]) -> bytes:
    message = Scene()
    message.header.step = step
    to_tensor(np.array(env_ids, np.int32), message.env_ids)  # (K,)
    return message.SerializeToString()


def test_each_environment_is_answered_with_its_latest_scene_once_in_order() -> None:
    """All of worker 0 at step 0, then env 1 at step 5, then envs 1 and 2 at step 9: env 0
    still needs the first payload, envs 1 and 2 the third; the second is superseded."""
    first, second, third = scene(0, [0, 1, 2]), scene(5, [1]), scene(9, [1, 2])
    scenes = LatestScenes()
    for payload in (first, second, third):
        scenes.add(W0, payload)
    scenes.add(W1, scene(3, [0]))
    assert scenes.answers(W0) == [(W0, first), (W0, third)]
    assert [key for key, _ in scenes.answers("hamnet/rp/sim/*/scene")] == [W0, W0, W1]
    assert scenes.answers("hamnet/other/sim/0/scene") == []


def test_a_payload_that_is_not_a_scene_is_refused() -> None:
    scenes = LatestScenes()
    with pytest.raises(PayloadError):
        scenes.add(W0, b"\x08\xff not a scene")
    assert scenes.answers(W0) == []
