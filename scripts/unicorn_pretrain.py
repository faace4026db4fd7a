"""The UniCORN encoder to ship and its report (issue 14): contact data, three encoders trained
on the same data for the same steps, held-out evaluation, and the encoder perception loads.

    python scripts/unicorn_pretrain.py                 # about an hour on 2 cores
    python scripts/unicorn_pretrain.py --from-runs     # no training: report and ship finished runs
    python scripts/unicorn_pretrain.py --pairs 2000 --steps 200 --runs runs/pretrain-try --no-ship

Steps (each a `hamnet pretrain` command, logged under `--runs`):
1. `generate` the training pairs (seed `--seed`) and the held-out pairs (seed + 1: shape
   instances never trained on);
2. `train` UniCORN, a randomly initialised frozen encoder (only the decoder learns) and a
   plain PointNet, side by side, each for `--steps` steps of `--batch-size` pairs;
3. `eval` all three on the held-out pairs: `docs/results/unicorn-pretrain.json` and `.png`,
   with the command, seed and commit added;
4. copy the UniCORN encoder to `hamnet/perception/weights/` (`SHIPPED_ENCODER`), with a JSON
   of where it came from next to it, but only when its held-out AUROC beats the random
   frozen encoder's: pre-training that does not beat random weights ships nothing.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

from hamnet.perception.checkpoint import SHIPPED_ENCODER, load_checkpoint
from hamnet.runtime.runs import commit

ROOT = Path(__file__).resolve().parents[1]
ENCODERS = ("unicorn", "random-frozen", "pointnet")
"""The encoder the policy uses first (the report's top-level figures are its), then the two
baselines the issue names."""


def pretrain(*args: str, log: Path) -> subprocess.Popen:
    """`python -m hamnet pretrain ARGS`, one torch thread, output to `log`."""
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen([sys.executable, "-m", "hamnet", "pretrain", *args], cwd=ROOT, env=env,
                            stdout=log.open("w"), stderr=subprocess.STDOUT)  # fmt: skip


def wait(processes: list[subprocess.Popen], runs: Path) -> None:
    """Wait for every process; a failure stops the script with where to look."""
    if any(process.wait() != 0 for process in processes):
        raise SystemExit(f"a step failed: see {runs}/*.log")


def train(args: argparse.Namespace) -> None:
    """Generate both datasets, then train the three encoders side by side."""
    runs = args.runs
    runs.mkdir(parents=True, exist_ok=True)
    workers = ["--workers", "2"]
    wait([pretrain("generate", "--pairs", str(args.pairs), "--seed", str(args.seed), *workers,
                   "--out", str(runs / "data"), log=runs / "generate.log")], runs)  # fmt: skip
    wait([pretrain("generate", "--pairs", str(args.heldout_pairs), "--seed", str(args.seed + 1),
                   *workers, "--out", str(runs / "heldout"), log=runs / "heldout.log")], runs)  # fmt: skip
    common = ["--data", str(runs / "data"), "--steps", str(args.steps), "--seed", str(args.seed),
              "--batch-size", str(args.batch_size), "--checkpoint-every", "1000"]  # fmt: skip
    wait([pretrain("train", *common, "--encoder", name, "--out", str(runs / name), log=runs / f"{name}.log")
          for name in ENCODERS], runs)  # fmt: skip


def ship(run: Path, provenance: dict) -> Path:
    """Copy the run's encoder to the shipped path (checked by loading it first) and write
    its provenance next to it."""
    source = run / "encoder.safetensors"
    _, version = load_checkpoint(source)
    SHIPPED_ENCODER.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(source, SHIPPED_ENCODER)
    note = {**provenance, "encoder_version": version}
    SHIPPED_ENCODER.with_suffix(".json").write_text(json.dumps(note, indent=1) + "\n")
    return SHIPPED_ENCODER


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--pairs", type=int, default=60_000, help="training pairs")
    parser.add_argument("--heldout-pairs", type=int, default=2_000, help="held-out pairs")
    parser.add_argument("--steps", type=int, default=10_000, help="training steps of each encoder")
    parser.add_argument("--batch-size", type=int, default=32, help="pairs per step")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--runs", type=Path, default=Path("runs/pretrain"), help="data and run folders"
    )
    parser.add_argument("--out", type=Path, default=Path("docs/results/unicorn-pretrain"),
                        help="result path without suffix (.json and .png are written)")  # fmt: skip
    parser.add_argument(
        "--from-runs", action="store_true", help="no training: report the runs in --runs"
    )
    parser.add_argument("--no-ship", action="store_true", help="leave the shipped encoder as it is")
    args = parser.parse_args()
    os.chdir(ROOT)  # relative paths (and those in the report) are the repository's
    code = commit()
    if not args.from_runs:
        train(args)
    report = args.out.with_suffix(".json")
    wait([pretrain("eval", "--data", str(args.runs / "heldout"), "--out", str(report),
                   "--runs", *(str(args.runs / name) for name in ENCODERS), log=args.runs / "eval.log")],
         args.runs)  # fmt: skip
    trained = json.loads((args.runs / "unicorn" / "state.json").read_text())
    provenance = {
        "command": " ".join(["python", "scripts/unicorn_pretrain.py", *(a for a in sys.argv[1:] if a != "--from-runs")]),
        "seed": trained["seed"], "commit": trained["commit"] or code, "training_pairs": trained["pairs"],
        "steps": trained["step"], "batch_size": trained["batch_size"],
    }  # fmt: skip
    summary = {**json.loads(report.read_text()), **provenance}
    auroc = {name: summary["runs"][str(args.runs / name)]["auroc"] for name in ENCODERS[:2]}
    if auroc["unicorn"] <= auroc["random-frozen"]:
        summary["shipped"] = None
        summary["not_shipped"] = (f"UniCORN's held-out AUROC {auroc['unicorn']:.3f} does not beat "
                                  f"the random frozen encoder's {auroc['random-frozen']:.3f}")  # fmt: skip
        print(summary["not_shipped"], file=sys.stderr)
    elif not args.no_ship:
        scores = {"heldout_auroc": auroc["unicorn"], "heldout_pairs": summary["pairs"]}
        summary["shipped"] = str(
            ship(args.runs / "unicorn", {**provenance, **scores}).relative_to(ROOT)
        )
    report.write_text(json.dumps(summary, indent=1) + "\n")
    print(json.dumps({key: summary[key] for key in ("heldout_auroc", "heldout_accuracy", "steps")}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
