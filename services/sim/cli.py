"""`hamnet sim`: B simulated FR3 environments with procedural scenes, stepped by the safety
filter's commands over Zenoh (see `hamnet.sim.shell` for the topics and the pacing).

`--show-scene SEED` writes a Rerun recording of one procedural scene and exits;
`--print-model-path` prints the FR3 model file and exits.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

import tyro

from hamnet.fr3.model import model_path
from hamnet.runtime.cli import CommonConfig, Flattened, parse_service
from hamnet.runtime.service import Service
from hamnet.sim.config import SimConfig
from hamnet.sim.env import VectorEnv
from hamnet.sim.loop import SimLoopConfig
from hamnet.sim.shell import PORTS, SimShell
from hamnet.sim.stages import StageName, stage_config, stage_in

OwnPrefix = tyro.conf.arg(name="")
"""Drop this field's own prefix (`--num-envs`, not `--sim.num-envs`) but keep its
sub-configs' (`--scene.p-tight`): their field names repeat, so they need them."""


@dataclass(frozen=True)
class SimServiceConfig:
    """One sim worker: the environments, how they are paced, and one-shot tools."""

    common: Annotated[CommonConfig, Flattened] = field(default_factory=CommonConfig)
    stage: StageName = "full"
    """Training stage (`hamnet.sim.stages`): full (the paper's domain), easy (issue 28) or
    easy-5cm (the former easy stage). It sets the defaults of every other sim flag; those
    flags change any field on top of it."""
    sim: Annotated[SimConfig, OwnPrefix] = field(default_factory=SimConfig)
    loop: Annotated[SimLoopConfig, Flattened] = field(default_factory=SimLoopConfig)
    show_scene: int | None = None
    """Write a Rerun recording of the scene drawn from this seed (procedural, or `--domain`),
    print its path and exit (open it with `rerun <file>`)."""
    scene_file: Path | None = None
    """Where `--show-scene` writes; None: runs/scene-<seed>.rrd."""
    print_model_path: bool = False
    """Print the path of the FR3 MJCF model file and exit."""


CONFIG = SimServiceConfig
"""The config `hamnet sim` parses (the launcher validates stack files against it)."""


def main(argv: Sequence[str]) -> int:
    """Run `hamnet sim` with command-line arguments `argv`; returns the exit status."""
    stage = stage_in(argv, "full")
    default = SimServiceConfig(stage=stage, sim=stage_config(stage))
    config, identity = parse_service(CONFIG, argv, "sim", __doc__, default=default, ports=PORTS)
    if config.print_model_path:
        print(model_path())
        return 0
    if config.show_scene is not None:
        from hamnet.sim.scene_view import save_scene  # Rerun loads in 0.3 s: only when used

        path = config.scene_file or Path("runs") / f"scene-{config.show_scene}.rrd"
        path.parent.mkdir(parents=True, exist_ok=True)
        save_scene(path, config.show_scene, config.sim.scene, domain=config.sim.domain)
        print(path)
        return 0
    env = VectorEnv(config.sim)
    with Service(identity, config.common.transport, remap=config.common.remap) as service:
        return SimShell(service, env, config.loop).run()
