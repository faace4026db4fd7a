"""`--source sim`: the four virtual D435s of the paper's rig (`hamnet.camera.render`)
render a procedurally generated one-environment scene (a `VectorEnv` of one environment
reset with `seed`), with the arm at the joint positions of the latest robot state, so the
real perception path runs end to end without cameras, with the sim or the bridge as the
robot. The renderer's segmentation goes out as the frames' labels.

The scene is the camera's own: it does not follow the sim's episodes or its object (the sim
publishes no camera frames), and nothing in it moves but the arm.
"""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is first imported: it picks GL then

import numpy as np

from hamnet.camera import render
from hamnet.camera.sources import Frames, SimSourceConfig
from hamnet.messages.robot_state import StateIn
from hamnet.sim.config import SimConfig
from hamnet.sim.env import VectorEnv


def sim_world(config: SimSourceConfig) -> VectorEnv:
    """The one-environment world the virtual cameras look at, reset with the seed (tests
    build the same one to know where the object truly is)."""
    env = VectorEnv(
        SimConfig(num_envs=1, num_objects=config.num_objects, nthread=1, seed=config.seed)
    )
    env.reset(seed=config.seed)
    return env


class SimSource:
    """Renders the rig's four views once per new robot state."""

    needs_state = True
    poll_s = 0.05
    done = False

    def __init__(self, config: SimSourceConfig) -> None:
        self.renderer = render.RigRenderer(sim_world(config), 0, config.width, config.height)
        self.names = [f"d435_{i}" for i in range(len(self.renderer.rig))]
        self.last: tuple[int, int] | None = None

    def poll(self, robot: StateIn | None) -> Frames | None:
        if robot is None or self.last == (robot.run, robot.step):
            return None
        self.last = (robot.run, robot.step)
        return Frames(robot.step, self.renderer.views(np.asarray(robot.q[0], np.float64)), self.names)

    def close(self) -> None:
        self.renderer.close()
