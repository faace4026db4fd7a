"""The FR3 model: MuJoCo and Pinocchio agree, the file equals the limits, and the chosen
timestep keeps the impedance loop and box contacts stable."""

from __future__ import annotations

import fnmatch
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest
import tomllib

import hamnet.fr3
from hamnet.fr3 import limits as fr3_limits
from hamnet.fr3 import model as fr3_model
from hamnet.fr3.limits import FR3, Q_HOME
from hamnet.sim import robot
from hamnet.sim.robot import impedance_torque

ROOT = Path(__file__).resolve().parents[2]
TOLERANCE = 1e-9
"""MuJoCo and Pinocchio evaluate the same chain in double precision: they agree to ~1e-14."""


@pytest.fixture(scope="module")
def mj_model() -> mujoco.MjModel:
    return fr3_model.load_mujoco()


@pytest.fixture(scope="module")
def pin_model() -> tuple[pin.Model, pin.Data]:
    return fr3_model.load_pinocchio()


def random_configurations(count: int, seed: int = 0) -> np.ndarray:
    """Uniform joint configurations within the FR3 limits, (count, J)."""
    return np.random.default_rng(seed).uniform(FR3.q_min, FR3.q_max, size=(count, 7))


def add_table_and_box(spec: mujoco.MjSpec, top: float, box_pos: list[float]) -> None:
    """A 0.5 x 0.7 m table in front of the robot with its top at `top`, and a free 5 cm,
    0.1 kg box at `box_pos`; both keep MuJoCo's default contact bits, like scene geoms."""
    spec.worldbody.add_geom(
        name="table",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        pos=[0.55, 0, top / 2],
        size=[0.25, 0.35, top / 2],
    )
    box = spec.worldbody.add_body(name="box", pos=box_pos)
    box.add_freejoint(name="box")
    box.add_geom(name="box", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.025] * 3, mass=0.1)


# MuJoCo and Pinocchio agree ------------------------------------------------------------


def test_mujoco_and_pinocchio_give_the_same_ee_pose(mj_model, pin_model) -> None:
    data = mujoco.MjData(mj_model)
    for q in random_configurations(50):
        mj_pos, mj_rot = fr3_model.mujoco_ee_placement(mj_model, data, q)
        pin_pos, pin_rot = fr3_model.pinocchio_ee_placement(*pin_model, q)
        np.testing.assert_allclose(mj_pos, pin_pos, atol=TOLERANCE)
        np.testing.assert_allclose(mj_rot, pin_rot, atol=TOLERANCE)


def test_mujoco_and_pinocchio_give_the_same_ee_jacobian(mj_model, pin_model) -> None:
    data = mujoco.MjData(mj_model)
    for q in random_configurations(50, seed=1):
        mj_jac = fr3_model.mujoco_ee_jacobian(mj_model, data, q)
        assert mj_jac.shape == (6, 7)
        pin_jac = fr3_model.pinocchio_ee_jacobian(*pin_model, q)
        np.testing.assert_allclose(mj_jac, pin_jac, atol=TOLERANCE)


def test_jacobian_is_the_derivative_of_the_pose(mj_model) -> None:
    """Agreement alone would not catch both libraries sharing a wrong convention (local
    frame, angular rows first): central differences of the pose pin the convention down."""
    data = mujoco.MjData(mj_model)
    eps = 1e-6
    for q in random_configurations(5, seed=2):
        jac = fr3_model.mujoco_ee_jacobian(mj_model, data, q)
        _, rot = fr3_model.mujoco_ee_placement(mj_model, data, q)
        for joint in range(7):
            step = np.zeros(7)
            step[joint] = eps
            pos_plus, rot_plus = fr3_model.mujoco_ee_placement(mj_model, data, q + step)
            pos_minus, rot_minus = fr3_model.mujoco_ee_placement(mj_model, data, q - step)
            skew = (rot_plus - rot_minus) @ rot.T / (2 * eps)  # dR/dq R^T = [omega]x
            angular = np.array([skew[2, 1], skew[0, 2], skew[1, 0]])
            linear = (pos_plus - pos_minus) / (2 * eps)
            np.testing.assert_allclose(jac[:3, joint], linear, atol=1e-7)
            np.testing.assert_allclose(jac[3:, joint], angular, atol=1e-7)


def test_mujoco_and_pinocchio_give_the_same_dynamics(mj_model, pin_model) -> None:
    """Masses, inertias and armature must parse alike too, or safety's model and the sim's
    physics would differ: joint-space inertia matrix and gravity torque."""
    pin_m, pin_d = pin_model
    data = mujoco.MjData(mj_model)
    for q in random_configurations(10, seed=3):
        data.qpos[:] = q
        mujoco.mj_forward(mj_model, data)
        mass_matrix = np.zeros((7, 7))
        mujoco.mj_fullM(mj_model, data, mass_matrix)
        np.testing.assert_allclose(mass_matrix, pin.crba(pin_m, pin_d, q), atol=1e-9)
        gravity = pin.computeGeneralizedGravity(pin_m, pin_d, q)
        np.testing.assert_allclose(data.qfrc_gravcomp, gravity, atol=1e-9)


