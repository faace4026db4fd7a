"""What happened to the arm during a step, per environment: the failure reasons the sim's
termination does not name (safety stop, collision, torque limit).

All three are read once per policy step, at its last physics substep: a contact or a
saturated torque that lasts less than a policy period (0.1 s) can be missed. A collision is
a contact between one of the arm's links and a scene cuboid; the paddle is left out, since
it pushes objects across the surfaces it stands on by design.
"""

from __future__ import annotations

import numpy as np

from hamnet.safety.filter import SafeOutput
from hamnet.sim.env import VectorEnv

TORQUE_SATURATION = 0.99
"""A joint is at its torque limit when |tau| >= this share of the command's clip (ours:
MuJoCo clamps to the force range exactly, so any share near 1 tells a clamped joint)."""

PADDLE_BODY = "fr3_paddle"
"""The arm's body that is meant to touch things."""


class ArmEvents:
    """Reads, after `env.step`, which environments' arm hit the scene or its torque limit."""

    def __init__(self, env: VectorEnv) -> None:
        model = env.world.model
        geoms = env.physics.robot_geoms
        paddle = model.body(PADDLE_BODY).id
        self.links = np.zeros(model.ngeom, dtype=bool)
        self.links[geoms[model.geom_bodyid[geoms] != paddle]] = True
        self.scene = np.zeros(model.ngeom, dtype=bool)
        self.scene[env.world.cuboid_geoms] = True
        self.env, self.data = env, None
        self.force = env.physics.bind("actuator_force")  # (B, J), after every step

    def collided(self, env_ids: np.ndarray) -> np.ndarray:
        """(K,) whether an arm link touches a scene cuboid in each of `env_ids` (K,)."""
        hits = np.zeros(len(env_ids), dtype=bool)
        for k, env in enumerate(env_ids):
            self.data = self.env.physics.batch.get_data(int(env), self.data)
            pairs = self.data.contact.geom[: self.data.ncon]  # (ncon, 2)
            links, scene = self.links[pairs], self.scene[pairs]
            hits[k] = bool(np.any((links[:, 0] & scene[:, 1]) | (links[:, 1] & scene[:, 0])))
        return hits

    def torque_limited(self, tau_limit: np.ndarray) -> np.ndarray:
        """(B,) whether any joint's torque reached the command's clip `tau_limit` (B, J)."""
        return np.any(np.abs(self.force) >= TORQUE_SATURATION * tau_limit, axis=1)


def safety_stopped(safe: SafeOutput) -> np.ndarray:
    """(B,) whether the safety filter braked or held instead of following the policy."""
    return np.asarray(safe.stopping, dtype=bool)
