"""What the skills analysis leaves in a run folder: skills.png, skills.rrd and skills.json.

skills.png: the UMAP projection of z_tau coloured by HDBSCAN cluster, unclustered steps in
black (paper Fig. qual-umap), beside the skill timelines of a few episodes (Fig.
inter-phase-route). skills.rrd, opened with `rerun skills.rrd`: every step's point in the
projection, and per episode (entity `episodes/<suite>/episode_<id>`, the id being the index
of its `EpisodeRecord`) its point moving through the projection and its skill as a time
series, both on the `step` timeline; hovering a cluster names its skill, selecting an
episode shows when it used which. skills.json: cluster sizes and every episode's timeline.
"""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only: no display on an evaluation machine
import matplotlib.pyplot as plt
import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from matplotlib.patches import Patch

from hamnet.evaluation.skills import NOISE, Skills, SkillsConfig
from hamnet.trainer.results.plot import save_figure

NOISE_COLOUR = (0.0, 0.0, 0.0, 1.0)
"""Unclustered steps are black, as in the paper's Fig. qual-umap."""

PAST_END = (1.0, 1.0, 1.0, 1.0)
"""Timeline cells after a shorter episode's end (white)."""

LEGEND = """\
**Skills of HAMnet's modulation embedding z_tau.** Left: every policy step's z_tau
projected by UMAP, coloured by HDBSCAN cluster (one skill each; black: no cluster). Under
`episodes/<suite>/episode_<id>` (id: the episode's index in the run's episodes.jsonl), the
episode's `position` moves through the projection along the `step` timeline, and `skill`
plots its cluster per step (-1: none). Hover a point to read its skill.
"""
"""What the Rerun view shows, under the projection."""


def palette(num_clusters: int) -> np.ndarray:
    """(K + 1, 4) RGBA in [0, 1]: row 0 for `NOISE`, row k + 1 for cluster k (tab20)."""
    tab20 = plt.get_cmap("tab20").colors
    cycle = tab20[0::2] + tab20[1::2]  # the ten strong hues first, then their light pairs
    rows = [NOISE_COLOUR] + [(*cycle[k % len(cycle)], 1.0) for k in range(num_clusters)]
    return np.array(rows)


def _class_ids(labels: np.ndarray) -> np.ndarray:
    """(N,) row of `palette` (and Rerun class id) per label: `NOISE` -> 0, cluster k -> k + 1."""
    return labels - NOISE


def _timeline_image(skills: Skills, episodes: list[int], colours: np.ndarray) -> np.ndarray:
    """(E, T_max, 4) RGBA: row e is episode `episodes[e]`'s skill colour per step."""
    timelines = skills.timelines()
    longest = max(len(timelines[episode]) for episode in episodes)
    image = np.tile(PAST_END, (len(episodes), longest, 1))
    for row, episode in enumerate(episodes):
        image[row, : len(timelines[episode])] = colours[_class_ids(timelines[episode])]
    return image


def plot_skills(skills: Skills, out: Path, config: SkillsConfig | None = None) -> Path:
    """Write the projection and `config.timeline_episodes` episodes' timelines to `out` (PNG).

    Args:
        skills: `find_skills`' result.
        out: the PNG to write (its folder is made).
        config: which episodes to draw (the first ids); defaults `SkillsConfig()`.
    Returns:
        `out`.
    """
    config = config or SkillsConfig()
    colours = palette(skills.num_clusters)  # (K + 1, 4)
    point_colours = colours[_class_ids(skills.labels)]  # (N, 4)
    figure = plt.figure(figsize=(13, 6))
    flat = skills.projection.shape[1] == 2
    scatter = figure.add_subplot(1, 2, 1, projection=None if flat else "3d")
    scatter.scatter(*skills.projection.T, c=point_colours, s=2, linewidths=0)
    scatter.set_title(f"UMAP of z_tau, {skills.num_clusters} HDBSCAN clusters")
    handles = [Patch(color=colours[0], label="no cluster")] + [
        Patch(color=colours[k + 1], label=f"skill {k}") for k in range(skills.num_clusters)
    ]
    scatter.legend(handles=handles, fontsize=7, loc="upper left")
    suites = skills.steps.episode_suites()
    shown = list(suites)[: config.timeline_episodes]
    timeline = figure.add_subplot(1, 2, 2)
    if shown:
        timeline.imshow(
            _timeline_image(skills, shown, colours), aspect="auto", interpolation="nearest"
        )
        timeline.set_yticks(range(len(shown)), [f"{suites[e]} #{e}" for e in shown], fontsize=8)
    timeline.set_xlabel("policy step")
    timeline.set_title("skill per step")
    return save_figure(figure, out)