# The published FR3's dynamics -------------------------------------------------------------

MENAGERIE_FR3 = Path(__file__).resolve().parent / "menagerie_fr3.xml"
"""MuJoCo Menagerie's franka_fr3 (links 0-7, inertials and joints verbatim; see its header)."""


def inertia_matrix(model: mujoco.MjModel, q: np.ndarray) -> np.ndarray:
    """Joint-space inertia matrix M(q) of the first 7 dofs, armature included, (J, J)."""
    data = mujoco.MjData(model)
    data.qpos[:7] = q
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    return full[:7, :7]


def test_inertia_matrix_is_the_published_fr3s() -> None:
    """M(q) with armature, paddle removed, against Menagerie's FR3 (hand removed) over 100
    random configurations: within 10% in the matrix norm and on every diagonal entry. The
    Panda identification with Franka's reflected motor inertias used before was 41% off in
    the norm and 184% on a diagonal entry."""
    ours = fr3_model.load_mujoco()
    paddle = ours.body("fr3_paddle").id
    ours.body_mass[paddle] = 0.0
    ours.body_inertia[paddle] = 0.0
    reference = mujoco.MjModel.from_xml_path(str(MENAGERIE_FR3))
    for q in random_configurations(100, seed=4):
        m_ours, m_ref = inertia_matrix(ours, q), inertia_matrix(reference, q)
        assert np.linalg.norm(m_ours - m_ref, 2) <= 0.1 * np.linalg.norm(m_ref, 2)
        np.testing.assert_allclose(np.diag(m_ours), np.diag(m_ref), rtol=0.1)


def test_joint_parameters_are_the_identified_fr3s(mj_model) -> None:
    """Armature, damping and Coulomb friction equal Menagerie's identified FR3 values."""
    reference = mujoco.MjModel.from_xml_path(str(MENAGERIE_FR3))
    dofs = fr3_model.robot_dof_index(mj_model)
    for name in ("dof_armature", "dof_damping", "dof_frictionloss"):
        np.testing.assert_array_equal(getattr(mj_model, name)[dofs], getattr(reference, name))


def test_link_masses_are_franka_cad_masses(mj_model) -> None:
    masses = [mj_model.body(f"fr3_link{i}").mass[0] for i in range(1, 8)]
    np.testing.assert_allclose(masses, [2.93, 2.94, 2.24, 2.62, 2.33, 1.82, 0.63], atol=0.006)


def test_zero_configuration_matches_published_kinematics(mj_model) -> None:
    """At q = 0 the flange is at (a7, 0, d1 + d3 + d5 - d_flange) pointing down, and the
    paddle face 0.09 m further."""
    pos, rot = fr3_model.mujoco_ee_placement(mj_model, mujoco.MjData(mj_model), np.zeros(7))
    np.testing.assert_allclose(pos, [0.088, 0.0, 0.333 + 0.316 + 0.384 - 0.107 - 0.09], atol=1e-12)
    np.testing.assert_allclose(rot[:, 2], [0.0, 0.0, -1.0], atol=1e-12)


# The file equals the limits ---------------------------------------------------------------


def test_joint_ranges_equal_the_fr3_limits(mj_model, pin_model) -> None:
    ranges = np.array([mj_model.joint(name).range for name in fr3_limits.JOINT_NAMES])
    np.testing.assert_array_equal(ranges[:, 0], FR3.q_min)
    np.testing.assert_array_equal(ranges[:, 1], FR3.q_max)
    assert mj_model.jnt_limited.all()
    np.testing.assert_array_equal(pin_model[0].lowerPositionLimit, FR3.q_min)
    np.testing.assert_array_equal(pin_model[0].upperPositionLimit, FR3.q_max)


def test_actuators_are_joint_motors_clipped_at_tau_max(mj_model, pin_model) -> None:
    for joint_name, actuator_name, tau_max in zip(
        fr3_limits.JOINT_NAMES, fr3_model.ACTUATOR_NAMES, FR3.tau_max, strict=True
    ):
        actuator = mj_model.actuator(actuator_name)
        assert actuator.trnid[0] == mj_model.joint(joint_name).id
        assert actuator.gear[0] == 1.0 and actuator.biastype == mujoco.mjtBias.mjBIAS_NONE
        assert actuator.ctrllimited
        np.testing.assert_array_equal(actuator.ctrlrange, [-tau_max, tau_max])
        joint = mj_model.joint(joint_name).id
        np.testing.assert_array_equal(mj_model.jnt_actfrcrange[joint], [-tau_max, tau_max])
    np.testing.assert_array_equal(pin_model[0].effortLimit, FR3.tau_max)


