"""Batched physics of one sim worker: B environments of one `World` in a `mujoco.batch.Batch`.

Per-environment differences are per-simulation model fields (`Batch.expand`): scene cuboids,
the object's parts and inertia, contact parameters, the arm's joint armature, damping and
friction, and its impedance gains and torque clip. One policy step is one `Batch.rollout`
call: MuJoCo steps every environment on all threads with the GIL released, evaluating the
impedance law at every physics step while `q_ref` follows the command's reference samples
(zero-order hold per sample).
"""

from __future__ import annotations

import mujoco
import numpy as np
from mujoco.batch import Batch

from hamnet.sim.world import World

CTRL = int(mujoco.mjtState.mjSTATE_CTRL)


def _expand(batch: Batch, *names: str) -> dict[str, np.ndarray]:
    return {name: batch.expand(name) for name in names}


class BatchPhysics:
    """Steps B environments and writes their per-environment model fields."""

    def __init__(self, world: World, num_envs: int, nthread: int = 0) -> None:
        self.world = world
        self.num_envs = num_envs
        self.batch = Batch(world.model, num_envs, nthread=nthread, persistent=True)
        self.fields = _expand(
            self.batch,
            "geom_pos",
            "geom_quat",
            "geom_size",
            "geom_rbound",
            "geom_aabb",
            "geom_dataid",
            "geom_contype",
            "geom_conaffinity",
            "geom_friction",
            "geom_solref",
            "body_mass",
            "body_inertia",
            "body_ipos",
            "body_iquat",
            "actuator_gainprm",
            "actuator_biasprm",
            "actuator_forcerange",
            "dof_armature",
            "dof_damping",
            "dof_frictionloss",
        )
        self.robot_geoms = np.flatnonzero(np.isin(world.model.geom_bodyid, world.robot_bodies))
        """Geoms of the arm's moving bodies (their friction is set per environment)."""
        self.qpos = self.batch.bind("qpos")  # (B, nq), live
        self.qvel = self.batch.bind("qvel")  # (B, nv), live
        self.ctrl = self.batch.bind("ctrl")  # (B, J) impedance references q_ref, live
        self.batch.reset()

    @property
    def timestep(self) -> float:
        """Physics timestep, s."""
        return float(self.world.model.opt.timestep)

    def set_scene(
        self,
        env_ids: np.ndarray,
        centre: np.ndarray,
        quat: np.ndarray,
        half_extent: np.ndarray,
        friction: np.ndarray,
    ) -> None:
        """Place and size the 16 cuboids of `env_ids` (K environments).

        Args:
            env_ids: (K,) environments.
            centre: (K, 16, 3) m; quat: (K, 16, 4) wxyz; half_extent: (K, 16, 3) m.
            friction: (K,) sliding friction of every cuboid.
        """
        geoms = self.world.cuboid_geoms
        rows = np.ix_(env_ids, geoms)
        f = self.fields
        f["geom_pos"][rows] = centre
        f["geom_quat"][rows] = quat
        f["geom_size"][rows] = half_extent
        f["geom_rbound"][rows] = np.linalg.norm(half_extent, axis=-1)  # (K, 16)
        f["geom_aabb"][rows] = np.concatenate([np.zeros_like(half_extent), half_extent], axis=-1)
        f["geom_friction"][env_ids[:, None], geoms[None, :], 0] = friction[:, None]

    def set_object(
        self,
        env_ids: np.ndarray,
        object_index: np.ndarray,
        mass: np.ndarray,
        friction: np.ndarray,
        solref: np.ndarray,
    ) -> None:
        """Give `env_ids` the library objects `object_index` with their physics parameters.

        Args:
            env_ids, object_index: (K,) environments and the object each gets.
            mass: (K,) kg; friction: (K,) sliding friction; solref: (K, 2) contact solref.
        """
        c = self.world.catalogue
        geoms, body = self.world.object_geoms, self.world.object_body
        rows = np.ix_(env_ids, geoms)
        used = c.part_used[object_index]  # (K, P)
        f = self.fields
        f["geom_dataid"][rows] = c.mesh_id[object_index]
        f["geom_pos"][rows] = c.part_pos[object_index]
        f["geom_quat"][rows] = c.part_quat[object_index]
        f["geom_size"][rows] = c.part_size[object_index]
        f["geom_rbound"][rows] = c.part_rbound[object_index] * used
        f["geom_aabb"][rows] = c.part_aabb[object_index]
        f["geom_contype"][rows] = used
        f["geom_conaffinity"][rows] = used
        f["geom_friction"][env_ids[:, None], geoms[None, :], 0] = friction[:, None]
        f["geom_solref"][rows] = solref[:, None, :]
        f["body_mass"][env_ids, body] = mass
        f["body_inertia"][env_ids, body] = c.unit_inertia[object_index] * mass[:, None]
        f["body_ipos"][env_ids, body] = c.inertia_pos[object_index]
        f["body_iquat"][env_ids, body] = c.inertia_quat[object_index]
        self.batch.set_const(env_ids)

    def set_robot_friction(self, env_ids: np.ndarray, friction: np.ndarray) -> None:
        """Sliding friction (K,) of every geom of the arm's moving bodies in `env_ids` (K,)."""
        geoms = self.robot_geoms
        self.fields["geom_friction"][env_ids[:, None], geoms[None, :], 0] = friction[:, None]

    def set_joint_dynamics(self, env_ids: np.ndarray, scale: np.ndarray) -> None:
        """Scale the arm's armature, damping and Coulomb friction of `env_ids` from the model
        file's values (`robot.draw_joint_dynamics`).

        Args:
            env_ids: (K,) environments; scale: (K, 3) factors on armature, damping, friction.
        """
        dofs = self.world.robot_dof
        rows = np.ix_(env_ids, dofs)
        nominal = self.world.model
        for column, name in enumerate(("dof_armature", "dof_damping", "dof_frictionloss")):
            self.fields[name][rows] = getattr(nominal, name)[dofs] * scale[:, column, None]
        self.batch.set_const(env_ids)  # armature enters the constants mj_setConst derives

    def set_gains(self, kp: np.ndarray, kd: np.ndarray, tau_limit: np.ndarray) -> None:
        """Impedance gains and torque clip of every environment until the next call.

        Args:
            kp: (B, J) Nm/rad; kd: (B, J) Nm s/rad; tau_limit: (B, J) Nm (> 0).
        """
        f = self.fields
        f["actuator_gainprm"][:, :, 0] = kp
        f["actuator_biasprm"][:, :, 1] = -kp
        f["actuator_biasprm"][:, :, 2] = -kd
        f["actuator_forcerange"][:, :, 0] = -tau_limit
        f["actuator_forcerange"][:, :, 1] = tau_limit

    def set_state(
        self, env_ids: np.ndarray, q: np.ndarray, object_pos: np.ndarray, object_quat: np.ndarray
    ) -> None:
        """Reset `env_ids` at rest: arm at `q` (K, J), object at pos (K, 3) / quat (K, 4).

        The impedance reference (ctrl) is set to `q` as well, so the arm holds its start and
        no joint pushes against its Coulomb friction: at rest, the only constraint forces on
        the arm are then contacts (`robot_init.arm_in_contact` relies on that).
        """
        self.batch.reset(env_ids, stage=mujoco.mjtStage.mjSTAGE_NONE)
        w = self.world
        self.qpos[np.ix_(env_ids, w.robot_qpos)] = q
        self.ctrl[env_ids] = q
        self.qpos[np.ix_(env_ids, w.object_qpos[:3])] = object_pos
        self.qpos[np.ix_(env_ids, w.object_qpos[3:])] = object_quat
        self.qvel[env_ids] = 0.0
        self.batch.forward(env_ids)

    def step(self, q_ref: np.ndarray, substeps: int) -> None:
        """Advance every environment by one policy step.

        Args:
            q_ref: (B, S, J) joint references, rad, one per control sample.
            substeps: physics steps per control sample (each sample is held for them).
        """
        control = np.repeat(q_ref, substeps, axis=1)  # (B, S*substeps, J)
        self.batch.rollout(control.shape[1], control=control, control_spec=CTRL, record=())
        self.batch.forward()

    def snapshot(self) -> dict[str, np.ndarray]:
        """Copies of every environment's integration state (`mjSTATE_INTEGRATION` rows:
        positions, velocities, warm start, controls, time) and of its per-environment model
        fields (`model.<name>`)."""
        fields = {f"model.{name}": values.copy() for name, values in self.fields.items()}
        return {"state": self.batch.state.copy(), **fields}

    def restore(self, arrays: dict[str, np.ndarray]) -> None:
        """Continue from `snapshot`'s arrays: model fields and the constants MuJoCo derives
        from them, then the state, with its derived fields recomputed."""
        for name, values in self.fields.items():
            values[...] = arrays[f"model.{name}"]
        self.batch.set_const()
        self.batch.state[...] = arrays["state"]
        self.batch.forward()

    def bind(self, name: str) -> np.ndarray:
        """(B, ...) live view of an MjData field (outputs are current after `step`)."""
        return self.batch.bind(name)
