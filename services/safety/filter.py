"""`SafetyFilter`: the whole pipeline, from a raw policy action to the references a robot
executes for one policy period.

Stages 1-5 and 7 (`pipeline.SafetyCore`) give a safe joint target and gains; stage 6
(`ruckig_references.TrajectoryGenerator`) turns the target into jerk-limited references
sampled at the executor's rate, continuous across periods; stage 7 runs again against those
samples (gains only go down). With `SafetyConfig.references == "target"` (the "training" and
"finetune" profiles, `config.with_profile`) stage 6 is `references.TargetReferences`: the
target on every sample. `brake` is the watchdog's and the e-stop's path: the references stop
smoothly and hold, with the last safe gains, whatever the policy does.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hamnet.safety.config import SafetyConfig
from hamnet.safety.pipeline import FilterResult, SafetyCore, tau_limit
from hamnet.safety.references import References, TargetReferences, TrajectoryConfig
from hamnet.safety.ruckig_references import TrajectoryGenerator
from hamnet.safety.stages import torque_preclip

BRAKE_MIN_DAMPING_RATIO = 1.0
"""Damping ratio the braking path uses at least."""


@dataclass(frozen=True)
class SafeOutput:
    """One policy period of safe commands (the SafeCommand message)."""

    q_ref: np.ndarray
    """(B, S, J) joint references, rad."""
    dq_ref: np.ndarray
    """(B, S, J) joint velocity references, rad/s."""
    kp: np.ndarray
    """(B, J) N m/rad."""
    kd: np.ndarray
    """(B, J) N m s/rad."""
    tau_limit: np.ndarray
    """(B, J) executor's hard torque clip, N m."""
    stopping: np.ndarray
    """(B,) bool: braking or holding (watchdog, e-stop), not following the policy."""
    references: References
    """What stage 6 planned (plan codes, Ruckig results)."""
    filtered: FilterResult | None = field(default=None)
    """What stages 1-5 and 7 did; None on the braking path."""


class SafetyFilter:
    """Per-environment memory of both halves of the pipeline."""

    def __init__(
        self,
        q: np.ndarray,
        config: SafetyConfig | None = None,
        trajectory: TrajectoryConfig | None = None,
    ) -> None:
        """Start at measured joint positions q (B, J), at rest."""
        self.config = config if config is not None else SafetyConfig()
        self.core = SafetyCore(len(q), self.config)
        self.core.reset(q)
        references = TrajectoryGenerator if self.config.references == "ruckig" else TargetReferences
        self.trajectory = references(q, trajectory)
        self.tau_limit = np.tile(tau_limit(self.config), (len(q), 1))  # (B, J)

    @property
    def num_envs(self) -> int:
        """B."""
        return len(self.tau_limit)

    @property
    def samples_per_period(self) -> int:
        """S: references per policy period."""
        return self.trajectory.config.samples_per_period

    def start_episodes(self, env_ids: np.ndarray, q: np.ndarray) -> None:
        """New episodes in `env_ids` (K,) starting at rest at q (K, J): memory cleared."""
        full = self.core.state.q_target.copy()  # (B, J)
        full[env_ids] = q
        self.core.reset(full, env_ids)
        self.trajectory.reset(env_ids, q)
        self.trajectory.resume(env_ids)

    def snapshot(self) -> tuple[dict[str, np.ndarray], dict[str, object]]:
        """The memory of both halves (stages 1-5 and 7 under `core.`, stage 6's references
        and stop flags), to continue from with `restore`. Only the target references of the
        training and fine-tuning profiles: Ruckig's plans have no state to write.

        Raises:
            ValueError: stage 6 is Ruckig's (`SafetyConfig.references == "ruckig"`).
        """
        if self.config.references != "target":
            raise ValueError("only a filter with target references (training profile) snapshots")
        core = {f"core.{name}": values for name, values in self.core.snapshot().items()}
        references = self.trajectory.state.q, self.trajectory.stopping  # (B, J) rad, (B,)
        return {**core, "references.q": references[0], "references.stopping": references[1]}, {}

    def restore(self, arrays: dict[str, np.ndarray], meta: dict[str, object]) -> None:
        """Continue from `snapshot`'s arrays (on a filter of the same config and size)."""
        self.core.restore({name[5:]: a for name, a in arrays.items() if name.startswith("core.")})
        every = np.arange(self.num_envs)
        self.trajectory.reset(every, arrays["references.q"])
        self.trajectory.stop(every[arrays["references.stopping"]])

    def command(
        self,
        action: object,
        q: np.ndarray,
        dq: np.ndarray,
        step: int,
        stale: np.ndarray | None = None,
    ) -> SafeOutput:
        """Filter a raw action (B, 21) at the measured state q, dq (B, J) and global `step`;
        rows where `stale` (B,) is set were computed for another episode and are rejected."""
        filtered = self.core.filter(action, q, dq, step, record=False, stale=stale)
        references = self.trajectory.step(filtered.q_target)
        filtered = self.core.recheck_torque(filtered, references.q_ref, q, dq)
        self.core.record(filtered)
        return SafeOutput(
            references.q_ref,
            references.dq_ref,
            filtered.kp,
            filtered.kd,
            filtered.tau_limit,
            self.trajectory.stopping.copy(),
            references,
            filtered,
        )

    def stop(self, env_ids: np.ndarray) -> None:
        """Brake `env_ids` from the next period on and hold until `resume` (watchdog, e-stop)."""
        self.trajectory.stop(env_ids)

    def resume(self, env_ids: np.ndarray, q: np.ndarray) -> None:
        """Follow the policy again in `env_ids` (K,), holding the measured q (K, J) until the
        next action (EMA cleared). The references go on from where the brake has brought them,
        at rest or not: re-anchoring them at rest would jump the commanded velocity of a robot
        still braking (a late action after the watchdog fired), which is a reflex on the FR3."""
        full = self.core.state.q_target.copy()  # (B, J)
        full[env_ids] = q
        self.core.reset(full, env_ids)
        self.trajectory.resume(env_ids)

    def brake(self, q: np.ndarray, dq: np.ndarray) -> SafeOutput:
        """One period without a policy action: stopping environments brake and hold, the
        others keep tracking their last safe target; gains are the last safe ones."""
        state = self.core.state
        references = self.trajectory.step(state.q_target)
        finite = (np.isfinite(q).all(axis=1) & np.isfinite(dq).all(axis=1))[:, None]  # (B, 1)
        q_now, dq_now = np.where(finite, q, state.q_target), np.where(finite, dq, 0.0)
        # At least critical damping while braking: the policy's rho can be as low as 0.3,
        # which would leave the arm drifting about its held reference.
        rho = np.maximum(state.rho, BRAKE_MIN_DAMPING_RATIO)
        kp, kd, _ = torque_preclip(references.q_ref, q_now, dq_now, state.kp, rho, self.tau_limit)
        return SafeOutput(
            references.q_ref,
            references.dq_ref,
            kp,
            kd,
            self.tau_limit.copy(),
            self.trajectory.stopping.copy(),
            references,
        )
