"""Rerun view of one procedural scene: its active cuboids and the object's start and goal.

`log_scene` logs into the current (or a given) Rerun recording, so the monitor can call it
at every reset; `save_scene` samples one scene from a seed and writes a `.rrd` file that a
person opens with `rerun file.rrd` (no viewer is spawned, nothing is downloaded), with a
layout (`scene_blueprint`): the 3D view seen from behind and beside the robot, the floor
grid where the robot and the table stand, and a legend of the colours. `spatial_view` is
that 3D view, which the monitor's layout reuses.
Entities: scene/base (table, plates, ramps), scene/case (walls, ceiling, translucent),
scene/start and scene/goal (a point and the object's axes).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from hamnet.sim import quaternion
from hamnet.sim.domains import domain_builder
from hamnet.sim.placement import Placement, sample_placements
from hamnet.sim.scene import (
    CEILING,
    NUM_BASE,
    PLATES,
    RAMPS,
    SceneBatch,
    sample_scenes,
)
from hamnet.sim.scene_config import FLOOR_Z, SceneConfig
from hamnet.sim.world import PEDESTAL_HALF_EXTENT
from hamnet.task.cuboids import CUBOID_NAMES, NUM_CUBOIDS, TABLE


def _slot_colours() -> np.ndarray:
    """RGBA per cuboid slot (N, 4): grey table, tan plates, orange ramps, translucent case."""
    colours = np.empty((NUM_CUBOIDS, 4), dtype=np.uint8)
    colours[TABLE] = (150, 150, 150, 255)
    colours[list(PLATES[0] + PLATES[1])] = (205, 170, 125, 255)
    colours[list(RAMPS[0] + RAMPS[1])] = (230, 140, 60, 255)
    colours[NUM_BASE:CEILING] = (60, 180, 90, 70)
    colours[CEILING] = (60, 180, 90, 50)
    return colours


_COLOURS = _slot_colours()
_POSE_COLOURS = {"start": (220, 50, 50, 255), "goal": (50, 90, 220, 255)}
"""Start red, goal blue, as in the paper's figures."""

EYE = rrb.EyeControls3D(
    kind=rrb.Eye3DKind.Orbital,
    position=(1.9, -1.5, 1.0),
    look_target=(0.45, 0.0, -0.1),
    eye_up=(0.0, 0.0, 1.0),
)
"""The camera a view opens with: ahead of the robot and to its right, a little above the
table, so that the arm (at the origin) and the whole table (ahead, +x) fit in one view."""

LEGEND = """\
**Scene colours.** **Grey** table, **tan** plates, **orange** ramps, **translucent green**
walls and ceiling. The object's start is the **red** point, its goal the **blue** one, each
with the object's axes (x red, y green, z blue). The dark box is the pedestal the robot stands on;
the grid is the floor under it and the table.
"""
"""What the scene's colours mean, shown under the 3D view."""


PEDESTAL_CENTRE_X = -0.05
"""x of the pedestal's centre, m (`hamnet.sim.world.build_spec` places it there)."""


def log_pedestal(recording: rr.RecordingStream | None = None) -> None:
    """The box the robot's base stands on, from the floor up to the base (static): without
    it the robot seems to hover above the floor the table stands on."""
    box = rr.Boxes3D(
        centers=[(PEDESTAL_CENTRE_X, 0.0, FLOOR_Z / 2)],
        half_sizes=[(*PEDESTAL_HALF_EXTENT, -FLOOR_Z / 2)],
        colors=[(90, 90, 100)],
        labels=["pedestal"],
        fill_mode=rr.components.FillMode.Solid,
    )
    rr.log("scene/pedestal", box, static=True, recording=recording)


def spatial_view(name: str, contents: list[str]) -> rrb.Spatial3DView:
    """The 3D view of a scene: `contents` seen from `EYE`, the grid on the floor."""
    return rrb.Spatial3DView(
        origin="/",
        contents=contents,
        name=name,
        eye_controls=EYE,
        line_grid=rrb.LineGrid3D(
            visible=True, spacing=0.1, plane=rr.components.Plane3D((0, 0, 1), FLOOR_Z)
        ),
    )


