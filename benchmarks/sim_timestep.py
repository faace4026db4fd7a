"""Evidence for the FR3 physics timestep (hamnet.sim.robot.TIMESTEP): sweeps the MuJoCo timestep
and integrator over the questions that decide it.

Consumes the project's FR3 model; produces four tables and one JSON line:
- impedance loop: worst joint error over the last 0.5 s of a 3 s, 0.2 rad step, for the
  extreme gains, nominal armature and the low end of its per-episode randomization
  (`robot.JointDynamicsRandomization`), with the identified joint friction and with none
  (the floor of the compensated arm's, the sim's default), torque recomputed every step or
  held for 80 Hz;
- box drop: speed and penetration of a 5 cm box 1.5 s after falling onto a table;
- paddle sweep: a 5 cm box swept by the paddle at about 1.2 m/s, final position against a
  0.2 ms reference and peak box speed (an ejected box shows up as metres and m/s);
- cost: median microseconds per mj_step of the sweep scene.
"""

from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np

# Run as a script, so benchmarks/ is on sys.path: the helpers every benchmark shares.
from common import report

from hamnet.fr3 import model as fr3_model
from hamnet.fr3.limits import Q_HOME
from hamnet.sim.robot import JointDynamicsRandomization, impedance_torque

TIMESTEPS = (0.001, 0.002, 0.0025, 0.003125, 0.005, 0.00625, 0.01, 0.0125)
"""Candidates, s; 2.5, 3.125 and 6.25 ms divide both the 80 Hz tick and the 10 Hz action."""
INTEGRATORS = {
    "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
    "euler": mujoco.mjtIntegrator.mjINT_EULER,
    "rk4": mujoco.mjtIntegrator.mjINT_RK4,
}
SWEEP_START = np.array([-0.5, -0.1, 0.0, -2.3, 0.0, 2.2, np.pi / 4])
"""Paddle face at the height of the box's upper half, 0.5 rad to the robot's right."""


def scene(timestep: float, integrator: int, box_pos: list[float], top: float) -> mujoco.MjModel:
    """FR3 + a 0.6 x 1.0 m table with its top at `top` + a free 5 cm, 0.1 kg box."""
    spec = mujoco.MjSpec.from_file(str(fr3_model.model_path()))
    spec.option.timestep, spec.option.integrator = timestep, integrator
    spec.worldbody.add_geom(
        type=mujoco.mjtGeom.mjGEOM_BOX, pos=[0.55, 0, top / 2], size=[0.3, 0.5, top / 2]
    )
    box = spec.worldbody.add_body(pos=box_pos)
    box.add_freejoint()
    box.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.025] * 3, mass=0.1)
    return spec.compile()


def step_error(
    timestep: float, kp: float, rho: float, armature: float, friction: float, hold: int
) -> float:
    """Worst joint error (rad) over the last 0.5 s of a 3 s, 0.2 rad step on every joint,
    with the model file's armature and Coulomb friction scaled by `armature`, `friction`."""
    model = fr3_model.load_mujoco()
    model.opt.timestep = timestep
    model.dof_armature[:] *= armature
    model.dof_frictionloss[:] *= friction
    data = mujoco.MjData(model)
    data.qpos[:] = Q_HOME
    q_ref = Q_HOME + 0.2
    steps, worst = round(3.0 / timestep), 0.0
    for step in range(steps):
        if step % hold == 0:
            data.ctrl[:] = impedance_torque(data.qpos, data.qvel, q_ref, kp, rho)
        mujoco.mj_step(model, data)
        if not np.all(np.isfinite(data.qpos)):
            return float("inf")
        if step >= steps - round(0.5 / timestep):
            worst = max(worst, float(np.abs(q_ref - data.qpos).max()))
    return round(worst, 4)


