"""The MuJoCo world of one sim worker, compiled once and shared by all its environments.

One model serves every environment; what differs per environment is written into
`mujoco.batch.Batch` per-simulation fields (`physics.py`), so no environment needs a model
of its own and stepping stays one call for the whole batch:

- the FR3 (`assets/fr3.xml`) with its torque motors turned into joint-impedance actuators,
  `tau = kp*(q_ref - q) - kd*qdot` evaluated by MuJoCo at every physics step, `q_ref` the
  control input, `kp`, `kd` and the torque clip per environment (gravity compensation is
  added on top, as the FR3 does itself);
- 16 box geoms in the world body, one per scene cuboid slot (`hamnet.task.cuboids`), moved
  and resized per environment;
- one free object body with `MAX_PARTS` convex-part geoms, each of which can take any
  library object's part mesh per environment;
- a parked catalogue: one static, non-colliding body per library object, compiled only so
  that MuJoCo's own values for that object (mesh frames, bounds, inertia axes) can be copied
  into the live object of an environment.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from hamnet.fr3 import limits as fr3_limits
from hamnet.fr3 import model as fr3_model
from hamnet.sim.objects.asset import ObjectAsset
from hamnet.sim.objects.library import ObjectSet
from hamnet.sim.objects.spec import full_inertia
from hamnet.sim.scene_config import FLOOR_Z
from hamnet.task.cuboids import CUBOID_NAMES

MAX_PARTS = 8
"""Convex parts of the live object; library objects with more are rejected."""

OBJECT_BODY = "object"
"""Name of the live object body (its free joint is `object/free`)."""

PEDESTAL_HALF_EXTENT = (0.15, 0.15)
"""Half extents in x, y of the box the robot's base stands on, from the floor up to the
base (the world origin), m: the 0.4 m rise of the authors' `base_height: table`."""

_CATALOGUE_ORIGIN = np.array([0.0, 0.0, -50.0])
"""Where catalogue bodies are parked, far from everything (they never collide anyway)."""

SCENE_BODY = "scene"
"""The mocap body that holds the scene slots in a world built for MuJoCo Warp."""

_LARGE_BOUND = 5.0
"""Half extent, m, of the bounding volumes of bodies whose geoms change per environment."""


@dataclass(frozen=True, eq=False)
class ObjectCatalogue:
    """MuJoCo's compiled values for every library object, ready to copy per environment.

    N objects, P = MAX_PARTS slots; unused slots of an object repeat its first part and are
    marked in `part_used`.
    """

    mesh_id: np.ndarray
    """(N, P) int: mesh of each part slot."""
    part_pos: np.ndarray
    """(N, P, 3) geom position in the object frame, m (MuJoCo centres meshes)."""
    part_quat: np.ndarray
    """(N, P, 4) geom orientation in the object frame, wxyz."""
    part_size: np.ndarray
    """(N, P, 3) compiled geom size."""
    part_rbound: np.ndarray
    """(N, P) bounding-sphere radius, m."""
    part_aabb: np.ndarray
    """(N, P, 6) bounding box in the geom frame: centre and half extents, m."""
    part_used: np.ndarray
    """(N, P) bool."""
    inertia_pos: np.ndarray
    """(N, 3) centre of mass in the object frame, m."""
    inertia_quat: np.ndarray
    """(N, 4) principal axes in the object frame, wxyz."""
    unit_inertia: np.ndarray
    """(N, 3) principal moments per kg, m^2."""


@dataclass(frozen=True, eq=False)
class World:
    """The compiled model and where its parts live in it."""

    model: mujoco.MjModel
    objects: ObjectSet
    catalogue: ObjectCatalogue
    cuboid_geoms: np.ndarray
    """(16,) geom ids of the scene slots, in `CUBOID_NAMES` order."""
    object_body: int
    object_geoms: np.ndarray
    """(P,) geom ids of the live object's part slots."""
    object_qpos: np.ndarray
    """(7,) qpos indices of the object's free joint: position, quaternion wxyz."""
    object_dof: np.ndarray
    """(6,) dof indices of the object's free joint: linear, angular velocity."""
    robot_qpos: np.ndarray
    """(J,) qpos indices of the arm joints."""
    robot_dof: np.ndarray
    """(J,) dof indices of the arm joints."""
    robot_bodies: np.ndarray
    """Ids of the arm's moving bodies (links 1-7 and the paddle)."""
    ee_site: int
    """Site at the paddle's contact face."""


