"""The monitor's core: turns decoded frames (`hamnet.monitor.frames`) into Rerun log calls
on a given recording stream. No Zenoh, no protobuf: tests feed it frames and read the
.rrd back.

Timelines: `step` (the newest `header.step` seen: the sim's step when a sim is watched, the
trainer's iteration when only a trainer publishes; the layout opens on it) and `time` (the
producer's wall-clock stamp); trainer metrics also on `iteration` and `env_transitions`
(the paper's x-axis). Entities (the blueprint in `hamnet.monitor.blueprint` lays them out):

- `robot/<body>`: the FR3 (`hamnet.monitor.robot`), posed every drawn step.
- `scene/base`, `scene/case`, `scene/start`, `scene/goal`: the cuboids and the object's
  start and goal of the current episode (`hamnet.sim.scene_view.log_scene`).
- `object`, `goal`: poses (Transform3D) of the object (privileged state) and of its goal,
  each with the object's surface points under `object/surface`, `goal/surface` (red and
  blue, as in the paper's figures).
- `clouds/object`, `clouds/environment`, `clouds/local`: perception's three clouds.
- `legend`: which colour is which cloud, surface and cuboid (text).
- `policy/module_weights`: the (L, M) module activations (layer x module, the paper's
  figure) and `policy/module_scale` its colour scale; `policy/modules` (each module's
  mean weight over the layers), `policy/values` (one series per reward term).
- `rewards/<term>`, `episodes/success_rate`, `episodes/return`.
- `safety/events` (text log), `safety/clip_rate/<stage>` (share of commands clipped).
- `trainer/<metric>` and `trainer/status`: a note until the first metrics arrive, then
  the latest iteration in one line.

Every plotted series gets a name and a colour once (`hamnet.monitor.palette`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import rerun as rr

from hamnet.monitor.config import ViewConfig
from hamnet.monitor.frames import (
    ActionFrame,
    CloudsFrame,
    EventFrame,
    MetricsFrame,
    SceneFrame,
    StateFrame,
    TransitionFrame,
)
from hamnet.monitor.pacing import SuccessRate
from hamnet.monitor.palette import REWARD_COLOURS, STAGE_COLOURS, Palette, Rgb, indexed
from hamnet.monitor.robot import XYZW, RobotView
from hamnet.sim.scene_view import log_pedestal, log_scene
from hamnet.task.rewards import REWARD_NAMES

OBJECT_RED = (220, 50, 50, 255)
GOAL_BLUE = (50, 90, 220, 120)
"""Current object red, goal blue and translucent, as in the paper's figures."""

CLOUD_COLOURS = {"object": (240, 150, 30), "environment": (120, 120, 120), "local": (40, 190, 90)}
CLOUD_RADIUS = 0.003
"""Point radius of the clouds and surfaces, m."""

LEGEND = """\
**3D colours.** Clouds (perception's inputs): **orange** object cloud, **grey** environment
cloud, **green** local cloud. Object: **red** surface at its current pose, **translucent
blue** at its goal; start and goal as points with axes. Cuboids: grey table, tan plates,
orange ramps, translucent green walls and ceiling, dark pedestal.
"""
"""What the 3D view's colours mean, shown under it."""

NO_METRICS = """\
**No trainer metrics yet**: start `hamnet trainer` (or `hamnet trainer --inprocess --publish`) in this namespace.
"""
"""Shown in place of the learning curves until the first metrics arrive."""

SUCCESS_LABEL = "monitor: last {} episodes of the worker"
SUCCESS_COLOUR: Rgb = (214, 39, 40)
"""The monitor's own success rate (from the sim's transitions): name and colour, beside
the trainer's `success_rate`."""

SCALE_STEPS = 11
"""Cells of the heat map's colour scale (0.0, 0.1, ..., 1.0)."""

WARNING_KINDS = ("REJECTED_NONFINITE", "REJECTED_SHAPE", "WATCHDOG_STOP", "ESTOP_LATCHED")
"""Safety events logged at WARN level; the others at INFO."""


@dataclass(frozen=True)
class _Cuboids:
    """The fields of `SceneBatch` that `log_scene` reads, for one environment (B = 1)."""

    centre: np.ndarray  # (1, C, 3) m
    quat: np.ndarray  # (1, C, 4) wxyz
    half_extent: np.ndarray  # (1, C, 3) m
    active: np.ndarray  # (1, C) bool


@dataclass(frozen=True)
class _StartGoal:
    """The fields of `Placement` that `log_scene` reads, for one environment (B = 1)."""

    start_pos: np.ndarray  # (1, 3) m
    start_quat: np.ndarray  # (1, 4) wxyz
    goal_pos: np.ndarray  # (1, 3) m
    goal_quat: np.ndarray  # (1, 4) wxyz


def pose_transform(pose: np.ndarray) -> rr.Transform3D:
    """Transform3D of a (7,) pose: position (m) and quaternion wxyz."""
    return rr.Transform3D(translation=pose[:3], quaternion=pose[3:][XYZW])


