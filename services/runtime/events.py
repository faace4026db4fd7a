"""Names of the events services count in their health reports that `hamnet up`'s summary
reads beyond printing them (`Service.count_event`)."""

from __future__ import annotations

EPISODES_ENDED = "episodes_ended"
"""The sim: episodes that ended (terminated or truncated), all environments together."""
EPISODES_SUCCEEDED = "episodes_succeeded"
"""The sim: episodes that ended in success."""


def success_line(events: dict[str, int]) -> str | None:
    """`5 of 12 episodes that ended succeeded (0.42)` from a process's event totals; None
    when no episode ended."""
    ended = events.get(EPISODES_ENDED, 0)
    if not ended:
        return None
    succeeded = events.get(EPISODES_SUCCEEDED, 0)
    return f"{succeeded} of {ended} episodes that ended succeeded (success rate {succeeded / ended:.2f})"