def scene_blueprint() -> rrb.Blueprint:
    """The layout of a `save_scene` file: the 3D view above the legend."""
    return rrb.Blueprint(
        rrb.Vertical(
            spatial_view("procedural scene", ["+ /scene/**"]),
            rrb.TextDocumentView(origin="/legend", name="legend"),
            row_shares=[6, 1],
        ),
        collapse_panels=True,
    )


def log_cuboids(
    centre: np.ndarray,
    quat: np.ndarray,
    half_extent: np.ndarray,
    active: np.ndarray,
    recording: rr.RecordingStream | None = None,
) -> None:
    """Log one environment's active cuboid slots (centre (N, 3), quat (N, 4) wxyz,
    half_extent (N, 3), active (N,)) as `scene/base` and `scene/case`, coloured by slot."""
    for name, slots in (("base", np.arange(NUM_BASE)), ("case", np.arange(NUM_BASE, NUM_CUBOIDS))):
        shown = slots[active[slots]]  # active slot indices of this group
        rr.log(
            f"scene/{name}",
            rr.Boxes3D(
                centers=centre[shown],
                half_sizes=half_extent[shown],
                quaternions=quat[shown][:, [1, 2, 3, 0]],  # Rerun wants xyzw
                colors=_COLOURS[shown],
                labels=[CUBOID_NAMES[i] for i in shown],
                fill_mode=rr.components.FillMode.Solid,
            ),
            recording=recording,
        )


def log_scene(
    scene: SceneBatch,
    env_index: int,
    placement: Placement | None = None,
    recording: rr.RecordingStream | None = None,
) -> None:
    """Log environment `env_index` of `scene` (and its start and goal, if given).

    Args:
        scene: the sampled scenes.
        env_index: which environment to show.
        placement: goal and start poses of the same batch, or None to show the cuboids only.
        recording: where to log; None logs into the current recording.
    """
    rr.log("scene", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True, recording=recording)
    i = env_index
    log_cuboids(scene.centre[i], scene.quat[i], scene.half_extent[i], scene.active[i], recording)
    if placement is None:
        return
    poses = {
        "start": (placement.start_pos[env_index], placement.start_quat[env_index]),
        "goal": (placement.goal_pos[env_index], placement.goal_quat[env_index]),
    }
    for name, (pos, quat) in poses.items():
        axes = 0.05 * quaternion.to_matrix(quat).T  # (3, 3): rows are the object's x, y, z
        rr.log(
            f"scene/{name}",
            rr.Points3D([pos], radii=0.008, colors=[_POSE_COLOURS[name]], labels=[name]),
            rr.Arrows3D(
                origins=np.tile(pos, (3, 1)),
                vectors=axes,
                colors=[(230, 40, 40), (40, 200, 40), (40, 80, 230)],
            ),
            recording=recording,
        )


def save_scene(
    path: Path,
    seed: int,
    config: SceneConfig | None = None,
    object_radius: float = 0.05,
    object_height: float = 0.08,
    domain: str = "",
) -> None:
    """Sample one scene and its placement from `seed` and write them to the `.rrd` file `path`.

    The object is a stand-in upright cylinder of `object_radius` and `object_height` (m)
    with one stable orientation; an invalid placement is still shown (the cuboids matter).
    `domain` names a benchmark domain (`hamnet.sim.domains`) to draw instead of a procedural
    scene; its cuboids keep the colours of the slots they fill.
    """
    rng = np.random.default_rng(seed)
    sample = domain_builder(domain) if domain else sample_scenes
    scene = sample(rng, np.array([object_height]), config)
    placement = sample_placements(
        rng,
        scene,
        stable_quat=np.array([[[1.0, 0.0, 0.0, 0.0]]]),
        planar_radius=np.array([[object_radius]]),
        rest_height=np.array([[object_height / 2]]),
        top_height=np.array([[object_height]]),
    )
    recording = rr.RecordingStream("hamnet_scene")
    recording.save(path, default_blueprint=scene_blueprint())
    recording.log("legend", rr.TextDocument(LEGEND, media_type="text/markdown"), static=True)
    log_pedestal(recording)
    log_scene(scene, 0, placement, recording=recording)
    recording.flush()
    recording.disconnect()
