"""The perception service's messages: RobotState and Scene decoded (`hamnet.messages`) with
the fields perception reads. Pure functions, tested without a session; a malformed payload
raises `PayloadError` (the inbox counts and drops it). The tokens are encoded by
`hamnet.messages.tokens.encode`.

The sim path (`hamnet.perception.shell`) reads the sim's object pose from the privileged
block and the scenes of the episodes; the camera path (`hamnet.perception.camera_shell`)
reads only a state's step and episode id.
"""

from __future__ import annotations

from hamnet.messages import robot_state, scene
from hamnet.messages.robot_state import StateIn
from hamnet.perception.core import EpisodeScenes
from hamnet.proto.sim_pb2 import RobotState, Scene
from hamnet.runtime.tensor import PayloadError


def decode_state(message: RobotState, num_envs: int | None) -> StateIn:
    """RobotState k with its episode ids and privileged block (the sim's object pose);
    `num_envs` None accepts any batch size.

    Raises:
        PayloadError: `missing` (no episode ids, or no privileged object pose: a real robot
            needs the camera path), `dtype`, `shape`, `nonfinite`.
    """
    why = (
        "its object_pose places the object cloud; on a real robot the cloud must come from "
        "depth cameras (hamnet perception --clouds-from cameras)"
    )
    return robot_state.decode(message, num_envs, required=("episode_ids",), privileged_for=why)


_SCENE_READS = (
    "episode_ids",
    "cuboid_pos",
    "cuboid_quat",
    "cuboid_half_size",
    "cuboid_active",
    "object_points",
)


def decode_scene(message: Scene, num_envs: int | None, num_points: int) -> EpisodeScenes:
    """The K scenes of a Scene message as CPU tensors.

    Raises:
        PayloadError: `missing`, `dtype`, `shape` (counts disagree, object points not
            (K, num_points, 3)), `nonfinite`, `range` (an environment index outside [0, B),
            or a scene without any active cuboid).
    """
    decoded = scene.decode(message, _SCENE_READS, num_envs=num_envs, num_points=num_points)
    if len(decoded.env_ids) and not decoded.cuboid_active.any(1).all():
        raise PayloadError("range", "Scene holds a scene without any active cuboid")
    return EpisodeScenes.from_arrays(
        decoded.env_ids,
        decoded.episode_ids,
        decoded.cuboid_pos,
        decoded.cuboid_quat,
        decoded.cuboid_half_size,
        decoded.cuboid_active,
        decoded.object_points,
    )


def decode_step(message: RobotState) -> StateIn:
    """RobotState k of one robot: the camera path answers its step and episode id.

    Raises:
        PayloadError: `missing`, `dtype`, `shape` (more than one environment: the cameras
            see one robot).
    """
    return robot_state.decode(message, 1, required=("episode_ids",))
