"""Ship a finished run's policy in the package: `hamnet/policy/shipped/<name>.safetensors`
(float16 network, `hamnet.policy.weights`) and its card `<name>.json`, which
`hamnet policy --checkpoint <name>` and `hamnet trainer --teacher <name>` check on load
(`hamnet.policy.shipped`).

    python scripts/ship_policy.py runs/ppo-easy/hamnet easy-teacher --result docs/results/ppo-easy.json
    python scripts/ship_policy.py runs/dagger-easy easy-student --result docs/results/dagger-easy.json

The shipped file is evaluated again on the held-out episodes of the result (same stage,
seed and count; a student sees clouds as the cameras do), so the card reports what the
shipped weights themselves do, float16 rounding included.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from hamnet.perception.checkpoint import SHIPPED_ENCODER
from hamnet.perception.config import student_clouds
from hamnet.policy.shipped import SHIPPED_DIR, card_path, encoder_sha256, read_shipped, weights_path
from hamnet.policy.weights import policy_from, read_checkpoint, sha256, to_bytes
from hamnet.trainer.results.evaluate import evaluate
from hamnet.trainer.results.summary import repository_path, run_of


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "run", type=Path, help="a finished run's folder (summary.json, checkpoints/)"
    )
    parser.add_argument("name", help="the shipped policy's name (what --checkpoint takes)")
    parser.add_argument("--result", type=Path, required=True,
                        help="the committed result file that reports this run")  # fmt: skip
    parser.add_argument("--seed", type=int, default=0, help="seed of the result's evaluation")
    args = parser.parse_args()
    summary = json.loads((args.run / "summary.json").read_text())
    result = json.loads(args.result.read_text())
    checkpoint = read_checkpoint(args.run / "checkpoints" / "latest.safetensors")
    data = to_bytes(policy_from(checkpoint), checkpoint.version, half=True)
    SHIPPED_DIR.mkdir(parents=True, exist_ok=True)
    weights_path(args.name).write_bytes(data)
    card = {
        "name": args.name,
        "architecture": checkpoint.architecture,
        "action_space": checkpoint.config.action_space,
        "stage": summary["stage"],
        "version": checkpoint.version,
        "weights_sha256": sha256(data),
        "storage": "network tensors float16, input statistics and log std float32",
        "encoder_checkpoint": repository_path(SHIPPED_ENCODER),
        "encoder_sha256": encoder_sha256(),
        "env_steps": summary["env_steps"],
        "wall_clock_s": summary["wall_clock_s"],
        "trained_by": summary["command"],
        "commit": summary["commit"],
        "result": repository_path(args.result),
        "result_success_rate": result["final_success_rate"],
        "shipped_by": " ".join(["python", "scripts/ship_policy.py", *sys.argv[1:]]),
    }
    card_path(args.name).write_text(json.dumps(card, indent=1) + "\n")
    shipped = policy_from(read_shipped(args.name))  # the card and the file agree
    clouds = None if shipped.config.privileged else student_clouds()
    episodes = result["eval_episodes"]
    held_out = evaluate(shipped, run_of(summary, args.seed), episodes, summary["env_steps"], clouds)
    card |= {"shipped_success_rate": held_out.success_rate, "eval_episodes": episodes}
    card_path(args.name).write_text(json.dumps(card, indent=1) + "\n")
    print(
        json.dumps(
            {key: card[key] for key in ("name", "result_success_rate", "shipped_success_rate")}
        )
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
