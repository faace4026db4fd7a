"""Policy networks: forward (inference) and forward+backward (training) time per batch for
HAMnet and every baseline, as ratios to the monolithic MLP measured in the same run.

The paper's per-epoch training times relative to its MLP are HAMnet 1.19x, soft
modularization 1.64x and hypernetwork 4.7x (Fig. dt_bar_plot); the issue asks HAMnet to beat
1.19x. Architectures are timed interleaved (one repetition of each in turn) so that load
from other processes on a shared machine hits them alike; medians and p99 over the
repetitions. Training = `Policy.evaluate` on given actions, a PPO-like loss (log-prob and
values), backward. Inference = `Policy.act` under `torch.inference_mode`.

    python benchmarks/policy.py            # batches 64, 1024, 8192
    python benchmarks/policy.py --quick    # batches 64, 1024; under a minute

The last stdout line is one JSON object: `hamnet_vs_mlp_train` and `hamnet_vs_mlp_infer` at
batch 1024, and every row.
"""

from __future__ import annotations

import argparse

import torch

# Run as a script, so benchmarks/ is on sys.path: the helpers every benchmark shares.
from common import median_p99, report, timer

from hamnet.policy.networks import PolicyInputs
from hamnet.policy.observation import RobotObservation, assemble
from hamnet.policy.policy import Policy
from hamnet.policy.registry import ARCHITECTURES, build, with_changes

PAPER_MLP = "mlp-paper-widths"
"""The MLP with the paper's exact widths (768, 384, 384, 192): fewer parameters than our
HAMnet (the registered `mlp` is scaled to match it), timed as a second reference."""

PAPER_TRAIN_VS_MLP = {"hamnet": 1.19, "sm": 1.64, "hyper": 4.7}
"""Per-epoch training time relative to the MLP, paper Fig. dt_bar_plot (1.33 s, 1.84 s,
5.31 s)."""


def inputs(policy: Policy, batch: int) -> PolicyInputs:
    """Random, well-formed inputs of `batch` environments (fixed seed)."""
    g = torch.Generator().manual_seed(batch)
    r = lambda *shape: torch.randn(*shape, generator=g)  # noqa: E731
    pose = lambda: torch.cat((r(batch, 3), torch.nn.functional.normalize(r(batch, 4), dim=-1)), -1)  # noqa: E731
    c = policy.config
    spec = c.observation
    j = spec.num_joints
    robot = RobotObservation(
        r(batch, j), r(batch, j), r(batch, 9), pose(), pose(), r(batch, 6), r(batch, spec.physics_params)
    )  # fmt: skip
    return PolicyInputs(
        assemble(robot, r(batch, c.action_dim), spec), r(batch, c.num_tokens, c.token_dim),
        r(batch, c.num_tokens, c.token_dim), r(batch, c.num_tokens, c.token_dim),
        r(batch, c.env_code_dim), policy.initial_memory(batch),
    )  # fmt: skip


def timers(policy: Policy, batch: int):
    """(infer, train) closures for one architecture at one batch size."""
    batch_inputs = inputs(policy, batch)
    actions = torch.randn(
        batch, policy.config.action_dim, generator=torch.Generator().manual_seed(1)
    )

    def infer() -> None:
        with torch.inference_mode():
            policy.act(batch_inputs, deterministic=False)

    def train() -> None:
        policy.zero_grad(set_to_none=True)
        evaluation = policy.evaluate(batch_inputs, actions)
        loss = -evaluation.log_prob.mean() + evaluation.values.square().mean()
        loss.backward()

    return infer, train


def measure(names: list[str], batch: int, repetitions: int, warmup: int) -> dict[str, dict]:
    """Interleaved timings (s) of every architecture at `batch`."""
    policies = {name: build(name, seed=0) for name in names if name != PAPER_MLP}
    if PAPER_MLP in names:
        paper_widths = with_changes("mlp", mlp_hidden=(768, 384, 384, 192))
        policies[PAPER_MLP] = build("mlp", paper_widths, seed=0)
    closures = {name: timers(policy, batch) for name, policy in policies.items()}
    samples: dict[str, dict[str, list[float]]] = {n: {"infer": [], "train": []} for n in names}
    for repetition in range(warmup + repetitions):
        for name in names:
            for kind, run in zip(("infer", "train"), closures[name]):
                seconds = timer(run)()
                if repetition >= warmup:
                    samples[name][kind].append(seconds)
    return samples


def rows(samples: dict[str, dict], batch: int) -> list[dict]:
    """One row per architecture: medians, p99 and ratios to the MLP."""
    ms = {n: {k: median_p99(v, 1e3) for k, v in s.items()} for n, s in samples.items()}
    out = []
    for name, kinds in ms.items():
        row = {"architecture": name, "batch": batch}
        for kind, (median, p99) in kinds.items():
            row[f"{kind}_ms"], row[f"{kind}_p99_ms"] = median, p99
            row[f"{kind}_vs_mlp"] = median / ms["mlp"][kind][0]
        row["paper_train_vs_mlp"] = PAPER_TRAIN_VS_MLP.get(name)
        out.append(row)
    return out


def main() -> dict:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--quick", action="store_true", help="batches 64 and 1024, few repetitions")
    parser.add_argument("--threads", type=int, default=1,
                        help="torch CPU threads (1: steadier on a shared machine)")  # fmt: skip
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    batches = (64, 1024) if args.quick else (64, 1024, 8192)
    names = [*ARCHITECTURES, PAPER_MLP]
    results = []
    for batch in batches:
        repetitions = 5 if args.quick else (30 if batch < 8192 else 10)
        table = rows(measure(names, batch, repetitions, warmup=2), batch)
        results += table
        print(
            f"batch {batch}: {'architecture':<15} {'infer ms':>9} {'x mlp':>6} {'train ms':>9} {'x mlp':>6}"
        )
        for row in table:
            print(f"{'':>{len(str(batch)) + 8}}{row['architecture']:<15} {row['infer_ms']:>9.2f} "
                  f"{row['infer_vs_mlp']:>6.2f} {row['train_ms']:>9.2f} {row['train_vs_mlp']:>6.2f}")  # fmt: skip
    at_1024 = {row["architecture"]: row for row in results if row["batch"] == 1024}
    return {
        "hamnet_vs_mlp_train": at_1024["hamnet"]["train_vs_mlp"],
        "hamnet_vs_mlp_infer": at_1024["hamnet"]["infer_vs_mlp"],
        "hamnet_vs_paper_width_mlp_train": (
            at_1024["hamnet"]["train_ms"] / at_1024[PAPER_MLP]["train_ms"]
        ),
        "sm_vs_mlp_train": at_1024["sm"]["train_vs_mlp"],
        "hyper_vs_mlp_train": at_1024["hyper"]["train_vs_mlp"],
        "paper_train_vs_mlp": PAPER_TRAIN_VS_MLP,
        "threads": args.threads,
        "device": "cpu",
        "results": results,
    }


if __name__ == "__main__":
    report(main())
