"""The summary of a finished run (`<run_dir>/summary.json`): what a learning result reports.

Final success rate on held-out episodes, the budget spent, the learning curve's points, and
how to reproduce it (command, seed, commit), next to the stage's definition.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from hamnet.policy.policy import Policy
from hamnet.policy.shipped import read_card, read_shipped, read_weights
from hamnet.policy.weights import policy_from
from hamnet.runtime.runs import read_metrics
from hamnet.trainer.results.evaluate import HeldOut
from hamnet.trainer.runners.run_config import RunConfig, stage_sim

CURVE_POINTS = 100
"""Points of the learning curve kept in the summary (evenly spaced iterations)."""


CHECKOUT = Path(__file__).resolve().parents[3]
"""The repository this package runs from (an editable install's checkout)."""


def repository_path(path: Path | str) -> str:
    """`path` relative to the checkout when inside it (result files must not name one
    machine's folders), else as given."""
    resolved = Path(path).resolve()
    return str(resolved.relative_to(CHECKOUT)) if resolved.is_relative_to(CHECKOUT) else str(path)


def policy_and_result(value: str) -> tuple[Policy, dict]:
    """The policy `value` names (a finished run's folder, or a shipped name) and the summary
    of the run that trained it (the folder's `summary.json`, or the result its card names)."""
    run = Path(value)
    if run.is_dir():
        summary = json.loads((run / "summary.json").read_text())
        return policy_from(read_weights(run / "checkpoints" / "latest.safetensors")), summary
    card = read_card(value)
    return policy_from(read_shipped(value)), json.loads((CHECKOUT / card["result"]).read_text())


DAGGER_KEYS = ("beta", "student_share", "imitation_loss", "student_episode_success")
"""Curve keys of a DAgger run, kept where its rows have them."""


def write_summary(
    config: RunConfig,
    held_out: HeldOut | None,
    code: str,
    commands: list[str],
    extra: dict[str, object] | None = None,
) -> Path:
    """Write `<run_dir>/summary.json` from the run's metrics, trained by the code of commit
    `code` (taken when the run started: the checkout may move while it runs) and made by
    `commands` (its start, then each resume: `Runner.commands`); `extra` adds fields (a
    DAgger run's teacher and both held-out success rates)."""
    rows = read_metrics(config.run_dir)
    stride = max(1, len(rows) // CURVE_POINTS)
    keys = ("env_transitions", "wall_clock_s", "success_rate", "return/total", "episode_length")
    keys += tuple(key for key in DAGGER_KEYS if rows and key in rows[-1])
    sim = config.sim
    summary = {
        "final_success_rate": None if held_out is None else held_out.success_rate,
        "final_goal_return": None if held_out is None else held_out.goal_return,
        "eval_episodes": config.eval_episodes,
        "stage": config.stage,
        "stage_definition": {
            "scene": dataclasses.asdict(sim.scene),
            "placement": dataclasses.asdict(sim.placement),
            "task": dataclasses.asdict(sim.task),
            "curriculum": dataclasses.asdict(sim.curriculum),
        },
        "architecture": config.architecture,
        "pose_readings": config.pose_readings,
        "encoder_checkpoint": (
            None if config.random_encoder else repository_path(config.encoder_checkpoint)
        ),
        "num_envs": config.num_envs,
        "env_steps": rows[-1]["env_transitions"] if rows else 0,
        "wall_clock_s": rows[-1]["wall_clock_s"] if rows else 0.0,
        "curve": [{key: row.get(key) for key in keys} for row in rows[::stride]],
        "command": commands[-1],
        "commands": commands,
        "seed": config.seed,
        "commit": code,
        **(extra or {}),
    }
    path = config.run_dir / "summary.json"
    path.write_text(json.dumps(summary, indent=1, default=str) + "\n")
    return path


def run_of(summary: dict, seed: int | None = None) -> RunConfig:
    """The run a summary describes, as far as evaluating its policy again needs: stage and
    its environments, seed (`seed`, default the run's), architecture and the encoder whose
    tokens it learned on (`encoder_checkpoint`, relative to the checkout; None: random)."""
    seed = summary["seed"] if seed is None else seed
    sim = dataclasses.replace(stage_sim(summary["stage"]), seed=seed)
    encoder = summary.get("encoder_checkpoint")
    located = {"encoder_checkpoint": CHECKOUT / encoder} if encoder else {}
    return RunConfig(
        stage=summary["stage"],
        sim=sim,
        architecture=summary["architecture"],
        random_encoder=encoder is None,
        **located,
    )
