"""`hamnet eval`: a policy on held-out procedural scenes and on the paper's nine benchmark
domains (rebuilt from cuboids: `hamnet.sim.domains`), per domain-object pair with several
start and goal pairs and collision-free robot initialisations, in this process or, with
`--stack`, through perception, policy and safety running as services (docs/evaluation.md).

    hamnet eval --quick                                   # a handful of episodes, under 2 min
    hamnet eval --policy easy-teacher                     # the paper's protocol (5 pairs x 128 inits)
    hamnet eval --policy runs/train/checkpoints/latest.safetensors easy-teacher  # compared
    hamnet eval --suites cabinet sink --objects 2 --inits 16 --skills
    hamnet eval --quick --stack                          # perception, policy, safety as services

Writes to `--out`: `report.json` (per suite and overall: success rate with its 95% Wilson
interval, failure reasons, episode lengths; with several policies, each against the first),
`report.png` (success per suite with its interval, failure reasons), `<label>.records.jsonl`
(one line per episode), `recordings/<suite>_<k>.rrd` (a few episodes of the first policy:
`rerun FILE`) and, with `--skills`, `skills/` (UMAP and HDBSCAN of HAMnet's modulation
embeddings: figure, per-episode cluster timelines, Rerun view). Prints a progress line per
batch and, last, one JSON line: success_rate, ci, episodes, per_domain (each benchmark
domain's rate), procedural, report.
"""

from __future__ import annotations

import json
import logging
import sys
from collections.abc import Sequence
from pathlib import Path

from hamnet.evaluation.config import EvalConfig
from hamnet.evaluation.figure import plot_evaluation
from hamnet.evaluation.metrics import OVERALL, summarise_suites
from hamnet.evaluation.records import (
    BENCHMARK_DOMAINS,
    PROCEDURAL,
    EpisodeRecord,
    write_records,
)
from hamnet.evaluation.report import comparison_report, policy_report, write_report
from hamnet.evaluation.run import evaluate_on_stack, evaluate_policy
from hamnet.policy.policy import Policy
from hamnet.policy.shipped import read_card, read_weights, shipped_names
from hamnet.policy.weights import WeightsError, policy_from
from hamnet.runtime.cli import parse
from hamnet.runtime.runs import command_line, commit

log = logging.getLogger(__name__)

DEFAULT_STAGE = "full"
"""The stage of a checkpoint that names none (the paper's full domain)."""


def stage_of(config: EvalConfig) -> str:
    """`--stage`, else the first policy's: a shipped card's, or its run's summary.json."""
    if config.stage:
        return config.stage
    name = config.policy[0]
    if name in shipped_names():
        return read_card(name)["stage"]
    summary = Path(name).resolve().parent.parent / "summary.json"  # RUN/checkpoints/x
    if summary.exists():
        return json.loads(summary.read_text()).get("stage", DEFAULT_STAGE)
    return DEFAULT_STAGE


def load(name: str) -> Policy:
    """The policy in checkpoint file or shipped policy `name` (WeightsError if unusable)."""
    return policy_from(read_weights(name)).eval()


def main(argv: Sequence[str]) -> int:
    """Run `hamnet eval` with arguments `argv`; returns the exit status."""
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    config = parse(EvalConfig, argv, "hamnet eval", __doc__).played
    try:
        policies = {name: load(name) for name in config.policy}
    except (WeightsError, OSError) as error:
        print(f"hamnet eval: {error}", file=sys.stderr)
        return 2
    stage, code = stage_of(config), commit()  # the commit of the code that evaluates
    played: dict[str, list[EpisodeRecord]] = {}
    for index, (name, policy) in enumerate(policies.items()):
        log.info("evaluating %s (%s) on the %s stage", name, policy.architecture, stage)
        recordings = config.out / "recordings" if index == 0 and config.record else None
        if config.stack:
            records, steps = evaluate_on_stack(name, policy, config, stage, recordings), None
        else:
            records, steps = evaluate_policy(policy, config, stage, recordings)
        played[name] = records
        write_records(config.out / f"{Path(name).stem}.records.jsonl", records)
        if steps is not None and index == 0:
            from hamnet.evaluation.skills import find_skills  # umap only when asked
            from hamnet.evaluation.skills_view import write_skills

            steps.save(config.out / "skills" / "steps.npz")
            write_skills(find_skills(steps), config.out / "skills")
    report = (
        policy_report(next(iter(played.values())))
        if len(played) == 1
        else comparison_report(played)
    )
    report = {**report, "run": run_fields(config, stage, code)}
    path = write_report(report, config.out / "report.json")
    plot_evaluation(played, config.out / "report.png", f"hamnet eval on the {stage} stage")
    print(json.dumps(last_line(next(iter(played.values())), path)))
    return 0


def run_fields(config: EvalConfig, stage: str, code: str) -> dict[str, object]:
    """How to reproduce a report: the command, the commit, the stage and every count."""
    return {
        "command": command_line("eval"),
        "commit": code,
        "stage": stage,
        "seed": config.seed,
        "policies": list(config.policy),
        "suites": list(config.suites),
        "objects": config.objects,
        "pairs": config.pairs,
        "inits": config.inits,
        "safety_profile": config.filter_profile,
        "stack": config.stack,
        "env_transitions": config.env_transitions,
    }


def last_line(records: list[EpisodeRecord], report: Path) -> dict[str, object]:
    """What a script reads of the first policy: its overall success rate with the interval,
    its episodes, the rate of each benchmark domain played (`per_domain`) and of the
    held-out procedural scenes, and where the report is."""
    summaries = summarise_suites(records)
    overall = summaries[OVERALL]
    return {
        "success_rate": overall.rate,
        "ci": [overall.ci_low, overall.ci_high],
        "episodes": overall.episodes,
        "per_domain": {
            suite: summaries[suite].rate for suite in BENCHMARK_DOMAINS if suite in summaries
        },
        "procedural": summaries[PROCEDURAL].rate if PROCEDURAL in summaries else None,
        "report": str(report),
    }
