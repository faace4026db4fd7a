"""The progress lines a person reads while a run goes on, one per logged iteration, from
that iteration's metrics row: PPO's, DAgger's, and the rollout workers' part both end with.
"""

from __future__ import annotations

import math


def ppo_line(row: dict[str, float]) -> str:
    """A PPO iteration: budget, rate, success, return and what the update did (and, guided,
    the imitation term)."""
    guide = row.get("guide_loss", math.nan)
    return (
        f"{_budget(row)} | success {row['success_rate']:.2f} over "
        f"{row['episodes']} episodes | return {row.get('return/total', math.nan):.3f} | "
        f"kl {row['approx_kl']:.4f} | clip {row['clip_fraction']:.2f} | grad agreement "
        f"{row['gradient_agreement']:.3f} | value ev {row.get('explained_variance', math.nan):.2f} | "
        f"lr {row['learning_rate']:.1e} | "
        f"log std {row['log_std']:.2f}{'' if math.isnan(guide) else f' | guide {guide:.4f}'}"
        f"{workers_part(row)}"
    )


def dagger_line(row: dict[str, float]) -> str:
    """A DAgger iteration: budget, rate, who acted, the imitation loss (and the velocity
    loss, when on) and success."""
    velocity = row.get("velocity_loss", math.nan)
    return (
        f"{_budget(row)} | beta {row['beta']:.2f} | student acts "
        f"{row['student_share']:.2f} | imitation {row['imitation_loss']:.4f}"
        f"{'' if math.isnan(velocity) else f' | velocity {velocity:.3f}'} | success "
        f"{row['success_rate']:.2f} over {row['episodes']} episodes | return "
        f"{row.get('return/total', math.nan):.3f}{workers_part(row)}"
    )


def workers_part(row: dict[str, float]) -> str:
    """The workers' part of a progress line (empty without workers): each worker's rate, or
    `-` when the iteration did not learn from it, `x` when its token is gone."""
    workers = sorted({k.split("/")[1] for k in row if k.startswith("workers/")})
    if not workers:
        return ""
    parts = []
    for worker in workers:
        rate = row.get(f"workers/{worker}/env_steps_per_s")
        gone = not row.get(f"workers/{worker}/alive", 1)
        parts.append(f"{worker}:{'x' if gone else '-' if rate is None else f'{rate:.0f}'}")
    return (
        f" | workers {int(row['workers_alive'])}/{len(workers)} up ({' '.join(parts)} steps/s), "
        f"{int(row['dropped_partial_rollouts'])} partial dropped"
    )


def _budget(row: dict[str, float]) -> str:
    """Where the run stands: its iteration, transitions so far and rate."""
    return (
        f"it {row['iteration']} | {row['env_transitions'] / 1e6:.2f}M transitions | "
        f"{row['env_steps_per_s']:.0f} env steps/s"
    )
