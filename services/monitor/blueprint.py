"""The monitor's default layout in the Rerun viewer (entities as in `hamnet.monitor.view`),
made to be kept open during a training run.

Left: the 3D scene (robot, cuboids, object and goal, clouds) seen from beside the robot,
with the legend of its colours under it. Right, top to bottom: the learning curves (the
trainer's return per reward term and success rate beside the monitor's own, with the
trainer's status line, or the note saying why there are none yet); the module activations
(layer x module heat map with its colour scale, each module's mean weight over time); tabs
for the rest (rewards of the env in focus, values, PPO statistics, DAgger statistics,
throughput, safety, episodes). The viewer opens on the `step` timeline.

A training run with no sim in its namespace (`hamnet trainer` with rollout workers, or in
process with `--publish`) gives the scene and the environment in focus nothing to draw, so
its layout (`--layout training`) shows only what it has: the trainer's status line, its
return per reward term and success rate, and below them the update's statistics, DAgger's
and the run's pace, on the `env_transitions` timeline (the paper's x-axis).
"""

from __future__ import annotations

from typing import Literal

import rerun as rr
import rerun.blueprint as rrb

from hamnet.sim.scene_view import spatial_view

Layout = Literal["stack", "training"]
"""stack: the whole stack's view (scene, clouds, modules, rewards, safety, trainer);
training: a trainer's curves alone, for a run whose namespace has no sim."""

DEFAULT_TIMELINE = "step"
"""The timeline the stack's view opens on (wall-clock time would squeeze a run into a sliver)."""
TRAINING_TIMELINE = "env_transitions"
"""The timeline the training view opens on: the paper's x-axis, the same for every run."""

SCENE_CONTENTS = ["+ /robot/**", "+ /scene/**", "+ /object/**", "+ /goal/**", "+ /clouds/**"]
"""What the 3D view shows (everything spatial, nothing else)."""

MODULE_COLORMAP = rr.components.Colormap.Viridis
"""Colour map of the module heat map and of its scale: weight 0 dark blue, 1 yellow."""

PPO_METRICS = (
    "approx_kl",
    "clip_fraction",
    "learning_rate",
    "log_std",
    "policy_loss",
    "value_loss",
)
"""Trainer metrics of the PPO update, one plot each (their scales differ by decades)."""
DAGGER_METRICS = (
    "imitation_loss",
    "imitation_loss_after",
    "beta",
    "student_share",
    "student_episode_success",
    "velocity_loss",
)
"""Trainer metrics of a DAgger run (`hamnet trainer --algo dagger --publish`), one plot each:
the loss on windows before and after they are fitted, who acts, the student's own success
and the velocity read-out's loss (`--dagger.velocity-coef`; empty when off)."""
THROUGHPUT_METRICS = ("env_steps_per_s", "policy_lag", "episode_length")
"""Trainer metrics of the run's pace, one plot each."""


WHOLE_RUN = rrb.TimeAxis(
    view_range=rrb.TimeRange(rrb.TimeRangeBoundary.infinite(), rrb.TimeRangeBoundary.infinite())
)
"""A plot's x-axis over all its data: on `env_transitions` (hundreds of thousands) the
viewer's own default showed only the last few thousand transitions."""


def _plot(
    origin: str, name: str, contents: list[str] | None = None, axis_x: rrb.TimeAxis | None = None
) -> rrb.TimeSeriesView:
    """A time series view with its legend in the top left corner."""
    return rrb.TimeSeriesView(
        origin=origin,
        contents=contents or "$origin/**",
        name=name,
        plot_legend=rrb.PlotLegend(rrb.Corner2D.LeftTop),
        axis_x=axis_x,
    )


def _heat_map(origin: str, name: str) -> rrb.TensorView:
    """A tensor view coloured 0 -> 1 by `MODULE_COLORMAP`."""
    return rrb.TensorView(
        origin=origin, name=name, scalar_mapping=rrb.TensorScalarMapping(colormap=MODULE_COLORMAP)
    )


def learning() -> rrb.Container:
    """The learning curves, with the trainer's status line (or why there is none) above."""
    success = ["+ /trainer/success_rate", "+ /episodes/success_rate"]
    return rrb.Vertical(
        rrb.TextDocumentView(origin="/trainer/status", name="trainer"),
        rrb.Horizontal(
            _plot("/trainer/return", "return per reward term (trainer)"),
            _plot("/", "success rate", success),
        ),
        row_shares=[1, 5],
    )


def modules() -> rrb.Container:
    """The module activations now (with the colour scale) and over time."""
    return rrb.Horizontal(
        rrb.Vertical(
            _heat_map("/policy/module_weights", "module activations (layer x module)"),
            _heat_map("/policy/module_scale", "colour scale: weight 0 to 1"),
            row_shares=[3, 1],
        ),
        _plot("/policy/modules", "mean module weight"),
    )


def update_tabs(axis_x: rrb.TimeAxis | None = None) -> list[rrb.Grid]:
    """The update's statistics, DAgger's and the run's pace: one grid of plots each."""
    groups = {"PPO update": PPO_METRICS, "DAgger": DAGGER_METRICS, "throughput": THROUGHPUT_METRICS}
    return [
        rrb.Grid(*(_plot(f"/trainer/{m}", m, axis_x=axis_x) for m in metrics), name=name)
        for name, metrics in groups.items()
    ]


def details() -> rrb.Container:
    """Everything else, one tab each."""
    return rrb.Tabs(
        _plot("/rewards", "reward terms (env in focus)"),
        _plot("/episodes/return", "episode return (env in focus)"),
        _plot("/policy/values", "values per reward term"),
        *update_tabs(),
        _plot("/safety/clip_rate", "safety: clipped share per stage"),
        rrb.TextLogView(origin="/safety/events", name="safety events"),
        rrb.TextLogView(origin="/episodes/started", name="episodes"),
    )


def panels(timeline: str) -> tuple[rrb.TimePanel, rrb.BlueprintPanel, rrb.SelectionPanel]:
    """The viewer's panels: the time panel collapsed, following the newest data on
    `timeline`; the blueprint and selection panels collapsed."""
    return (
        rrb.TimePanel(timeline=timeline, play_state="following", state="collapsed"),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
    )


def training() -> rrb.Blueprint:
    """The training layout: status line, curves, and the update's tabs under them."""
    curves = rrb.Horizontal(
        _plot("/trainer/return", "return per reward term (trainer)", axis_x=WHOLE_RUN),
        _plot("/trainer/success_rate", "success rate (trainer)", axis_x=WHOLE_RUN),
    )
    view = rrb.Vertical(
        rrb.TextDocumentView(origin="/trainer/status", name="trainer"),
        curves,
        rrb.Tabs(*update_tabs(WHOLE_RUN)),
        row_shares=[1, 6, 6],
    )
    return rrb.Blueprint(view, *panels(TRAINING_TIMELINE))


def blueprint(layout: Layout = "stack") -> rrb.Blueprint:
    """The layout `layout`, sent with the data to every output."""
    if layout == "training":
        return training()
    scene = rrb.Vertical(
        spatial_view("FR3 and scene", SCENE_CONTENTS),
        rrb.TextDocumentView(origin="/legend", name="legend"),
        row_shares=[6, 1],
    )
    return rrb.Blueprint(
        rrb.Horizontal(scene, rrb.Vertical(learning(), modules(), details()), column_shares=[1, 1]),
        *panels(DEFAULT_TIMELINE),
    )
