"""What `hamnet eval` plays: which policies, which suites, how many episodes of each, and
where the report goes. The counts default to the paper's protocol (Sec. "Simulated
Benchmark in Realistic Domains": per domain-object pair 5 stable start and goal pairs and
128 collision-free robot initialisations); `--quick` plays a handful, to see it work."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from hamnet.evaluation.records import SUITES
from hamnet.runtime.errors import ConfigError
from hamnet.safety.config import Profile


@dataclass(frozen=True)
class EvalConfig:
    """One evaluation."""

    policy: tuple[str, ...] = ("easy-teacher",)
    """Checkpoints to evaluate: files `hamnet trainer` wrote, or names of shipped policies;
    with several, the report compares them on the same episodes, the first as reference."""
    suites: tuple[str, ...] = SUITES
    """`procedural` (held-out procedural scenes of the stage) and benchmark domains."""
    stage: str = ""
    """The stage whose objects, task (success thresholds, timeout) and procedural scenes are
    played; empty: the first policy's (a shipped policy's card), else `full`."""
    objects: int = 4
    """Objects per domain, drawn from the stage's library (the paper's domains hold several
    objects each)."""
    pairs: int = 5
    """Start and goal pose pairs per domain-object pair (paper: 5)."""
    inits: int = 128
    """Collision-free robot initialisations per pose pair (paper: 128)."""
    procedural_episodes: int = 0
    """Episodes of the procedural suite; 0: as many as one domain plays."""
    num_envs: int = 64
    """Environments stepped side by side (episodes are played in batches of this many)."""
    seed: int = 0
    """Seeds every plan, scene and initialisation (offset from any training seed)."""
    env_transitions: int = 0
    """Schedule counter the policies act at (the safety filter's action bound anneals with
    it); 0: the start of the curriculum, where the widest bound holds."""
    safety_profile: Profile | None = None
    """The safety filter between policy and sim: `training` (what the policy was trained and
    the trainer's held-out evaluation measured with) or `deploy` (every stage the real robot
    runs: Cartesian clip, torque pre-clip, Ruckig references), to measure what the deployed
    filter changes; unset: training in this process, deploy with `--stack` (as deployed)."""
    record: int = 2
    """Episodes per suite of the first policy drawn into a Rerun recording."""
    skills: bool = False
    """Collect HAMnet's modulation embeddings and write the skills analysis (UMAP and
    HDBSCAN; paper Sec. on the emergence of skills)."""
    stack: bool = False
    """Serve the policy, its perception and the safety filter as `hamnet` services on
    Zenoh, this process their sim, instead of running their cores in this process (slower:
    every step crosses the network)."""
    quick: bool = False
    """A handful of episodes: one object, one pair, two initialisations per domain."""
    out: Path = Path("runs/eval")
    """Where report.json, report.png, records, recordings and skills go."""

    def __post_init__(self) -> None:
        unknown = sorted(set(self.suites) - set(SUITES))
        if unknown:
            raise ConfigError(f"--suites: unknown {unknown}; known: {', '.join(SUITES)}")
        if not self.policy:
            raise ConfigError("--policy: give at least one checkpoint or shipped policy")
        stems = [Path(name).stem for name in self.policy]
        if len(set(stems)) < len(stems):
            raise ConfigError(f"--policy: two policies share a name ({stems}): rename one file")
        if self.stack and self.skills:
            raise ConfigError("--skills reads the policy's embedding in process: not with --stack")
        counts = (self.objects, self.pairs, self.inits, self.num_envs)
        if min(counts) < 1 or self.procedural_episodes < 0 or self.record < 0:
            raise ConfigError("--objects, --pairs, --inits and --num-envs must be >= 1")

    @property
    def played(self) -> EvalConfig:
        """The counts as played: `--quick` turns them down."""
        if not self.quick:
            return self
        return replace(self, objects=1, pairs=1, inits=2, procedural_episodes=2, record=1)

    @property
    def filter_profile(self) -> Profile:
        """`safety_profile`, resolved."""
        if self.safety_profile is not None:
            return self.safety_profile
        return "deploy" if self.stack else "training"

    @property
    def episodes_per_domain(self) -> int:
        return self.objects * self.pairs * self.inits