def test_model_options_are_the_documented_timestep_and_integrator(mj_model) -> None:
    assert mj_model.opt.timestep == robot.TIMESTEP
    assert mj_model.opt.integrator == robot.INTEGRATOR
    np.testing.assert_array_equal(mj_model.opt.gravity, [0.0, 0.0, -9.81])
    # Whole physics steps per 80 Hz torque tick and per 10 Hz policy action.
    assert (0.0125 / robot.TIMESTEP).is_integer() and (0.1 / robot.TIMESTEP).is_integer()


def test_limit_arrays_are_read_only() -> None:
    with pytest.raises(ValueError):
        FR3.q_max[0] = 10.0
    with pytest.raises(ValueError):
        Q_HOME[0] = 1.0


def test_home_is_inside_the_limits_with_the_paddle_down_in_front(mj_model) -> None:
    assert np.all(Q_HOME > FR3.q_min) and np.all(Q_HOME < FR3.q_max)
    data = mujoco.MjData(mj_model)
    pos, rot = fr3_model.mujoco_ee_placement(mj_model, data, Q_HOME)
    assert 0.4 < pos[0] < 0.6 and abs(pos[1]) < 1e-9 and 0.35 < pos[2] < 0.6
    np.testing.assert_allclose(rot[:, 2], [0.0, 0.0, -1.0], atol=1e-9)
    mujoco.mj_forward(mj_model, data)
    assert data.ncon == 0


# Contact filtering ------------------------------------------------------------------------


def test_robot_geoms_collide_with_the_scene_but_not_with_each_other(mj_model) -> None:
    robot_geoms = range(mj_model.ngeom)
    assert all(mj_model.geom_contype[g] == fr3_model.ROBOT_CONTYPE for g in robot_geoms)
    assert all(mj_model.geom_conaffinity[g] == fr3_model.ROBOT_CONAFFINITY for g in robot_geoms)
    scene_contype, scene_conaffinity = 1, 1  # MuJoCo's defaults
    assert not fr3_model.ROBOT_CONTYPE & fr3_model.ROBOT_CONAFFINITY
    assert (
        fr3_model.ROBOT_CONTYPE & scene_conaffinity or scene_contype & fr3_model.ROBOT_CONAFFINITY
    )


def test_explicit_self_collision_pairs_never_join_adjacent_links(mj_model) -> None:
    assert mj_model.npair > 0
    for geom1, geom2 in zip(mj_model.pair_geom1, mj_model.pair_geom2, strict=True):
        body1, body2 = mj_model.geom_bodyid[geom1], mj_model.geom_bodyid[geom2]
        assert mj_model.body_parentid[body1] != body2 and mj_model.body_parentid[body2] != body1


def test_paddle_touches_a_scene_box() -> None:
    spec = mujoco.MjSpec.from_file(str(fr3_model.model_path()))
    model = fr3_model.load_mujoco()
    data = mujoco.MjData(model)
    ee, _ = fr3_model.mujoco_ee_placement(model, data, Q_HOME)
    add_table_and_box(spec, top=0.2, box_pos=[ee[0], ee[1], ee[2] - 0.02])
    model = spec.compile()
    data = mujoco.MjData(model)
    data.qpos[:7] = Q_HOME
    mujoco.mj_forward(model, data)
    touching = {
        (model.geom(c.geom[0]).name, model.geom(c.geom[1]).name) for c in data.contact[: data.ncon]
    }
    assert touching == {("fr3_paddle_plate", "box")} or touching == {("box", "fr3_paddle_plate")}


def test_the_plate_half_extents_lie_along_the_ee_frames_axes(mj_model) -> None:
    """The scripted pusher keeps the plate's reach clear of the object: that reach is the
    file's 12 x 6 cm plate, whose axes are the ee site's and whose outer face holds it."""
    data = mujoco.MjData(mj_model)
    data.qpos[:7] = Q_HOME
    mujoco.mj_forward(mj_model, data)
    plate = mj_model.geom(fr3_model.PADDLE_PLATE_GEOM).id
    site = mj_model.site(fr3_model.EE_SITE).id
    assert fr3_model.paddle_plate_half_extents() == pytest.approx([0.06, 0.03])
    site_rot = data.site_xmat[site].reshape(3, 3)
    assert data.geom_xmat[plate].reshape(3, 3) == pytest.approx(site_rot, abs=1e-12)
    face = data.geom_xpos[plate] + site_rot[:, 2] * mj_model.geom_size[plate, 2]
    assert face == pytest.approx(data.site_xpos[site], abs=1e-12)


# Control and contact at the chosen timestep --------------------------------------------