def _impedance_actuators(spec: mujoco.MjSpec) -> None:
    """Turn the FR3's torque motors into joint-impedance actuators.

    force = gain*ctrl + bias0 + bias1*q + bias2*qdot with gain = kp, bias = (0, -kp, -kd)
    is kp*(q_ref - q) - kd*qdot with q_ref = ctrl; kp, kd and the force clip are written per
    environment at every policy step (`physics.BatchPhysics.set_gains`).
    """
    kp = 100.0  # placeholder gains until the first command sets them
    for actuator, q_min, q_max, tau_max in zip(
        spec.actuators,
        fr3_limits.FR3.q_min,
        fr3_limits.FR3.q_max,
        fr3_limits.FR3.tau_max,
        strict=True,
    ):
        actuator.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        actuator.gainprm[0] = kp
        actuator.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        actuator.biasprm[:3] = [0.0, -kp, -2.0 * np.sqrt(kp)]
        actuator.ctrllimited = True
        actuator.ctrlrange = [q_min, q_max]
        actuator.forcelimited = True
        actuator.forcerange = [-tau_max, tau_max]


def _mesh(spec: mujoco.MjSpec, name: str, vertices: np.ndarray, faces: np.ndarray) -> str:
    """Add an object part's mesh once, with the convex-hull data collision needs.

    MuJoCo builds a mesh's hull graph and polygons (`mesh_graphadr`, `mesh_poly*`) only for
    meshes that a colliding geom names, or whose inertia comes from the hull. Catalogue
    geoms never collide, yet the live object takes their meshes per environment: without
    hull data, convex collision of such a mesh returns one contact at the wrong depth, and a
    box sinks and rocks (1-6 cm) into the table. Hull inertia forces the hull for every
    part; parts are convex, so it equals the exact inertia (which is unused anyway: bodies
    set theirs explicitly).
    """
    if spec.mesh(name) is None:
        mesh = spec.add_mesh(name=name, uservert=vertices.ravel(), userface=faces.ravel())
        mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_CONVEX
    return name


def _add_parts(body: mujoco.MjsBody, prefix: str, meshes: list[str], collide: bool) -> None:
    for j, mesh in enumerate(meshes):
        body.add_geom(
            name=f"{prefix}/part{j}",
            type=mujoco.mjtGeom.mjGEOM_MESH,
            meshname=mesh,
            contype=1 if collide else 0,
            conaffinity=1 if collide else 0,
            group=3,
        )


def _object_meshes(spec: mujoco.MjSpec, index: int, asset: ObjectAsset) -> list[str]:
    if len(asset.parts) > MAX_PARTS:
        raise ValueError(f"object {asset.name} has {len(asset.parts)} parts, more than {MAX_PARTS}")
    return [
        _mesh(spec, f"obj{index}/part{j}", part.vertices, part.faces)
        for j, part in enumerate(asset.parts)
    ]


def _padded(meshes: list[str]) -> list[str]:
    return meshes + [meshes[0]] * (MAX_PARTS - len(meshes))


def build_spec(objects: ObjectSet, scene_body: bool = False) -> mujoco.MjSpec:
    """The world's spec: robot, scene slots, floor, live object and catalogue. With
    `scene_body` the scene slots sit on a mocap body at the origin (`SCENE_BODY`) instead
    of the world body: MuJoCo Warp computes the frames of the world body's geoms once, so
    slots moved per environment must belong to a body it poses every step."""
    spec = mujoco.MjSpec.from_file(str(fr3_model.model_path()))
    spec.modelname = "hamnet_world"
    _impedance_actuators(spec)
    world = spec.worldbody
    world.add_geom(
        name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05], pos=[0, 0, FLOOR_Z]
    )
    world.add_geom(
        name="pedestal",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=[*PEDESTAL_HALF_EXTENT, -FLOOR_Z / 2],
        pos=[-0.05, 0.0, FLOOR_Z / 2],
    )
    slots = world.add_body(name=SCENE_BODY, mocap=True) if scene_body else world
    for name in CUBOID_NAMES:
        slots.add_geom(name=f"scene/{name}", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.01] * 3)
    meshes = [_object_meshes(spec, i, asset) for i, asset in enumerate(objects)]
    live = world.add_body(name=OBJECT_BODY, pos=[0.5, 0.0, 0.5])
    live.add_freejoint(name=f"{OBJECT_BODY}/free")
    live.explicitinertial = True
    live.ipos = [0.0, 0.0, 0.0]  # unset, MuJoCo would put the centre of mass at `pos`
    live.mass = 0.1
    live.inertia = [1e-4, 1e-4, 1e-4]
    _add_parts(live, OBJECT_BODY, _padded(meshes[0]), collide=True)
    for i, (asset, names) in enumerate(zip(objects, meshes, strict=True)):
        parked = world.add_body(name=f"catalogue/{i}", pos=list(_CATALOGUE_ORIGIN + [i, 0, 0]))
        parked.explicitinertial = True
        parked.ipos = [0.0, 0.0, 0.0]
        parked.mass = 1.0
        parked.fullinertia = full_inertia(asset.unit_inertia)
        _add_parts(parked, f"catalogue/{i}", _padded(names), collide=False)
    return spec


