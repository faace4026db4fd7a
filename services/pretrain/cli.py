"""`hamnet pretrain`: UniCORN pre-training on contact pairs (issue 14; docs/pretrain.md).

    hamnet pretrain generate --pairs 60000 --workers 1 --out runs/pretrain/data
    hamnet pretrain generate --pairs 2000 --seed 1 --out runs/pretrain/heldout
    hamnet pretrain train --data runs/pretrain/data --out runs/pretrain/unicorn --max-minutes 45
    hamnet pretrain train ... --encoder pointnet --out runs/pretrain/pointnet     # baselines
    hamnet pretrain eval --data runs/pretrain/heldout --runs runs/pretrain/unicorn runs/pretrain/pointnet

`generate` and `train` continue where they stopped (`generate` skips finished chunks;
`train --resume`). `<command> --help` lists every option.
"""

from __future__ import annotations

import json
import logging
import sys
from collections.abc import Callable, Sequence

from hamnet.pretrain.config import EvalConfig, GenerateConfig, TrainConfig
from hamnet.runtime.cli import parse
from hamnet.runtime.logs import configure_logging

log = logging.getLogger(__name__)


def _generate(argv: Sequence[str]) -> int:
    from hamnet.pretrain.dataset import generate

    config = parse(GenerateConfig, argv, "hamnet pretrain generate", __doc__)
    manifest = generate(config)
    print(
        json.dumps(
            {k: manifest[k] for k in ("pairs", "chunks", "colliding_share", "positive_point_share")}
        )
    )
    return 0


def _train(argv: Sequence[str]) -> int:
    from hamnet.pretrain.train import train
    from hamnet.runtime.runs import commit

    config = parse(TrainConfig, argv, "hamnet pretrain train", __doc__)
    state = train(config, commit())
    print(json.dumps({k: state[k] for k in ("step", "version", "train_s")}))
    return 0


def _eval(argv: Sequence[str]) -> int:
    from hamnet.pretrain.evaluate import evaluate

    config = parse(EvalConfig, argv, "hamnet pretrain eval", __doc__)
    summary = evaluate(config)
    print(json.dumps({k: summary[k] for k in ("heldout_auroc", "heldout_accuracy")}))
    return 0


SUBCOMMANDS: dict[str, Callable[[Sequence[str]], int]] = {
    "generate": _generate,
    "train": _train,
    "eval": _eval,
}


def main(argv: Sequence[str]) -> int:
    """Run `hamnet pretrain <generate|train|eval> ...`; returns the exit status."""
    if not argv or argv[0] in ("-h", "--help"):
        print(f"usage: hamnet pretrain {{{'|'.join(SUBCOMMANDS)}}} [--help]\n\n{__doc__}")
        return 0 if argv else 2
    if argv[0] not in SUBCOMMANDS:
        print(
            f"hamnet pretrain: unknown command {argv[0]!r} (choose from {', '.join(SUBCOMMANDS)})",
            file=sys.stderr,
        )
        return 2
    configure_logging("pretrain")
    return SUBCOMMANDS[argv[0]](argv[1:])
