"""Names and colours of every plotted series, fixed here rather than left to the viewer.

Rerun colours a series by a hash of its entity path, so two series in one plot can share a
colour (`goal` and `success` did, and two pairs of safety stages) and a multi-column series
is labelled `values[0]`. The monitor instead logs, once per series, a static SeriesLines
with a name and a colour from this module: reward terms have their own colours everywhere
(rewards, values, returns), safety stages and modules take the categorical palette by
their index, and any other series the next colour of its plot.
"""

from __future__ import annotations

from hamnet.safety.stats import STAGE_NAMES

Rgb = tuple[int, int, int]

CATEGORICAL: tuple[Rgb, ...] = (
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (127, 127, 127),
    (188, 189, 34),
    (23, 190, 207),
    (0, 0, 128),
    (128, 0, 0),
)
"""Twelve colours a reader tells apart (matplotlib's tab10, then navy and maroon)."""

REWARD_COLOURS: dict[str, Rgb] = {
    "success": (46, 160, 67),
    "goal": (31, 119, 180),
    "contact": (230, 120, 20),
    "total": (60, 60, 60),
}
"""Each reward term's colour (`hamnet.task.rewards.REWARD_NAMES`; a test checks they all
have one), and the sum's."""

STAGE_COLOURS: dict[str, Rgb] = dict(zip(STAGE_NAMES, CATEGORICAL, strict=False))
"""Each safety stage's colour (`hamnet.safety.stats.STAGE_NAMES`), by its order."""


def indexed(index: int) -> Rgb:
    """The categorical colour of series `index` (modules, unknown stages, metrics); past
    twelve the colours repeat."""
    return CATEGORICAL[index % len(CATEGORICAL)]


class Palette:
    """Hands out colours for one plot: known names keep their own, others take the next
    categorical colour not used yet in that plot."""

    def __init__(self, known: dict[str, Rgb] | None = None) -> None:
        self.known = dict(known or {})
        self.given: dict[str, Rgb] = {}

    def colour(self, name: str) -> Rgb:
        """The colour of series `name`, the same on every call."""
        if name not in self.given:
            if name in self.known:
                self.given[name] = self.known[name]
            else:
                used = set(self.given.values()) | set(self.known.values())
                free = [c for c in CATEGORICAL if c not in used]
                self.given[name] = free[0] if free else indexed(len(self.given))
        return self.given[name]
