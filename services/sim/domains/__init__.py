"""The paper's nine benchmark domains (Sec. "Simulated Benchmark in Realistic Domains"),
rebuilt from cuboids for the MuJoCo sim, and planned episodes on them.

`DOMAIN_NAMES` lists the domains and `domain_builder(name)` gives a builder with the
signature of `scene.sample_scenes`; `SimConfig.domain` draws every episode from one domain,
and `EpisodePlan` with `VectorEnv.start_planned` starts chosen episodes for evaluation.
Modules: `fixture` (shared cuboid helpers), `furniture` and `containers` (the builders),
`registry` (names), `plan` (planned episodes).
"""

from hamnet.sim.domains.plan import EpisodePlan, pair_placement
from hamnet.sim.domains.registry import DOMAIN_BUILDERS, DOMAIN_NAMES, domain_builder

__all__ = ["DOMAIN_BUILDERS", "DOMAIN_NAMES", "EpisodePlan", "domain_builder", "pair_placement"]