def _as_3d(projection: np.ndarray) -> np.ndarray:
    """(N, 3) points: a 2-D projection on the z = 0 plane, a 3-D one as it is."""
    return np.pad(projection, ((0, 0), (0, 3 - projection.shape[1])))


def skills_blueprint() -> rrb.Blueprint:
    """The projection with the legend under it, the episodes' skill plots beside it."""
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                rrb.Spatial3DView(
                    origin="/",
                    contents=["+ /projection", "+ /episodes/**/position"],
                    name="z_tau (UMAP)",
                ),
                rrb.TextDocumentView(origin="/legend", name="legend"),
                row_shares=[4, 1],
            ),
            rrb.TimeSeriesView(origin="/episodes", contents="+ /episodes/**/skill", name="skill"),
        ),
        rrb.TimePanel(timeline="step"),
    )


def save_skills_view(skills: Skills, path: Path, config: SkillsConfig | None = None) -> Path:
    """Write the Rerun recording of `skills` to `path` (.rrd), `config.view_episodes` of its
    episodes one by one; returns `path`."""
    config = config or SkillsConfig()
    colours = (palette(skills.num_clusters) * 255).astype(np.uint8)  # (K + 1, 4)
    names = ["no cluster"] + [f"skill {k}" for k in range(skills.num_clusters)]
    recording = rr.RecordingStream("hamnet_skills")
    path.parent.mkdir(parents=True, exist_ok=True)
    recording.save(path, default_blueprint=skills_blueprint())
    context = [rr.AnnotationInfo(i, name, colours[i]) for i, name in enumerate(names)]
    recording.log("/", rr.AnnotationContext(context), static=True)
    recording.log("legend", rr.TextDocument(LEGEND, media_type="text/markdown"), static=True)
    points = _as_3d(skills.projection)  # (N, 3)
    class_ids = _class_ids(skills.labels)  # (N,)
    recording.log("projection", rr.Points3D(points, class_ids=class_ids, radii=0.02), static=True)
    suites = skills.steps.episode_suites()
    for episode in list(suites)[: config.view_episodes]:
        rows = np.flatnonzero(skills.steps.episode == episode)
        rows = rows[np.argsort(skills.steps.step[rows])]  # (T,) in step order
        entity = f"episodes/{suites[episode]}/episode_{episode:05d}"
        step = [rr.TimeColumn("step", sequence=skills.steps.step[rows])]
        recording.send_columns(
            f"{entity}/position",
            step,
            rr.Points3D.columns(positions=points[rows], class_ids=class_ids[rows]),
        )
        recording.send_columns(
            f"{entity}/skill", step, rr.Scalars.columns(scalars=skills.labels[rows])
        )
    recording.flush()
    recording.disconnect()
    return path


def write_skills(skills: Skills, folder: Path, config: SkillsConfig | None = None) -> list[Path]:
    """Write skills.png, skills.rrd and skills.json to `folder`; returns their paths.

    skills.json: {"clusters": K, "steps": N, "cluster_steps": {label: steps}, with "-1" for
    unclustered steps, "episodes": [{"episode": id, "suite": s, "skills": [label per step]}]}.
    """
    labels, counts = np.unique(skills.labels, return_counts=True)
    suites = skills.steps.episode_suites()
    summary = {
        "clusters": skills.num_clusters,
        "steps": len(skills.labels),
        "cluster_steps": {str(label): int(n) for label, n in zip(labels.tolist(), counts)},
        "episodes": [
            {"episode": episode, "suite": suites[episode], "skills": timeline.tolist()}
            for episode, timeline in skills.timelines().items()
        ],
    }
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "skills.json").write_text(json.dumps(summary) + "\n")
    return [
        plot_skills(skills, folder / "skills.png", config),
        save_skills_view(skills, folder / "skills.rrd", config),
        folder / "skills.json",
    ]