def entity(prefix: str, name: str) -> str:
    """`prefix/name` with each part of a free-form name (reward term, metric) escaped."""
    return "/".join([prefix, *(rr.escape_entity_path_part(p) for p in name.split("/") if p)])


class MonitorView:
    """Logs the stack's messages for one environment in focus into `recording`."""

    def __init__(
        self,
        recording: rr.RecordingStream,
        config: ViewConfig | None = None,
        robot: RobotView | None = None,
    ) -> None:
        self.recording = recording
        self.config = config if config is not None else ViewConfig()
        self.robot = robot if robot is not None else RobotView()
        self.success = SuccessRate(self.config.success_window)
        self.step = 0
        """The newest step seen (trainer metrics are drawn there)."""
        self.episode_return = 0.0
        """Sum of the focus environment's reward terms since its episode started."""
        self._module_names: int | None = None
        """M for which the module series got their names."""
        self._styled: set[str] = set()
        """Series entities that got their name and colour."""
        self.palettes = {
            "rewards": Palette(REWARD_COLOURS),
            "stages": Palette(STAGE_COLOURS),
            "trainer": Palette(trainer_colours()),
        }
        """One palette per group of plots, so a name keeps its colour in its group."""
        self.metrics_seen = False
        """Whether trainer metrics have arrived (until then `trainer/status` says why not)."""
        recording.log("/", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        recording.log("legend", rr.TextDocument(LEGEND, media_type="text/markdown"), static=True)
        recording.log(
            "trainer/status", rr.TextDocument(NO_METRICS, media_type="text/markdown"), static=True
        )
        scale = np.linspace(0.0, 1.0, SCALE_STEPS, dtype=np.float32)[None]  # (1, SCALE_STEPS)
        recording.log(
            "policy/module_scale",
            rr.Tensor(scale, dim_names=("scale", "weight 0 to 1"), value_range=(0.0, 1.0)),
            static=True,
        )
        log_pedestal(recording)
        self.robot.log_geometry(recording)

    def _series(self, path: str, names: list[str], colours: list[Rgb]) -> None:
        """Name and colour the series at `path` (once: SeriesLines logged static)."""
        if path not in self._styled:
            self.recording.log(path, rr.SeriesLines(names=names, colors=colours), static=True)
            self._styled.add(path)

    def _scalar(self, group: str, prefix: str, name: str, value: float, label: str) -> None:
        """Plot `value` at `prefix/name`, named `label`, coloured by palette `group`."""
        path = entity(prefix, name)
        self._series(path, [label], [self.palettes[group].colour(name)])
        self.recording.log(path, rr.Scalars(value))

    def _at(self, step: int, stamp_ns: int) -> None:
        self.step = max(self.step, step)
        self.recording.reset_time()
        self.recording.set_time("step", sequence=step)
        if stamp_ns:
            self.recording.set_time("time", timestamp=np.datetime64(stamp_ns, "ns"))

    def on_state(self, frame: StateFrame) -> None:
        """The robot posed at q, the object and its goal."""
        self._at(frame.step, frame.stamp_ns)
        self.robot.log_pose(frame.q, self.recording)
        if frame.object_pose is not None:
            self.recording.log("object", pose_transform(frame.object_pose))
        self.recording.log("goal", pose_transform(frame.goal_pose))

    def on_scene(self, frame: SceneFrame) -> None:
        """A new episode: its cuboids, start and goal, and the object's surface."""
        self._at(frame.step, frame.stamp_ns)
        rec = self.recording
        cuboids = _Cuboids(
            frame.centre[None], frame.quat[None], frame.half_extent[None], frame.active[None]
        )
        start_goal = _StartGoal(
            frame.start_pose[None, :3],
            frame.start_pose[None, 3:],
            frame.goal_pose[None, :3],
            frame.goal_pose[None, 3:],
        )
        log_scene(cuboids, 0, start_goal, recording=rec)  # type: ignore[arg-type]
        for name, colour in (("object", OBJECT_RED), ("goal", GOAL_BLUE)):
            points = rr.Points3D(frame.object_points, radii=CLOUD_RADIUS, colors=colour)
            rec.log(f"{name}/surface", points)
        rec.log("object", pose_transform(frame.start_pose))
        rec.log("goal", pose_transform(frame.goal_pose))
        rec.log("episodes/started", rr.TextLog(f"episode {frame.episode_id}: {frame.object_id}"))
        self.episode_return = 0.0

    def on_clouds(self, frame: CloudsFrame) -> None:
        """Perception's object, environment and local clouds."""
        self._at(frame.step, frame.stamp_ns)
        for name, colour in CLOUD_COLOURS.items():
            points = getattr(frame, name)  # (P, 3)
            cloud = rr.Points3D(points, radii=CLOUD_RADIUS, colors=colour, labels=f"{name} cloud")
            self.recording.log(f"clouds/{name}", cloud)

    def on_action(self, frame: ActionFrame) -> None:
        """Module activations (L, M), each module's mean weight, and the values."""
        self._at(frame.step, frame.stamp_ns)
        rec = self.recording
        if frame.module_weights is not None:
            weights = frame.module_weights  # (L, M)
            rec.log(
                "policy/module_weights",
                rr.Tensor(weights, dim_names=("layer", "module"), value_range=(0.0, 1.0)),
            )
            modules = weights.shape[1]
            if self._module_names != modules:
                names, colours = (
                    [f"module {m}" for m in range(modules)],
                    list(map(indexed, range(modules))),
                )
                rec.log("policy/modules", rr.SeriesLines(names=names, colors=colours), static=True)
                self._module_names = modules
            rec.log("policy/modules", rr.Scalars(weights.mean(axis=0)))  # (M,)
        if frame.values is not None:
            terms = value_names(len(frame.values))
            colours = [self.palettes["rewards"].colour(t) for t in terms]
            self._series("policy/values", [f"value: {t}" for t in terms], colours)
            rec.log("policy/values", rr.Scalars(frame.values))  # (R,)

    def on_transition(self, frame: TransitionFrame) -> None:
        """Reward terms (drawn steps), success rate and the focus episode's return."""
        self._at(frame.step, frame.stamp_ns)
        rec = self.recording
        self.episode_return += float(frame.reward_terms.sum())
        if frame.drawn:
            for name, value in zip(frame.reward_names, frame.reward_terms, strict=True):
                self._scalar("rewards", "rewards", name, float(value), name)
        if self.success.add(frame.done, frame.success):
            self._series(
                "episodes/success_rate",
                [SUCCESS_LABEL.format(self.config.success_window)],
                [SUCCESS_COLOUR],
            )
            rec.log("episodes/success_rate", rr.Scalars(self.success.rate))
        if frame.done[self.config.env]:
            self._series("episodes/return", ["return (env in focus)"], [REWARD_COLOURS["total"]])
            rec.log("episodes/return", rr.Scalars(self.episode_return))
            self.episode_return = 0.0

    def on_event(self, frame: EventFrame) -> None:
        """A safety event in the text log; statistics as clip rates per stage."""
        self._at(frame.step, frame.stamp_ns)
        rec = self.recording
        if frame.is_statistics:
            for stage in frame.stages:
                if stage.commands:
                    rate = stage.clipped / stage.commands
                    self._scalar("stages", "safety/clip_rate", stage.stage, rate, stage.stage)
            return
        focus = " (env in focus)" if self.config.env in frame.env_ids else ""
        level = rr.TextLogLevel.WARN if frame.kind in WARNING_KINDS else rr.TextLogLevel.INFO
        text = f"{frame.kind} [{frame.stage}] {frame.reason}; {len(frame.env_ids)} envs{focus}"
        rec.log("safety/events", rr.TextLog(text, level=level))

    def on_metrics(self, frame: MetricsFrame) -> None:
        """Trainer metrics at the newest step seen (the trainer's own step, its iteration,
        when no sim is watched), on the `iteration` and `env_transitions` timelines, and the
        status line in place of the note."""
        self._at(max(self.step, frame.step), frame.stamp_ns)
        rec = self.recording
        rec.set_time("iteration", sequence=frame.iteration)
        transitions = frame.scalars.get("env_transitions")
        if transitions is not None:
            rec.set_time("env_transitions", sequence=int(transitions))
        for name, value in frame.scalars.items():
            self._scalar("trainer", "trainer", name, value, trainer_label(name))
        rec.log(
            "trainer/status",
            rr.TextDocument(status_line(frame), media_type="text/markdown"),
            static=True,
        )
        self.metrics_seen = True


def trainer_colours() -> dict[str, Rgb]:
    """Colours of the trainer metrics that share plots with others: returns per reward
    term as the reward terms, the success rate apart from the monitor's own."""
    colours = {f"return/{term}": colour for term, colour in REWARD_COLOURS.items()}
    return colours | {"success_rate": (44, 160, 44)}


def trainer_label(name: str) -> str:
    """Legend name of trainer metric `name` (`return/goal` -> `return: goal`)."""
    return name.replace("/", ": ")


def value_names(terms: int) -> tuple[str, ...]:
    """Names of `terms` value heads: the reward terms when the count matches."""
    return REWARD_NAMES if terms == len(REWARD_NAMES) else tuple(f"term {i}" for i in range(terms))


def status_line(frame: MetricsFrame) -> str:
    """One line on the latest trainer iteration, shown above the learning curves."""
    scalars = frame.scalars
    parts = [f"**iteration {frame.iteration}**"]
    if "env_transitions" in scalars:
        parts.append(f"{scalars['env_transitions'] / 1e6:.3f} M env transitions")
    if "success_rate" in scalars:
        parts.append(f"success rate {scalars['success_rate']:.2f}")
    if "env_steps_per_s" in scalars:
        parts.append(f"{scalars['env_steps_per_s']:.0f} env steps/s")
    return " · ".join(parts)
