"""Curriculum over robot initialisation and ceiling types (paper, "Procedural domain and
curriculum generation", lines 316-322), a pure function of env_transitions
(hamnet.runtime.counter).

Early in training the sim prefers *near* robot initialisations (the end-effector within
0.1 m of the object) and *nominal* ceilings; as training progresses the proportion of
*random* initialisations and *tight* ceilings rises linearly (line 321). The trainer
publishes its counter on `hamnet/<ns>/trainer/schedule`; the sim evaluates
`curriculum_values(env_transitions)` from it, feeds `p_tight` into
`SceneConfig.p_tight` (`scene_config_at`) and draws a near initialisation with
probability `p_near_init`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from hamnet.runtime.counter import from_vectorized_steps
from hamnet.sim.scene_config import SceneConfig

SCHEDULE_NAMES = ("p_near_init", "p_tight")
"""Stable names of the curriculum values (statistics, logs)."""


@dataclass(frozen=True)
class CurriculumConfig:
    """Linear schedule of the two sampling probabilities over env_transitions.

    The paper gives neither endpoints nor length. The defaults come from the authors'
    code, which weights tight episodes by 0.5 rising to 5 against 1 for nominal ones, and
    random initialisations by 0.25 rising to 10 against 1 for near ones, over its whole
    training run; with equal shares of each kind that is p_tight 1/3 -> 5/6 and
    p_near_init 4/5 -> 1/11. The code raises the weights geometrically; the paper says
    linearly, which is what this schedule does to the probabilities.
    """

    p_near_init_start: float = 0.8
    """Probability of a near robot initialisation at the start of the curriculum."""
    p_near_init_end: float = 1.0 / 11.0
    """Probability of a near robot initialisation at its end (the rest are random)."""
    p_tight_start: float = 1.0 / 3.0
    """Probability that a ceiling is tight rather than nominal at the start."""
    p_tight_end: float = 5.0 / 6.0
    """Probability that a ceiling is tight rather than nominal at the end."""
    start_step: int = 0
    """env_transitions where the values start to move."""
    num_steps: int = from_vectorized_steps(2e6)
    """env_transitions over which they move from start to end: the authors' 2e6 vectorized
    steps of 1024 environments (ham/scripts/env_wrappers.py:1128 total_scale_step, counted
    once per batched step at line 1216; 2.048e9 transitions, the paper's "2 billion
    interactions", line 374). The authors move in 1953 stairs of 1024 vectorized steps
    (n_step_per_update, line 1129); this schedule moves continuously."""

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            if field.name.startswith("p_") and not 0.0 <= getattr(self, field.name) <= 1.0:
                value = getattr(self, field.name)
                raise ValueError(f"{field.name} must be a probability, got {value}")
        if self.start_step < 0:
            raise ValueError(f"start_step must be >= 0, got {self.start_step}")
        if self.num_steps < 1:
            raise ValueError(f"num_steps must be >= 1, got {self.num_steps}")


@dataclass(frozen=True)
class CurriculumValues:
    """The curriculum's sampling probabilities at one env_transitions count."""

    p_near_init: float
    """Probability of a near robot initialisation (else random)."""
    p_tight: float
    """Probability that a ceiling is tight (else nominal); feeds SceneConfig.p_tight."""

    def as_dict(self) -> dict[str, float]:
        """The values keyed by SCHEDULE_NAMES."""
        return {name: getattr(self, name) for name in SCHEDULE_NAMES}


def curriculum_progress(env_transitions: int, config: CurriculumConfig) -> float:
    """Share of the curriculum done at `env_transitions`, in [0, 1]."""
    return min(max((env_transitions - config.start_step) / config.num_steps, 0.0), 1.0)


def _lerp(start: float, end: float, progress: float) -> float:
    return start + (end - start) * progress


def curriculum_values(
    env_transitions: int, config: CurriculumConfig | None = None
) -> CurriculumValues:
    """The sampling probabilities at `env_transitions` (hamnet.runtime.counter)."""
    config = config if config is not None else CurriculumConfig()
    progress = curriculum_progress(env_transitions, config)
    return CurriculumValues(
        p_near_init=_lerp(config.p_near_init_start, config.p_near_init_end, progress),
        p_tight=_lerp(config.p_tight_start, config.p_tight_end, progress),
    )


def scene_config_at(values: CurriculumValues, scene: SceneConfig) -> SceneConfig:
    """`scene` with its tight-ceiling probability set by the curriculum."""
    return dataclasses.replace(scene, p_tight=values.p_tight)
