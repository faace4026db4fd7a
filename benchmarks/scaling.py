"""Scaling benchmark: training throughput with 1, 2 and 4 rollout worker processes against one
worker, the learner's share of the time, and what TLS costs against plain TCP.

Every setup is deployed as across machines, on loopback: a `hamnet router` (its own port),
`hamnet rollout` processes as its clients, and the trainer's loop (`Runner` learning from
`hamnet.trainer.collection.streamed.Streamed`, synchronous) in this process as a client too. Each worker
has the same `--num-envs` environments, so an update learns from workers x num-envs of
them: linear scaling means the rate grows with the workers. One warm-up iteration (it
includes the workers' start) is not measured. The TLS setup is the 2-worker one with
`hamnet certs`' certificates (`--tls-dir`, tls/ links, mutual authentication).

Produces a progress line per setup on stderr and, as the last stdout line, one JSON object:
`env_steps_per_s` and `learner_share` per worker count, `efficiency_2_workers` (rate with 2 /
(2 x rate with 1); goal >= 0.85 until the learner saturates), `efficiency_4_workers`
(rate with 4 / (4 x rate with 1)), `saturation` (where and why it falls below 0.85 of
linear), `tls_env_steps_per_s` and `tls_overhead` (time per env
step over TLS / over TCP - 1; null with `tls_note` when the TLS setup cannot run).

    .venv/bin/python benchmarks/scaling.py --quick     # state-mlp, 5 iterations a setup: 1 min on 2 cores
    .venv/bin/python benchmarks/scaling.py             # HAMnet, 20 iterations a setup

On a machine with fewer cores than workers + 1 the processes share cores: the rate then
stops growing with the workers because the CPUs, not the learner, are saturated
(`learner_share` tells which).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import subprocess
import sys
import time
from pathlib import Path
from tempfile import TemporaryDirectory

# Run as a script, so benchmarks/ is on sys.path: the helpers every benchmark shares.
from common import header, loopback_transport, progress, report, spawn, stop

from hamnet.runtime.service import Service, ServiceIdentity
from hamnet.runtime.transport import free_port
from hamnet.sim.stages import stage_config
from hamnet.trainer.collection.streamed import Streamed
from hamnet.trainer.runners.run_config import RunConfig
from hamnet.trainer.runners.runner import Runner

WORKERS = (1, 2, 4)
"""Rollout worker processes of the plain setups."""
TLS_WORKERS = 2
"""Rollout worker processes of the TLS setup (compared with the plain one of as many)."""
IDENTITIES = ("router", "trainer", "rollout")
"""Certificates the TLS setup issues (each command presents its own name's)."""


def make_certificates(directory: Path) -> str | None:
    """A CA and the certificates of `IDENTITIES` in `directory`; None, or why not."""
    for args in (["init"], *(["issue", name] for name in IDENTITIES)):
        result = subprocess.run([sys.executable, "-m", "hamnet", "certs", *args, "--dir",
                                 str(directory)], check=False, capture_output=True, text=True)  # fmt: skip
        if result.returncode:
            return f"hamnet certs {' '.join(args)} failed: {result.stderr.strip()[-300:]}"
    return None


def rate(config: RunConfig, workers: int, iterations: int, tls_dir: Path | None) -> dict:
    """Env steps/s and the learner's share of `iterations` iterations of the trainer learning
    from `workers` rollout processes through a router on loopback (TLS with `tls_dir`)."""
    protocol = "tcp" if tls_dir is None else "tls"
    endpoint = f"{protocol}/127.0.0.1:{free_port()}"
    client = loopback_transport("scaling", mode="client", rendezvous="", connect=(endpoint,),
                                tls_dir=tls_dir)  # fmt: skip
    secure = [] if tls_dir is None else ["--tls-dir", str(tls_dir)]
    run = ["--architecture", config.architecture, "--sim.num-envs", str(config.num_envs),
           "--sim.nthread", "1", "--steps-per-rollout", str(config.rollout_steps)]  # fmt: skip
    if config.random_encoder:
        run.append("--random-encoder")
    processes = [spawn(["router", "--listen", endpoint, "--namespace", client.namespace, *secure])]
    processes += [spawn(["rollout", "--worker", str(k), *run], client) for k in range(workers)]
    transport = dataclasses.replace(client, identity="" if tls_dir is None else "trainer")
    try:
        with Service(ServiceIdentity("trainer", "bench"), transport) as service:
            runner = Runner(config, lambda policy: Streamed(service, policy, workers,
                                                            config.num_envs))  # fmt: skip
            runner.iterate()  # the workers start
            started = time.perf_counter()
            rows = [runner.iterate() for _ in range(iterations)]
            elapsed = time.perf_counter() - started
    finally:
        stop(processes)
    steps = iterations * workers * config.num_envs * config.rollout_steps
    learning = sum(row["learn_s"] for row in rows)
    return {"env_steps_per_s": steps / elapsed, "learner_share": learning / elapsed}


def saturation(plain: dict[int, dict], cpus: int) -> str:
    """Where the rate stops growing at 0.85 of linear, and why (CPUs or the learner)."""
    one = plain[1]["env_steps_per_s"]
    for workers, figures in plain.items():
        if workers > 1 and figures["env_steps_per_s"] < 0.85 * workers * one:
            share = figures["learner_share"]
            why = (f"{workers} workers and the trainer share {cpus} cores: the CPUs saturate, "
                   if workers + 1 > cpus else "the learner saturates, " if share > 0.5
                   else "neither the cores nor the learner: the transport or the router, ")  # fmt: skip
            return (
                f"below 0.85 of linear from {workers} workers; {why}learner {share:.0%} of the time"
            )
    return f"at least 0.85 of linear up to {max(plain)} workers"


def main() -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true",
                        help="the state-mlp policy, 5 iterations a setup (under 2 min)")  # fmt: skip
    parser.add_argument("--num-envs", type=int, default=8, help="environments per worker")
    parser.add_argument("--architecture", default=None,
                        help="policy architecture (default: state-mlp with --quick, else hamnet)")  # fmt: skip
    args = parser.parse_args()
    iterations = 5 if args.quick else 20
    architecture = args.architecture or ("state-mlp" if args.quick else "hamnet")
    with TemporaryDirectory() as scratch:
        config = RunConfig(sim=stage_config("easy", num_envs=args.num_envs, nthread=1),
                           architecture=architecture, random_encoder=True, steps_per_rollout=8,
                           run_dir=Path(scratch) / "run", eval_episodes=0)  # fmt: skip
        plain = {}
        for workers in WORKERS:
            plain[workers] = rate(config, workers, iterations, None)
            progress(f"{workers} rollout worker(s), tcp: {plain[workers]['env_steps_per_s']:.0f} "
                     f"env steps/s, learner {plain[workers]['learner_share']:.0%} of the time")  # fmt: skip
        certificates = Path(scratch) / "certs"
        tls_note = make_certificates(certificates)
        tls = None if tls_note else rate(config, TLS_WORKERS, iterations, certificates)
        if tls is not None:
            progress(
                f"{TLS_WORKERS} rollout workers, tls: {tls['env_steps_per_s']:.0f} env steps/s"
            )
    one = plain[1]["env_steps_per_s"]
    overhead = (
        None if tls is None else plain[TLS_WORKERS]["env_steps_per_s"] / tls["env_steps_per_s"] - 1
    )
    return {
        **header("scaling", args.quick),
        "architecture": architecture,
        "num_envs_per_worker": args.num_envs,
        "steps_per_rollout": config.rollout_steps,
        "iterations": iterations,
        "env_steps_per_s": {str(w): round(r["env_steps_per_s"], 1) for w, r in plain.items()},
        "learner_share": {str(w): round(r["learner_share"], 3) for w, r in plain.items()},
        "efficiency_2_workers": round(plain[2]["env_steps_per_s"] / (2 * one), 3),
        "efficiency_4_workers": round(plain[4]["env_steps_per_s"] / (4 * one), 3),
        "tls_env_steps_per_s": None if tls is None else round(tls["env_steps_per_s"], 1),
        "tls_overhead": None if tls is None else round(overhead, 3),
        "tls_note": tls_note or f"{TLS_WORKERS} workers over tls/ against tcp/, both via a router",
        "saturation": saturation(plain, os.cpu_count() or 1),
        "cpus": os.cpu_count(),
    }


if __name__ == "__main__":
    report(main())