def test_impedance_holds_home_under_gravity_within_torque_limits(mj_model) -> None:
    """kp=200, rho=1 for 2 s: the robot's gravity compensation plus the impedance torque
    keep it at home; without gravcomp in the model it would sag by about 0.1 rad."""
    data = mujoco.MjData(mj_model)
    data.qpos[:] = Q_HOME
    for _ in range(round(2.0 / robot.TIMESTEP)):
        tau = impedance_torque(data.qpos, data.qvel, Q_HOME, 200.0, 1.0)
        assert np.all(np.abs(tau) <= FR3.tau_max)
        data.ctrl[:] = tau
        mujoco.mj_step(mj_model, data)
        assert np.all(np.abs(data.qfrc_actuator) <= FR3.tau_max)  # command plus gravity
        assert np.abs(data.qpos - Q_HOME).max() < 1e-4
    assert np.abs(data.qfrc_gravcomp).max() > 10.0  # gravity is there, and compensated


@pytest.mark.parametrize("kp, rho", [(10.0, 0.3), (200.0, 2.0)])
@pytest.mark.parametrize("steps_per_update", [1, 5], ids=["physics_rate", "80Hz"])
def test_step_of_the_reference_is_tracked_stably(
    mj_model, kp: float, rho: float, steps_per_update: int
) -> None:
    """A 0.2 rad step on every joint with the softest and the stiffest gains, torque
    recomputed every physics step or held for an 80 Hz tick: finite, within the speed
    limits, and the error in the last 0.5 s of 3 s is under half the step."""
    data = mujoco.MjData(mj_model)
    data.qpos[:] = Q_HOME
    q_ref = Q_HOME + 0.2
    errors = []
    for step in range(round(3.0 / robot.TIMESTEP)):
        if step % steps_per_update == 0:
            data.ctrl[:] = impedance_torque(data.qpos, data.qvel, q_ref, kp, rho)
        mujoco.mj_step(mj_model, data)
        assert np.all(np.isfinite(data.qpos)) and np.all(np.abs(data.qvel) < FR3.dq_max)
        errors.append(np.abs(q_ref - data.qpos).max())
    assert max(errors[-round(0.5 / robot.TIMESTEP) :]) < 0.1


def test_box_dropped_on_a_table_comes_to_rest() -> None:
    """A 5 cm box dropped from 5 cm onto a table beside the holding robot settles on the
    top: slow, at the right height, upright, after 1.5 s."""
    spec = mujoco.MjSpec.from_file(str(fr3_model.model_path()))
    add_table_and_box(spec, top=0.3, box_pos=[0.55, 0.2, 0.3 + 0.025 + 0.05])
    model = spec.compile()
    data = mujoco.MjData(model)
    qpos, dofs = fr3_model.robot_qpos_index(model), fr3_model.robot_dof_index(model)
    data.qpos[qpos] = Q_HOME
    box = model.joint("box").qposadr[0], model.joint("box").dofadr[0]
    for _ in range(round(1.5 / model.opt.timestep)):
        data.ctrl[:] = impedance_torque(data.qpos[qpos], data.qvel[dofs], Q_HOME, 200.0, 1.0)
        mujoco.mj_step(model, data)
    assert np.abs(data.qvel[box[1] : box[1] + 6]).max() < 1e-3
    assert data.qpos[box[0] + 2] == pytest.approx(0.325, abs=1e-3)
    np.testing.assert_allclose(np.abs(data.qpos[box[0] + 3 : box[0] + 7]), [1, 0, 0, 0], atol=1e-3)


# Packaging ------------------------------------------------------------------------------


def test_model_file_is_declared_package_data() -> None:
    """Without the package-data entry a wheel or Docker image would ship robot.py but not
    fr3.xml; the editable install used here would not notice."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    patterns = config["tool"]["setuptools"]["package-data"]["hamnet.fr3"]
    relative = fr3_model.model_path().relative_to(Path(hamnet.fr3.__file__).parent).as_posix()
    assert any(fnmatch.fnmatch(relative, pattern) for pattern in patterns)


def test_model_loads_in_a_fresh_interpreter_outside_the_repo(tmp_path: Path) -> None:
    """`python -I` from another folder: no repo on sys.path, only the installed package."""
    code = (
        "import hamnet.fr3, pathlib\n"
        "from hamnet.fr3 import model as fr3_model\n"
        "path = fr3_model.model_path()\n"
        "assert path.is_file(), path\n"
        "assert path.is_relative_to(pathlib.Path(hamnet.fr3.__file__).parent), path\n"
        "assert fr3_model.load_mujoco().nu == 7 and fr3_model.load_pinocchio()[0].nq == 7\n"
        "print(path)\n"
    )
    result = subprocess.run(
        [sys.executable, "-I", "-c", code], cwd=tmp_path, capture_output=True, text=True
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().endswith("fr3.xml")
