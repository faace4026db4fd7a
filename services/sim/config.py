"""Configuration of the sim: batch size, clocks, library, scenes, task and curriculum.

One frozen dataclass whose defaults run on a CPU laptop; `hamnet sim --help` is generated
from the field docstrings.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from hamnet.sim.curriculum import CurriculumConfig
from hamnet.sim.domains import DOMAIN_NAMES
from hamnet.sim.objects.config import ObjectLibraryConfig
from hamnet.sim.objects.randomization import ObjectRandomization
from hamnet.sim.placement import PlacementConfig
from hamnet.sim.robot import TIMESTEP, JointDynamicsRandomization
from hamnet.sim.robot_init import RobotInitConfig
from hamnet.sim.scene_config import SceneConfig
from hamnet.sim.task_config import TaskConfig


@dataclass(frozen=True)
class SimConfig:
    """A batch of simulated FR3 environments with procedural scenes or a benchmark domain."""

    num_envs: int = 4
    """Environments stepped together by this worker."""
    nthread: int = 0
    """Physics threads (0: every core)."""
    backend: Literal["mujoco", "warp"] = "mujoco"
    """Who integrates the physics: `mujoco` (the C engine's `mujoco.batch`, every core) or
    `warp` (MuJoCo Warp on `warp_device`: the same model, results and API; first use
    compiles its kernels for about a minute, cached after). Episodes, rewards and resets
    are the same code either way (`hamnet.sim.warp_physics`)."""
    warp_device: str = "cpu"
    """Warp's device for the `warp` backend: `cpu`, or `cuda` / `cuda:N` where a GPU is."""
    seed: int = 0
    """Seed of every random draw (scenes, objects, placements, starts)."""
    policy_period_s: float = 0.1
    """Time between two actions, s (10 Hz)."""
    control_samples: int = 8
    """Reference samples per action (80 Hz); each is held for the physics steps in between."""
    num_objects: int = 16
    """Procedural objects in the library."""
    object_folder: Path | None = None
    """Folder of meshes (OBJ/STL/GLB) to add to the library."""
    size_bins: int = 3
    """Sizes per object across `objects.radius` or `objects.scale` (meshes are compiled once,
    so sizes are discrete)."""
    library: ObjectLibraryConfig = field(default_factory=ObjectLibraryConfig)
    objects: ObjectRandomization = field(default_factory=ObjectRandomization)
    scene: SceneConfig = field(default_factory=SceneConfig)
    placement: PlacementConfig = field(default_factory=PlacementConfig)
    robot_init: RobotInitConfig = field(default_factory=RobotInitConfig)
    joint_dynamics: JointDynamicsRandomization = field(default_factory=JointDynamicsRandomization)
    task: TaskConfig = field(default_factory=TaskConfig)
    curriculum: CurriculumConfig = field(default_factory=CurriculumConfig)
    domain: str = ""
    """Empty: procedural scenes (`scene`); else every scene is this benchmark domain
    (`hamnet.sim.domains.DOMAIN_NAMES`: cabinet, sink, grill, ...), its start and goal
    apart in position and in orientation (`domains.pair_placement`)."""

    def __post_init__(self) -> None:
        for name in ("num_envs", "num_objects", "size_bins"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if self.domain and self.domain not in DOMAIN_NAMES:
            raise ValueError(
                f"domain must be '' (procedural scenes) or one of {', '.join(DOMAIN_NAMES)}, "
                f"got {self.domain!r}"
            )
        if self.nthread < 0:
            raise ValueError(f"nthread must be >= 0 (0: every core), got {self.nthread}")
        if self.backend not in ("mujoco", "warp"):
            raise ValueError(f"backend must be 'mujoco' or 'warp', got {self.backend!r}")
        period = self.physics_steps_per_sample * self.control_samples * TIMESTEP
        if self.physics_steps_per_sample < 1 or abs(period - self.policy_period_s) > 1e-9:
            raise ValueError(
                f"policy_period_s / control_samples must be a multiple of the {TIMESTEP} s "
                "physics timestep"
            )

    @property
    def start_goal_placement(self) -> PlacementConfig:
        """`placement` with its start/goal separations raised to the task's success thresholds,
        so no episode starts already solved (the authors' `avoid_direct_suc`) whatever the
        success preset."""
        return dataclasses.replace(
            self.placement,
            min_position_separation=max(
                self.placement.min_position_separation, self.task.success_radius
            ),
            min_orientation_separation=max(
                self.placement.min_orientation_separation, self.task.success_angle
            ),
        )

    @property
    def physics_steps_per_sample(self) -> int:
        """Physics steps each reference sample is held for."""
        return round(self.policy_period_s / self.control_samples / TIMESTEP)
