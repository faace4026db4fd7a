"""The project's Franka Research 3: limits, home pose, model loading and end-effector maths.

One MJCF file (`assets/fr3.xml`, written from published facts, see its header) feeds both
MuJoCo (simulation) and Pinocchio (safety's Cartesian clipping), so the two agree on the
end-effector pose and Jacobian by construction; tests/sim/test_robot.py checks that they do.
The limits are Franka's FR3 control-parameter table; the joint ranges and torque limits in the
model file must equal them (also checked).

Physics timestep: 2.5 ms with MuJoCo's `implicitfast` integrator. The control design is a
joint impedance `tau = kp*(q_ref - q) - kd*qdot`, kp in [10, 200], kd = rho*sqrt(kp),
rho in [0.3, 2.0], on top of the gravity compensation the FR3 does itself. Why 2.5 ms
(figures from `benchmarks/sim_timestep.py`):

- It divides both clocks of the design: 5 physics steps per 80 Hz torque tick (the authors'
  0.0125 s) and 40 per 10 Hz policy action.
- Impedance loop. The FR3's reflected motor inertia (armature 0.21-0.61 kg m^2) dominates
  each joint's inertia, so with the nominal model a 0.2 rad step converges with kp=200 and
  rho=0.3 or 2 at every timestep up to 12.5 ms, torque recomputed each step or held for an
  80 Hz tick. The margin shows when armature is randomised down to 0.1x: with kp=200, rho=2
  the worst error over the last 0.5 s of 3 s is 0.007 rad at 2 ms, 0.024 at 2.5 ms, 0.063 at
  5 ms and 0.47 at 10 ms; holding the torque for a whole 80 Hz tick leaves 0.45-0.68 rad at
  any timestep. So the sim recomputes the impedance torque every physics step (400 Hz).
- Contact. A 5 cm, 0.1 kg box dropped on a table rests (speed < 1e-8 m/s, 0.11 mm
  penetration) at 1-10 ms. Swept by the paddle at about 1.2 m/s, the box ends 27-31 mm from a
  0.2 ms reference at 1-5 ms (the impact is chaotic), 47 mm at 6.25 ms, but 1.1 m away at
  10 ms (ejected at 4.3 m/s), and at 12.5 ms MuJoCo must soften every contact (its default
  solref time constant, 0.02 s, needs a timestep <= 0.01 s). 2.5 ms keeps a 4x margin on
  both and leaves room for stiffer contacts (time constants down to 5 ms).
- Cost: about 8 us per step (FR3, table, one box, one core), 0.3 ms of physics per action.
`implicitfast` gives the same trajectories as `Euler` for this model today (joint damping is
implicit in both and the motors have no velocity term) at the same cost; it is chosen because
it also integrates any velocity-dependent actuator force (a kv term) implicitly. RK4 survives
the 10 ms sweep, at 3.7x the cost per step (about four 2.5 ms steps), but it cannot help the
impedance loop, whose torque stays fixed over a step (0.1x armature: 0.42 rad at 10 ms), and
10 ms divides neither clock.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

TIMESTEP = 0.0025
"""MuJoCo physics timestep in s (the model file's `<option timestep>`; see module docstring)."""

INTEGRATOR = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
"""MuJoCo integrator (the model file's `<option integrator>`)."""

JOINT_NAMES = tuple(f"fr3_joint{i}" for i in range(1, 8))
"""Joint names in the model, in the order of every joint-space array (J = 7)."""

ACTUATOR_NAMES = tuple(f"fr3_motor{i}" for i in range(1, 8))
"""Torque motors, one per joint, same order as JOINT_NAMES."""

EE_SITE = "ee"
"""Site (MuJoCo) and frame (Pinocchio) at the centre of the paddle's contact face."""

ROBOT_CONTYPE = 2
"""contype of every robot geom: scene geoms (contype 1) do not match it..."""

ROBOT_CONAFFINITY = 1
"""...but robot geoms accept contype 1, so robot-scene pairs collide and robot-robot do not."""


def _frozen(values: list[float]) -> np.ndarray:
    array = np.array(values, dtype=np.float64)
    array.setflags(write=False)
    return array


@dataclass(frozen=True)
class FR3Limits:
    """Franka's FR3 control-parameter table (docs: Facts about the dependencies)."""

    q_min: np.ndarray = field(
        default_factory=lambda: _frozen(
            [-2.9007, -1.8361, -2.9007, -3.0770, -2.8763, 0.4398, -3.0508]
        )
    )
    """Lower joint position limits, (J,), rad."""
    q_max: np.ndarray = field(
        default_factory=lambda: _frozen([2.9007, 1.8361, 2.9007, -0.1169, 2.8763, 4.6216, 3.0508])
    )
    """Upper joint position limits, (J,), rad."""
    dq_max: np.ndarray = field(
        default_factory=lambda: _frozen([2.62, 2.62, 2.62, 2.62, 5.26, 4.18, 5.26])
    )
    """Joint speed limits, (J,), rad/s."""
    ddq_max: np.ndarray = field(default_factory=lambda: _frozen([10.0] * 7))
    """Joint acceleration limits, (J,), rad/s^2."""
    jerk_max: np.ndarray = field(default_factory=lambda: _frozen([5000.0] * 7))
    """Joint jerk limits, (J,), rad/s^3."""
    tau_max: np.ndarray = field(default_factory=lambda: _frozen([87.0] * 4 + [12.0] * 3))
    """Joint torque limits, (J,), N m (symmetric: the model's ctrlrange is +-tau_max)."""
    dtau_max: np.ndarray = field(default_factory=lambda: _frozen([1000.0] * 7))
    """Joint torque rate limits, (J,), N m/s."""
    ee_speed_max: float = 3.0
    """End-effector translational speed limit, m/s."""
    ee_acc_max: float = 9.0
    """End-effector translational acceleration limit, m/s^2."""
    ee_jerk_max: float = 4500.0
    """End-effector translational jerk limit, m/s^3."""
    ee_ang_speed_max: float = 2.5
    """End-effector angular speed limit, rad/s."""
    ee_ang_acc_max: float = 17.0
    """End-effector angular acceleration limit, rad/s^2."""
    ee_ang_jerk_max: float = 8500.0
    """End-effector angular jerk limit, rad/s^3."""


FR3 = FR3Limits()
"""The FR3's limits; arrays are read-only."""

Q_HOME = _frozen([0.0, -0.2, 0.0, -2.0, 0.0, 1.8, np.pi / 4])
"""Home configuration, (J,), rad: paddle face down, about (0.50, 0.00, 0.455) m, above a
table in front of the robot; q6 = q2 - q4 keeps the paddle level, q7 = pi/4 aligns its
edges with the world axes."""


def model_path() -> Path:
    """Path of the FR3 MJCF file, shipped as package data of `hamnet.sim`."""
    return Path(__file__).resolve().parent / "assets" / "fr3.xml"


def load_mujoco() -> mujoco.MjModel:
    """The FR3 as a MuJoCo model (robot only; scenes add their geoms through MjSpec)."""
    return mujoco.MjModel.from_xml_path(str(model_path()))


def load_pinocchio() -> tuple[pin.Model, pin.Data]:
    """The FR3 as a Pinocchio model and a matching data, from the same file."""
    model = pin.buildModelFromMJCF(str(model_path()))
    return model, model.createData()


def robot_qpos_index(model: mujoco.MjModel) -> np.ndarray:
    """qpos addresses of the robot joints, (J,), also in a model with scene bodies added."""
    return np.array([model.joint(name).qposadr[0] for name in JOINT_NAMES])


def robot_dof_index(model: mujoco.MjModel) -> np.ndarray:
    """qvel (dof) addresses of the robot joints, (J,)."""
    return np.array([model.joint(name).dofadr[0] for name in JOINT_NAMES])


def mujoco_ee_pose(
    model: mujoco.MjModel, data: mujoco.MjData, q: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """End-effector pose in the world by MuJoCo.

    Args:
        model: a model holding the FR3 (alone or in a scene).
        data: scratch data for `model`; its robot qpos is overwritten with `q`.
        q: joint positions, (J,), rad.
    Returns:
        position (3,) in m and rotation matrix (3, 3) of site `ee`.
    """
    data.qpos[robot_qpos_index(model)] = q
    mujoco.mj_kinematics(model, data)
    site = model.site(EE_SITE).id
    return data.site_xpos[site].copy(), data.site_xmat[site].reshape(3, 3).copy()


def mujoco_ee_jacobian(model: mujoco.MjModel, data: mujoco.MjData, q: np.ndarray) -> np.ndarray:
    """End-effector Jacobian by MuJoCo, world-aligned at site `ee`.

    Args:
        model, data: as in `mujoco_ee_pose` (data is scratch).
        q: joint positions, (J,), rad.
    Returns:
        (6, J): rows 0-2 linear velocity (m/s), rows 3-5 angular velocity (rad/s) per rad/s.
    """
    data.qpos[robot_qpos_index(model)] = q
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    jacp = np.zeros((3, model.nv))
    jacr = np.zeros((3, model.nv))
    mujoco.mj_jacSite(model, data, jacp, jacr, model.site(EE_SITE).id)
    return np.vstack([jacp, jacr])[:, robot_dof_index(model)]


def pinocchio_ee_pose(
    model: pin.Model, data: pin.Data, q: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """End-effector pose in the world by Pinocchio: position (3,) m, rotation (3, 3)."""
    pin.framesForwardKinematics(model, data, q)
    placement = data.oMf[model.getFrameId(EE_SITE)]
    return placement.translation.copy(), placement.rotation.copy()


def pinocchio_ee_jacobian(model: pin.Model, data: pin.Data, q: np.ndarray) -> np.ndarray:
    """End-effector Jacobian by Pinocchio, (6, J), same convention as `mujoco_ee_jacobian`."""
    frame = model.getFrameId(EE_SITE)
    return pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED).copy()


def impedance_torque(
    q: np.ndarray, qdot: np.ndarray, q_ref: np.ndarray, kp: np.ndarray, rho: np.ndarray
) -> np.ndarray:
    """Joint impedance torque `kp*(q_ref - q) - kd*qdot` with kd = rho*sqrt(kp).

    Added to the robot's own gravity compensation (the model's gravcomp); recompute it every
    physics step (module docstring). Not clipped: the motors' ctrlrange clips to +-tau_max.

    Args:
        q, qdot, q_ref: (..., J) in rad, rad/s, rad.
        kp: stiffness, (..., J) or broadcastable, N m/rad.
        rho: damping ratio, broadcastable to kp.
    Returns:
        torque, (..., J), N m.
    """
    return kp * (q_ref - q) - rho * np.sqrt(kp) * qdot