def box_drop(timestep: float, integrator: int) -> dict[str, float]:
    """Box speed (m/s) and penetration (mm) 1.5 s after a 5 cm drop onto a table."""
    model = scene(timestep, integrator, [0.55, 0.2, 0.375], top=0.3)
    data = mujoco.MjData(model)
    data.qpos[:7] = Q_HOME
    for _ in range(round(1.5 / timestep)):
        data.ctrl[:] = impedance_torque(data.qpos[:7], data.qvel[:7], Q_HOME, 200.0, 1.0)
        mujoco.mj_step(model, data)
    return {
        "speed": float(f"{np.abs(data.qvel[7:13]).max():.1e}"),
        "penetration_mm": round(1000 * (0.325 - data.qpos[9]), 2),
    }


def sweep(timestep: float, integrator: int) -> tuple[np.ndarray, float, float]:
    """Sweep joint 1 through 1 rad in 0.5 s (paddle about 1.2 m/s) across a box, 0.5 s more.

    Returns final box position (3,) m, peak box speed m/s, median us per mj_step."""
    model = scene(timestep, integrator, [0.5, 0.0, 0.295], top=0.27)
    data = mujoco.MjData(model)
    data.qpos[:7] = SWEEP_START
    peak, costs = 0.0, []
    for step in range(round(1.0 / timestep)):
        q_ref = SWEEP_START.copy()
        q_ref[0] += min(1.0, 2.0 * step * timestep)
        data.ctrl[:] = impedance_torque(data.qpos[:7], data.qvel[:7], q_ref, 200.0, 1.0)
        start = time.perf_counter_ns()
        mujoco.mj_step(model, data)
        costs.append(time.perf_counter_ns() - start)
        peak = max(peak, float(np.linalg.norm(data.qvel[7:10])))
    return data.qpos[7:10].copy(), peak, float(np.median(costs)) / 1e3


QUICK_TIMESTEPS = (0.0025, 0.01)
"""`--quick`: the chosen timestep and one that fails."""


def main(timesteps: tuple[float, ...], integrators: dict[str, int]) -> dict:
    implicit = INTEGRATORS["implicitfast"]
    print("impedance step: worst error in the last 0.5 s (rad), kp=200")
    loop = {}
    ranges = JointDynamicsRandomization()
    for friction in (1.0, ranges.friction_scale[0]):
        for armature in (1.0, ranges.armature[0]):
            for timestep in timesteps:
                row = {
                    f"rho={rho} {'80Hz' if hold > 1 else 'every step'}": step_error(
                        timestep, 200.0, rho, armature, friction, hold
                    )
                    for rho in (0.3, 2.0)
                    for hold in (1, max(1, round(0.0125 / timestep)))
                }
                name = f"friction x{friction:g} armature x{armature} dt={timestep * 1e3:g}ms"
                loop[name] = row
                print(f"  {name}", row)
    print("box drop after 1.5 s")
    drops = {f"{t * 1e3:g}ms": box_drop(t, implicit) for t in timesteps}
    for name, result in drops.items():
        print(f"  dt={name}", result)
    print("paddle sweep: box error vs 0.2 ms reference (mm), peak box speed (m/s), us/step")
    reference, _, _ = sweep(0.0002, implicit)
    sweeps = {}
    for name, integrator in integrators.items():
        for timestep in timesteps:
            final, peak, cost = sweep(timestep, integrator)
            key = f"{name} {timestep * 1e3:g}ms"
            sweeps[key] = {
                "error_mm": round(1000 * float(np.linalg.norm(final - reference)), 1),
                "peak_speed": round(peak, 2),
                "us_per_step": round(cost, 1),
            }
            print(f"  {key}", sweeps[key])
    return {"loop": loop, "drop": drops, "sweep": sweeps}


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two timesteps, implicitfast only")
    args = parser.parse_args()
    if args.quick:
        report(main(QUICK_TIMESTEPS, {"implicitfast": INTEGRATORS["implicitfast"]}))
    else:
        report(main(TIMESTEPS, INTEGRATORS))
