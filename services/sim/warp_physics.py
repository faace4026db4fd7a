"""The sim's physics on MuJoCo Warp (`mujoco-warp`): the same `BatchPhysics`, with every
policy step integrated by MuJoCo Warp on its device (Warp's CPU device here, a GPU where
one is lent) instead of by `mujoco.batch`.

The C batch stays the keeper of what the episodes write (each environment's model fields,
the constants MuJoCo derives from them, the state at a reset) and of what the environment
reads between steps (`bind`: the state's derived fields, recomputed by one C forward pass
after each step), so every per-environment write and read is the C backend's own code. A
step copies what changed into Warp's per-world arrays, integrates there, and copies the
state back. Two differences of the engines are bridged here: Warp poses the world body's
geoms once, so the scene slots sit on a mocap body (`world.build_world(scene_body=True)`),
and Warp's contact types are per geom, not per world, so an unused part slot of the object
gets no mesh (`geom_dataid` -1, which Warp's broadphase skips) instead of contype 0.
"""

from __future__ import annotations

import mujoco
import mujoco_warp as mjw
import numpy as np
import warp as wp

from hamnet.sim.physics import BatchPhysics
from hamnet.sim.world import World

wp.config.quiet = True  # no banner, and no line for every kernel module it loads
wp.config.log_level = wp.LOG_WARNING

DERIVED = ("body_subtreemass", "body_invweight0", "dof_invweight0", "actuator_acc0")
"""Constants MuJoCo derives from the per-environment fields (`mj_setConst`) that the
solver reads: taken from each environment's C model after a change."""

GEOMETRY = ("geom_pos", "geom_quat", "geom_size", "geom_rbound", "geom_aabb", "geom_friction")
"""Fields `set_scene` writes (the object's parts too)."""
OBJECT = (
    *GEOMETRY,
    "geom_dataid",
    "geom_solref",
    "body_mass",
    "body_inertia",
    "body_ipos",
    "body_iquat",
)
"""Fields `set_object` writes (its contype decides `geom_dataid` here)."""
JOINTS = ("dof_armature", "dof_damping", "dof_frictionloss")
"""Fields `set_joint_dynamics` writes."""
GAINS = ("actuator_gainprm", "actuator_biasprm", "actuator_forcerange")
"""Fields `set_gains` writes, every step."""

UNBATCHED = ("geom_contype", "geom_conaffinity")
"""Per-environment fields Warp keeps per geom only (see the module docstring)."""

CONTACTS_PER_WORLD = 64
"""Contacts Warp makes room for per world (arm, object and scene touch at a few points)."""
CONSTRAINTS_PER_WORLD = 256
"""Constraint rows per world (contacts, joint limits and friction)."""


class WarpPhysics(BatchPhysics):
    """B environments integrated by MuJoCo Warp on `device`."""

    def __init__(self, world: World, num_envs: int, nthread: int = 0, device: str = "cpu") -> None:
        super().__init__(world, num_envs, nthread)
        self.device = device
        with wp.ScopedDevice(device):
            self.model = mjw.put_model(world.model)
            self.data = mjw.put_data(
                world.model,
                mujoco.MjData(world.model),
                nworld=num_envs,
                nconmax=CONTACTS_PER_WORLD * num_envs,
                njmax=CONSTRAINTS_PER_WORLD,
            )
        self._batched: set[str] = set()
        """Model fields already given one row per world."""
        self._dirty: set[str] = set(self.fields) - set(UNBATCHED)
        """Model fields written since the last step (only those are copied to Warp)."""
        self._derived_stale = np.ones(num_envs, dtype=bool)
        self._state_stale = True

    def set_scene(self, env_ids, centre, quat, half_extent, friction) -> None:
        super().set_scene(env_ids, centre, quat, half_extent, friction)
        self._dirty.update(GEOMETRY)

    def set_object(self, env_ids, object_index, mass, friction, solref) -> None:
        super().set_object(env_ids, object_index, mass, friction, solref)
        self._dirty.update(OBJECT)
        self._derived_stale[env_ids] = True

    def set_robot_friction(self, env_ids, friction) -> None:
        super().set_robot_friction(env_ids, friction)
        self._dirty.add("geom_friction")

    def set_joint_dynamics(self, env_ids, scale) -> None:
        super().set_joint_dynamics(env_ids, scale)
        self._dirty.update(JOINTS)
        self._derived_stale[env_ids] = True

    def set_gains(self, kp, kd, tau_limit) -> None:
        super().set_gains(kp, kd, tau_limit)
        self._dirty.update(GAINS)

    def set_state(self, env_ids, q, object_pos, object_quat) -> None:
        super().set_state(env_ids, q, object_pos, object_quat)
        self._state_stale = True

    def restore(self, arrays: dict[str, np.ndarray]) -> None:
        super().restore(arrays)
        self._dirty = set(self.fields) - set(UNBATCHED)
        self._derived_stale[:] = True
        self._state_stale = True

    def step(self, q_ref: np.ndarray, substeps: int) -> None:
        """Advance every environment by one policy step on Warp, then bring the state back
        and recompute its derived fields on the C side."""
        with wp.ScopedDevice(self.device):
            self._push_model()
            if self._state_stale:
                self._push_state()
            for sample in range(q_ref.shape[1]):
                self.data.ctrl.assign(np.ascontiguousarray(q_ref[:, sample], np.float32))
                for _ in range(substeps):
                    mjw.step(self.model, self.data)
            self.qpos[...] = self.data.qpos.numpy()
            self.qvel[...] = self.data.qvel.numpy()
            self.ctrl[...] = q_ref[:, -1]
        self.batch.forward()

    def _push_model(self) -> None:
        """The per-environment fields written since the last step into Warp's per-world
        arrays, and the derived constants of the environments whose fields changed them."""
        for name in sorted(self._dirty):
            values = self.fields[name]
            if name == "geom_dataid":
                unused = self.fields["geom_contype"] == 0  # (B, ngeom): parts switched off
                values = np.where(unused, -1, values)
            self._assign(name, values)
        self._dirty.clear()
        if self._derived_stale.any():
            derived = {name: self._derived_rows(name) for name in DERIVED}
            for name, values in derived.items():
                self._assign(name, values)
            self._derived_stale[:] = False

    def _derived_rows(self, name: str) -> np.ndarray:
        """(B, ...) a derived constant of every environment's C model."""
        return np.stack([getattr(self.batch.get_model(i), name) for i in range(self.num_envs)])

    def _assign(self, name: str, values: np.ndarray) -> None:
        """Set Warp's model field `name` to `values` (B, ...), one row per world (the first
        time, the field's one shared row becomes B rows)."""
        field = getattr(self.model, name)
        array = np.ascontiguousarray(values, dtype=_numpy_type(field.dtype))
        if name in self._batched:
            field.assign(array)
        else:
            setattr(self.model, name, wp.array(array, dtype=field.dtype))
            self._batched.add(name)

    def _push_state(self) -> None:
        """The C state (positions, velocities, references) into Warp, with no warm start."""
        self.data.qpos.assign(np.ascontiguousarray(self.qpos, np.float32))
        self.data.qvel.assign(np.ascontiguousarray(self.qvel, np.float32))
        self.data.ctrl.assign(np.ascontiguousarray(self.ctrl, np.float32))
        self.data.qacc_warmstart.zero_()
        self._state_stale = False


def _numpy_type(dtype: object) -> type:
    """The numpy scalar type of a Warp dtype (vectors and matrices by their scalar)."""
    scalar = getattr(dtype, "_wp_scalar_type_", dtype)
    return np.int32 if scalar in (wp.int32, int) else np.float32
