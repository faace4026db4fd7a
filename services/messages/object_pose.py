"""ObjectPoseEstimate (perception's camera path -> bridge): the object pose estimated from
one robot's depth frames, for the state of step k; the bridge puts it in its next states.
"""

from __future__ import annotations

import numpy as np

from hamnet.proto.perception_pb2 import ObjectPoseEstimate
from hamnet.runtime.tensor import field_array, to_tensor


def encode(pose: np.ndarray, step: int) -> ObjectPoseEstimate:
    """ObjectPoseEstimate of one robot's object (pose (7,): position (m), quaternion wxyz)
    for state `step`."""
    message = ObjectPoseEstimate()
    message.header.step = step
    to_tensor(np.asarray(pose, dtype=np.float32)[None], message.pose)  # (1, 7)
    return message


def decode(message: ObjectPoseEstimate) -> tuple[int, np.ndarray]:
    """(the state step it answers, pose (7,) float32). Non-finite values pass: the bridge
    forwards the estimate as it is, and the policy's decoder judges the state it lands in.

    Raises:
        PayloadError: `missing`, `dtype`, `shape` (not one robot's (1, 7)).
    """
    pose = field_array(message, "pose", np.float32, (1, 7), finite=False)  # (1, 7)
    return message.header.step, np.array(pose[0])
