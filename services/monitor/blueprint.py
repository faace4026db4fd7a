"""The monitor's default layout in the Rerun viewer (entities as in `hamnet.monitor.view`).

Left, the 3D scene (robot, cuboids, object and goal, clouds) takes most of the width.
Right, top to bottom: the module activations (layer x module heat map, the paper's
figure) beside each module's mean weight over time; reward terms and episodes (success
rate, return); safety (clip rate per stage, event log) and trainer metrics in tabs.
"""

from __future__ import annotations

import rerun.blueprint as rrb

SCENE_CONTENTS = ["+ /robot/**", "+ /scene/**", "+ /object/**", "+ /goal/**", "+ /clouds/**"]
"""What the 3D view shows (everything spatial, nothing else)."""


def blueprint() -> rrb.Blueprint:
    """The default layout, sent with the data to every output."""
    policy = rrb.Horizontal(
        rrb.TensorView(origin="/policy/module_weights", name="module activations (layer x module)"),
        rrb.TimeSeriesView(origin="/policy/modules", name="mean module weight"),
    )
    rewards = rrb.Horizontal(
        rrb.TimeSeriesView(origin="/rewards", name="reward terms (env in focus)"),
        rrb.Vertical(
            rrb.TimeSeriesView(origin="/episodes/success_rate", name="success rate"),
            rrb.TimeSeriesView(origin="/episodes/return", name="episode return (env in focus)"),
        ),
    )
    monitoring = rrb.Tabs(
        rrb.TimeSeriesView(origin="/safety/clip_rate", name="safety: clipped share per stage"),
        rrb.TextLogView(origin="/safety/events", name="safety events"),
        rrb.TimeSeriesView(origin="/trainer", name="trainer metrics"),
        rrb.TimeSeriesView(origin="/policy/values", name="values per reward term"),
        rrb.TextLogView(origin="/episodes/started", name="episodes"),
    )
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="/", contents=SCENE_CONTENTS, name="FR3 and scene"),
            rrb.Vertical(policy, rewards, monitoring),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )
