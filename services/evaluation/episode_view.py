"""A few evaluated episodes as Rerun recordings, one `.rrd` per episode: the scene's cuboids,
the robot posed at every step, the object's surface points at its pose and the goal, on a
`step` timeline (`rerun <file>` replays it). They show how an episode failed where the
report only counts it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr

from hamnet.messages.robot_state import Observation
from hamnet.monitor.robot import RobotView
from hamnet.sim import quaternion
from hamnet.sim.env import VectorEnv
from hamnet.sim.scene_view import log_cuboids, log_pedestal

OBJECT_COLOUR = (230, 160, 40)
GOAL_COLOUR = (40, 200, 90)


class EpisodeView:
    """Records environments `env_ids` of `env` from their episodes' start to their end."""

    def __init__(self, env: VectorEnv, env_ids: list[int], paths: list[Path]) -> None:
        """`paths`: one `.rrd` file per environment of `env_ids`."""
        self.env, self.env_ids = env, env_ids
        self.robot = RobotView()
        self.recordings: list[rr.RecordingStream] = []
        scenes = env.scenes(np.asarray(env_ids, dtype=np.int64))
        for k, path in enumerate(paths):
            path.parent.mkdir(parents=True, exist_ok=True)
            recording = rr.RecordingStream("hamnet_eval")
            recording.save(path)
            recording.log("/", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
            log_pedestal(recording)
            self.robot.log_geometry(recording)
            log_cuboids(
                scenes.cuboid_centre[k],
                scenes.cuboid_quat[k],
                scenes.cuboid_half_extent[k],
                scenes.cuboid_active[k],
                recording,
            )
            self.recordings.append(recording)
        self.points = scenes.object_points  # (K, P, 3) in the object's frame
        self.episode_ids = scenes.episode_ids
        self.goal = scenes.goal_pose

    def frame(self, step: int, observation: Observation) -> None:
        """Log the recorded environments still in their first episode at `step`."""
        for k, (env, recording) in enumerate(zip(self.env_ids, self.recordings, strict=True)):
            if observation.episode_ids[env] != self.episode_ids[k]:
                continue
            recording.set_time("step", sequence=step)
            self.robot.log_pose(observation.q[env], recording)
            for name, pose, colour in (
                ("object", observation.object_pose[env], OBJECT_COLOUR),
                ("goal", self.goal[k], GOAL_COLOUR),
            ):
                rotation = quaternion.to_matrix(np.asarray(pose[3:], dtype=np.float64))
                points = self.points[k] @ rotation.T + pose[:3]
                recording.log(name, rr.Points3D(points, radii=0.003, colors=[colour]))

    def close(self) -> None:
        for recording in self.recordings:
            recording.flush()
            recording.disconnect()
