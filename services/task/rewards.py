"""The paper's three reward terms by name, in the order of every (B, R) reward array: the
sim's `reward_terms` columns, the Transition message's `reward_names`, the critic's value
heads and the trainer's and monitor's per-term returns.
"""

from __future__ import annotations

REWARD_NAMES = ("success", "goal", "contact")
"""Columns of `reward_terms`: r_s, lambda_r r_r, lambda_c r_c (the proto's reward_names)."""
