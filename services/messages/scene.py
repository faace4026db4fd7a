"""Scene (sim -> perception, policy, monitor): the procedural scenes of the K environments
that were (re)set. The sim describes them (`SceneDescription`) and encodes them here; every
consumer decodes them with one function (`SceneIn`, fields the sender leaves out None).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from hamnet.messages.fields import Spec, arrays
from hamnet.proto.common_pb2 import Header
from hamnet.proto.sim_pb2 import Scene
from hamnet.runtime.tensor import PayloadError, field_array, to_tensor


@dataclass(frozen=True)
class SceneDescription:
    """The current episodes of K environments: what the Scene message carries."""

    env_ids: np.ndarray
    """(K,) int64 environment indices."""
    episode_ids: np.ndarray
    """(K,) int64."""
    object_ids: tuple[str, ...]
    """(K,) library name of each environment's object."""
    object_scale: np.ndarray
    """(K,) float32, the object's scale relative to its library mesh."""
    object_points: np.ndarray
    """(K, P, 3) float32 surface points of the object in its own frame, m."""
    cuboid_centre: np.ndarray
    """(K, C, 3) float32 cuboid centres, world frame, m."""
    cuboid_quat: np.ndarray
    """(K, C, 4) float32 cuboid orientations, wxyz."""
    cuboid_half_extent: np.ndarray
    """(K, C, 3) float32 half sizes, m."""
    cuboid_active: np.ndarray
    """(K, C) bool: slots in use (inactive slots are parked out of the way)."""
    env_code: np.ndarray
    """(K, 25) float32 EnvCode of each scene (paper, "Scene encoding")."""
    start_pose: np.ndarray
    """(K, 7) float32 object pose at the episode's start: position, quaternion wxyz."""
    goal_pose: np.ndarray
    """(K, 7) float32 goal pose: position, quaternion wxyz."""


@dataclass(frozen=True)
class SceneIn:
    """Scene k decoded: K environments' scenes; a field the message leaves out is None."""

    step: int
    """The state step the scenes start at."""
    env_ids: np.ndarray
    """(K,) int32 environment indices."""
    episode_ids: np.ndarray | None = None
    """(K,) int64 episodes starting with these scenes."""
    cuboid_pos: np.ndarray | None = None
    """(K, C, 3) float32 cuboid centres, m (slot 0: the table)."""
    cuboid_quat: np.ndarray | None = None
    """(K, C, 4) float32 orientations, wxyz."""
    cuboid_half_size: np.ndarray | None = None
    """(K, C, 3) float32 half extents, m."""
    cuboid_active: np.ndarray | None = None
    """(K, C) bool: slots in use."""
    object_scale: np.ndarray | None = None
    """(K,) float32."""
    start_pose: np.ndarray | None = None
    """(K, 7) float32 object start pose: position (m), quaternion wxyz."""
    goal_pose: np.ndarray | None = None
    """(K, 7) float32 goal pose."""
    env_code: np.ndarray | None = None
    """(K, E) float32 EnvCode (E = 25)."""
    object_points: np.ndarray | None = None
    """(K, P, 3) float32 object surface points in the object's frame, m."""
    object_ids: tuple[str, ...] = ()
    """K library names (empty when the sender leaves them out)."""
    stamp_ns: int = 0
    """`Header.stamp_ns`."""


def decode(
    message: Scene,
    required: Iterable[str] = (),
    num_envs: int | None = None,
    num_cuboids: int | None = None,
    num_points: int | None = None,
    env_code_dim: int | None = None,
) -> SceneIn:
    """Scene k, every field it carries checked against K and the given sizes.

    Args:
        required: fields that must be set (names of `SceneIn`'s arrays, or "object_ids").
        num_envs: B, the environments an index must fall in (None: unchecked).
        num_cuboids, num_points, env_code_dim: C, P and E (None: any, C the same in every
            cuboid field).
    Raises:
        PayloadError: `missing`, `dtype`, `shape` (counts disagree), `nonfinite`, `range`
            (an environment index outside [0, B)).
    """
    env_ids = np.array(field_array(message, "env_ids", np.int32, (None,)))  # (K,)
    k = len(env_ids)
    if num_envs is not None and k and (env_ids.min() < 0 or env_ids.max() >= num_envs):
        raise PayloadError("range", f"Scene.env_ids {env_ids.tolist()} outside [0, {num_envs})")
    if message.HasField("cuboid_pos") and num_cuboids is None:
        num_cuboids = field_array(message, "cuboid_pos", np.float32, (k, None, 3)).shape[1]
    c = num_cuboids
    specs = {
        "episode_ids": Spec(np.int64),
        "cuboid_pos": Spec(np.float32, (c, 3)),
        "cuboid_quat": Spec(np.float32, (c, 4)),
        "cuboid_half_size": Spec(np.float32, (c, 3)),
        "cuboid_active": Spec(np.bool_, (c,)),
        "object_scale": Spec(np.float32),
        "start_pose": Spec(np.float32, (7,)),
        "goal_pose": Spec(np.float32, (7,)),
        "env_code": Spec(np.float32, (env_code_dim,)),
        "object_points": Spec(np.float32, (num_points, 3)),
    }
    names = tuple(message.object_ids)
    required = tuple(required)
    if (names or "object_ids" in required) and len(names) != k:
        raise PayloadError("shape", f"Scene.object_ids: {len(names)} names for {k} envs")
    decoded = arrays(message, specs, k, (name for name in required if name != "object_ids"))
    header = message.header
    return SceneIn(header.step, env_ids, object_ids=names, stamp_ns=header.stamp_ns, **decoded)


def encode(scenes: SceneDescription, step: int) -> Scene:
    """The Scene message of K environments' current episodes, at the state of `step`."""
    message = Scene(header=Header(step=step), object_ids=list(scenes.object_ids))
    to_tensor(scenes.env_ids.astype(np.int32), message.env_ids)  # (K,)
    to_tensor(scenes.episode_ids.astype(np.int64), message.episode_ids)  # (K,)
    to_tensor(scenes.cuboid_centre, message.cuboid_pos)  # (K, C, 3)
    to_tensor(scenes.cuboid_quat, message.cuboid_quat)  # (K, C, 4)
    to_tensor(scenes.cuboid_half_extent, message.cuboid_half_size)  # (K, C, 3)
    to_tensor(scenes.cuboid_active.astype(bool), message.cuboid_active)  # (K, C)
    to_tensor(scenes.object_scale, message.object_scale)  # (K,)
    to_tensor(scenes.start_pose, message.start_pose)  # (K, 7)
    to_tensor(scenes.goal_pose, message.goal_pose)  # (K, 7)
    to_tensor(scenes.env_code, message.env_code)  # (K, 25)
    to_tensor(scenes.object_points, message.object_points)  # (K, P, 3)
    return message
