"""How the sim drives the FR3: physics timestep, integrator and the joint impedance law.

The robot itself (limits, model file, kinematics) is `hamnet.fr3`.

Physics timestep: 2.5 ms with MuJoCo's `implicitfast` integrator. The control design is a
joint impedance `tau = kp*(q_ref - q) - kd*qdot`, kp in [10, 200], kd = rho*sqrt(kp),
rho in [0.3, 2.0], on top of the gravity compensation the FR3 does itself. Why 2.5 ms
(figures from `benchmarks/sim_timestep.py`):

- It divides both clocks of the design: 5 physics steps per 80 Hz torque tick (the authors'
  0.0125 s) and 40 per 10 Hz policy action.
- Impedance loop. The FR3's reflected motor inertia (armature 0.195 kg m^2 on joints 1-4,
  0.074 on 5-7, Menagerie's identification) is a large part of each joint's inertia. A
  0.2 rad step with kp=200, torque recomputed every physics step, ends where it ends at
  1 ms at every timestep up to 5 ms with the nominal armature and up to 3.125 ms at the low
  end of its per-episode randomization (0.7x, `JointDynamicsRandomization`), with the
  identified joint friction and with none (the floor of the compensated arm's, the sim's
  default). With rho=2 it settles to within 0.0025 rad (the identified friction's dead
  band, frictionloss/kp <= 0.006 rad), or to 0 without friction; at 0.7x armature it misses
  by 0.021-0.023 rad at 5 ms, 0.043-0.045 at 6.25 ms and 0.11 at 10 ms. With rho=0.3 and
  no friction the arm still rings 2.5 s after the step (0.022 rad, the same at every
  timestep: the light damping, not the integrator). 2.5 ms keeps a 2x margin. Holding the
  torque for a whole 80 Hz tick leaves 0.05-0.15 rad at any timestep (rho=2), so the sim
  evaluates the impedance at every physics step (400 Hz; MuJoCo's actuators do it,
  `world.py`).
- Contact. A 5 cm, 0.1 kg box dropped on a table rests (speed < 1e-8 m/s, 0.11 mm
  penetration) at 1-10 ms. Swept by the paddle at about 1.2 m/s, the box ends 5-18 mm from a
  0.2 ms reference at 1-3.125 ms (the impact is chaotic), 20-34 mm at 5-6.25 ms, 121 mm at
  10 ms and 315 mm at 12.5 ms, where MuJoCo must also soften every contact (its default
  solref time constant, 0.02 s, needs a timestep <= 0.01 s). 2.5 ms keeps a 2-4x margin on
  both and leaves room for stiffer contacts (time constants down to 5 ms).
- Cost: about 11 us per step (FR3, table, one box, one core), 0.45 ms of physics per
  action, with the identified friction's seven constraint rows; 8 us without them (MuJoCo
  adds a row only where frictionloss > 0).
`implicitfast` gives the same trajectories as `Euler` for this model (joint damping is
implicit in both and these motors have no velocity term) at the same cost; it is chosen
because it also integrates the velocity term of the sim's impedance actuators (kd)
implicitly. RK4 costs 3.6x per step (40 us) and cannot help the impedance loop, whose torque
stays fixed over a step; 10 ms divides neither clock.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import mujoco
import numpy as np

TIMESTEP = 0.0025
"""MuJoCo physics timestep in s (the model file's `<option timestep>`; see module docstring)."""

INTEGRATOR = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
"""MuJoCo integrator (the model file's `<option integrator>`)."""

FrictionMode = Literal["compensated", "identified"]
"""Which joint friction the impedance law meets (`JOINT_FRICTION`)."""


@dataclass(frozen=True)
class JointFriction:
    """The arm's Coulomb friction in one mode, as fractions of the model file's identified
    values (1.137 N m on joints 1-4, 0.763, 0.44, 0.248 on 5-7)."""

    nominal: float
    """Nominal friction, fraction of the identified."""
    factor: tuple[float, float]
    """Default per-episode factor on `nominal` (uniform)."""


JOINT_FRICTION: dict[FrictionMode, JointFriction] = {
    # The FR3's torque interface takes "joint-level torque commands without gravity and
    # friction" (libfranka franka::Torques; Franka's FCI overview: "gravity & friction
    # compensated joint level torque commands"): the robot compensates its own friction and
    # the controller meets only what compensation leaves. No figure for that residual is
    # published. The authors' fallback sysid (`sysid_friction`,
    # ham/src/ham/env/robot/franka.py:944-951; their run's new_sysid.pkl is not released)
    # has 0.00174 and 0.01 on joints 1-2 and about 0 on 3-4, 0.2-0.9% of the identified
    # 1.137 N m (Isaac Gym DOF friction, which PhysX applies as a coefficient, so not
    # strictly N m). Ours: 5% nominal (0.057 N m on joints 1-4), drawn per episode from
    # perfect compensation (0) to 10% (0.114 N m) for imperfect compensation.
    "compensated": JointFriction(nominal=0.05, factor=(0.0, 2.0)),
    # Menagerie's identification as it stands, for a driver that does not compensate
    # friction; harmonic-drive friction changes by tens of percent with temperature and load.
    "identified": JointFriction(nominal=1.0, factor=(0.5, 1.5)),
}
"""Every friction mode by name."""


@dataclass(frozen=True)
class JointDynamicsRandomization:
    """Per-episode factors on the FR3's identified joint parameters (model file: Menagerie's
    armature, damping and Coulomb friction), one factor per parameter for all seven joints,
    uniform in each range; the friction is the mode's (`JOINT_FRICTION`). The authors train
    with one fixed identification (ham/src/ham/env/robot/franka.py:937-984,
    `joint_param_file`, rss_train.yaml:119) and do not randomize these; ranges are ours:
    wide enough to cover an identification on another arm or at another temperature, narrow
    enough that the 2.5 ms timestep keeps its margin at the low armature end (module
    docstring)."""

    armature: tuple[float, float] = (0.7, 1.3)
    """Factor on the armature (0.195 / 0.074 kg m^2), the term the timestep depends on."""
    damping: tuple[float, float] = (0.5, 2.0)
    """Factor on the viscous damping (0.21 N m s/rad); small next to any kd = rho sqrt(kp)
    >= 0.95, so a wide range costs nothing."""
    friction_mode: FrictionMode = "compensated"
    """Joint friction the controller meets: compensated (what the FR3 leaves after
    compensating its own friction, as under libfranka's torque interface: 5% of the
    identified, 0-10% per episode) or identified (Menagerie's 1.137 ... 0.248 N m, 0.5-1.5x
    per episode, for a driver that does not compensate friction)."""
    friction: tuple[float, float] | None = None
    """Factor on the mode's nominal friction; None: the mode's own range."""

    def __post_init__(self) -> None:
        for name in ("armature", "damping"):
            low, high = getattr(self, name)
            if not 0.0 < low <= high:
                raise ValueError(f"{name} must be 0 < low <= high, got {(low, high)}")
        if self.friction_mode not in JOINT_FRICTION:
            known = ", ".join(JOINT_FRICTION)
            raise ValueError(f"friction_mode must be one of {known}, got {self.friction_mode!r}")
        low, high = self.friction_factor
        if not 0.0 <= low <= high:
            raise ValueError(f"friction must be 0 <= low <= high, got {(low, high)}")

    @property
    def friction_factor(self) -> tuple[float, float]:
        """Per-episode factor range on the mode's nominal friction."""
        mode = JOINT_FRICTION[self.friction_mode]
        return self.friction if self.friction is not None else mode.factor

    @property
    def friction_scale(self) -> tuple[float, float]:
        """Range of the friction column: friction as a fraction of the identified."""
        nominal = JOINT_FRICTION[self.friction_mode].nominal
        low, high = self.friction_factor
        return nominal * low, nominal * high


def draw_joint_dynamics(
    rng: np.random.Generator, ranges: JointDynamicsRandomization, count: int
) -> np.ndarray:
    """(count, 3) factors on the model file's armature, damping and friction
    (`hamnet.task.physics.JOINT_DYNAMICS_NAMES`); the friction's includes the mode's
    nominal."""
    bounds = np.array([ranges.armature, ranges.damping, ranges.friction_scale])  # (3, 2)
    return rng.uniform(bounds[:, 0], bounds[:, 1], size=(count, 3))


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
