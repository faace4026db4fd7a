"""The physics parameters drawn per episode, by name, in the order of every (B, P) array of
them: the sim's `Episodes.physics_params`, RobotState.privileged.physics_params and the
teacher policy's privileged input.
"""

from __future__ import annotations

JOINT_DYNAMICS_NAMES = ("joint_armature_scale", "joint_damping_scale", "joint_friction_scale")
"""The per-episode scale factors on the model file's armature, damping and frictionloss, in
the order of `hamnet.sim.robot.draw_joint_dynamics`'s columns. The friction column is the
friction the arm has, as a fraction of the identified one, whatever the friction mode."""

PHYSICS_PARAM_NAMES = (
    "object_mass",
    "object_friction",
    "object_restitution",
    "robot_friction",
    "scene_friction",
    "object_scale",
    *JOINT_DYNAMICS_NAMES,
)
"""Columns of `Episodes.physics_params` (RobotState.privileged.physics_params); the policy
sizes its input from this tuple, so a new column lands here only. The paper's nu (R^6, Table
tab:state_components) plus the object's scale and the arm's joint-dynamics factors, which the
teacher needs once those vary per episode."""