def _catalogue(model: mujoco.MjModel, objects: ObjectSet) -> ObjectCatalogue:
    bodies = [model.body(f"catalogue/{i}").id for i in range(len(objects))]
    geoms = np.array(
        [
            [model.geom(f"catalogue/{i}/part{j}").id for j in range(MAX_PARTS)]
            for i in range(len(objects))
        ]
    )  # (N, P)
    used = np.array([[j < len(a.parts) for j in range(MAX_PARTS)] for a in objects])  # (N, P)
    return ObjectCatalogue(
        mesh_id=model.geom_dataid[geoms].copy(),
        part_pos=model.geom_pos[geoms].copy(),
        part_quat=model.geom_quat[geoms].copy(),
        part_size=model.geom_size[geoms].copy(),
        part_rbound=model.geom_rbound[geoms].copy(),
        part_aabb=model.geom_aabb[geoms].copy(),
        part_used=used,
        inertia_pos=model.body_ipos[bodies].copy(),
        inertia_quat=model.body_iquat[bodies].copy(),
        unit_inertia=model.body_inertia[bodies].copy(),
    )


def _loosen_bounding_volumes(model: mujoco.MjModel, bodies: list[int]) -> None:
    """Make the bounding volumes of `bodies` cover anything their geoms may become.

    Per-environment geoms change size and place, but a body's bounding-volume hierarchy is
    compiled once; left as compiled, MuJoCo's midphase would skip contacts with a resized
    geom. Large volumes make it test every geom pair instead, which its cheap per-geom
    bounding spheres and boxes then prune.
    """
    for body in bodies:
        start, count = model.body_bvhadr[body], model.body_bvhnum[body]
        model.bvh_aabb[start : start + count] = [0, 0, 0, _LARGE_BOUND, _LARGE_BOUND, _LARGE_BOUND]


def _moving_robot_bodies(model: mujoco.MjModel) -> np.ndarray:
    """Bodies of the arm that move: those below a joint of the FR3 (link0 is fixed)."""
    first = model.jnt_bodyid[model.joint(fr3_limits.JOINT_NAMES[0]).id]
    return np.array([b for b in range(first, model.nbody) if model.body(b).name.startswith("fr3_")])


def _drop_shortcuts(model: mujoco.MjModel, geoms: np.ndarray, body: int, dofs: np.ndarray) -> None:
    """Make MuJoCo read the frames that change per environment.

    The compiler flags a geom whose frame equals its body's (`geom_sameframe`), and a body
    whose inertial frame equals its own (`body_sameframe`, `body_simple`, `dof_simplenum`),
    so that the computation skips `geom_pos`/`geom_quat` or `body_ipos`/`body_iquat`. Those are
    exactly the fields written per environment, so the shortcuts must go.
    """
    model.geom_sameframe[geoms] = 0
    model.body_sameframe[body] = 0
    model.body_simple[body] = 0
    model.dof_simplenum[dofs] = 0


def build_world(objects: ObjectSet, scene_body: bool = False) -> World:
    """Compile the world for an object library (`scene_body`: see `build_spec`)."""
    if len(objects) == 0:
        raise ValueError("the object library is empty")
    model = build_spec(objects, scene_body).compile()
    object_body = model.body(OBJECT_BODY).id
    joint = model.joint(f"{OBJECT_BODY}/free")
    cuboid_geoms = np.array([model.geom(f"scene/{name}").id for name in CUBOID_NAMES])
    object_geoms = np.array([model.geom(f"{OBJECT_BODY}/part{j}").id for j in range(MAX_PARTS)])
    object_dof = np.arange(joint.dofadr[0], joint.dofadr[0] + 6)
    moved = [0, object_body] + ([model.body(SCENE_BODY).id] if scene_body else [])
    _loosen_bounding_volumes(model, moved)
    _drop_shortcuts(model, np.concatenate([cuboid_geoms, object_geoms]), object_body, object_dof)
    return World(
        model=model,
        objects=objects,
        catalogue=_catalogue(model, objects),
        cuboid_geoms=cuboid_geoms,
        object_body=object_body,
        object_geoms=object_geoms,
        object_qpos=np.arange(joint.qposadr[0], joint.qposadr[0] + 7),
        object_dof=object_dof,
        robot_qpos=fr3_model.robot_qpos_index(model),
        robot_dof=fr3_model.robot_dof_index(model),
        robot_bodies=_moving_robot_bodies(model),
        ee_site=model.site(fr3_model.EE_SITE).id,
    )
