"""What one step costs the monitor, so that `--max-rate-hz` and `--inbox-capacity` can be
set knowing how far behind it would fall (it never slows the stack: it runs in its own
process, and a full inbox drops the oldest payload).

Per step of B environments (state, clouds + tokens, action, transition, as the wire
carries them: P = 512 points per cloud, 17 x 128 tokens per cloud, L x M = 5 x 8 module
weights), measured on the monitor's own thread:

- `skip`: what a step the pacer skips costs (parse the header of state, tokens, action;
  decode the transition for the success rate);
- `decode`: the monitor's decoders alone (parse, check, cut out the focus env);
- `draw`: decode and log every frame into a Rerun recording written to an .rrd file;
- baseline `parse only`: protobuf parsing of the same payloads, nothing checked.

Warm-up, fixed seed, medians and p99 in ms; `max_drawn_steps_per_s` is 1 / median draw.
The last stdout line is one JSON object of figures. `--quick` runs in under a minute.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import rerun as rr

# Run as a script, so benchmarks/ is on sys.path: the helpers every benchmark shares.
from common import report, summary, timer

from hamnet.fr3.limits import Q_HOME
from hamnet.messages.robot_state import Observation
from hamnet.monitor.decode import decode_action, decode_state, decode_tokens, decode_transition
from hamnet.monitor.view import MonitorView
from hamnet.proto.common_pb2 import Header
from hamnet.proto.perception_pb2 import PerceptionTokens
from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.proto.sim_pb2 import RobotState, Transition
from hamnet.runtime.codec import encode, parse
from hamnet.runtime.tensor import to_tensor
from hamnet.sim.shell import encode_state
from hamnet.task.rewards import REWARD_NAMES

J, P, N, D, L, M = 7, 512, 17, 128, 5, 8
DISTINCT = 10
"""Different payloads per size, cycled (a step of 1024 envs is about 45 MB)."""
TYPES = {"state": RobotState, "tokens": PerceptionTokens, "action": PolicyAction,
         "transition": Transition}  # fmt: skip


def payloads(b: int, step: int, rng: np.random.Generator) -> dict[str, bytes]:
    """The four payloads of one step of `b` environments."""
    f = lambda *shape: rng.standard_normal((b, *shape)).astype(np.float32)  # noqa: E731
    pose = np.tile([0.5, 0.0, 0.1, 1.0, 0.0, 0.0, 0.0], (b, 1)).astype(np.float32)
    obs = Observation(
        episode_ids=np.arange(b, dtype=np.int64), episode_step=np.zeros(b, np.int32),
        q=np.tile(Q_HOME, (b, 1)) + 0.1 * f(J), dq=f(J), tau=f(J), ee_pos_rot6d=f(9),
        goal_pose=pose, object_pose=pose, object_velocity=f(6), physics_params=f(6),
    )  # fmt: skip
    transition = Transition(header=Header(step=step), reward_names=REWARD_NAMES)
    to_tensor(obs.episode_ids, transition.episode_ids)  # (B,)
    to_tensor(f(len(REWARD_NAMES)), transition.reward_terms)  # (B, R)
    for name in ("terminated", "truncated", "success"):
        to_tensor(np.zeros(b, bool), getattr(transition, name))  # (B,)
    tokens = PerceptionTokens(header=Header(step=step))
    for name in ("object", "environment", "local"):
        to_tensor(f(P, 3), getattr(tokens, f"{name}_cloud"))  # (B, P, 3)
        to_tensor(f(N, D), getattr(tokens, f"{'global' if name == 'environment' else name}_tokens"))
    action = PolicyAction(header=Header(step=step))
    to_tensor(f(21), action.action)
    to_tensor(np.full((b, L, M), 1.0 / M, np.float32), action.module_weights)  # (B, L, M)
    to_tensor(f(3), action.values)
    return {"state": encode(encode_state(obs, step)), "tokens": encode(tokens),
            "action": encode(action), "transition": encode(transition)}  # fmt: skip


def decode_step(step: dict[str, bytes], env: int = 0) -> list:
    """The monitor's decoders on one step's payloads."""
    return [
        decode_state(parse(RobotState, step["state"]), env),
        decode_tokens(parse(PerceptionTokens, step["tokens"]), env),
        decode_action(parse(PolicyAction, step["action"]), env),
        decode_transition(parse(Transition, step["transition"]), env, drawn=True),
    ]


def skip_step(step: dict[str, bytes]) -> None:
    """What a skipped step costs: headers only, and the transition for the success rate."""
    for name in ("state", "tokens", "action"):
        parse(TYPES[name], step[name]).header.step
    decode_transition(parse(Transition, step["transition"]), 0, drawn=False)


def parse_step(step: dict[str, bytes]) -> None:
    for name, payload in step.items():
        parse(TYPES[name], payload)


def timed(function, steps: list[dict[str, bytes]], warmup: int) -> dict[str, float]:
    """Median and p99 of `function(step)` over `steps` after `warmup` calls, ms."""
    for step in steps[:warmup]:
        function(step)
    call = timer(function)
    return summary([call(step) for step in steps[warmup:]], "ms", 1e3)


def main() -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="small sizes, under a minute")
    args = parser.parse_args()
    sizes, count, warmup = ((4, 64), 60, 10) if args.quick else ((4, 64, 256, 1024), 300, 30)
    rng = np.random.default_rng(0)
    results = []
    with tempfile.TemporaryDirectory() as folder:
        for b in sizes:
            distinct = [payloads(b, k, rng) for k in range(DISTINCT)]
            steps = [distinct[k % DISTINCT] for k in range(count)]
            recording = rr.RecordingStream("hamnet_monitor_benchmark")
            recording.save(Path(folder) / f"b{b}.rrd")
            view = MonitorView(recording)
            handlers = (view.on_state, view.on_clouds, view.on_action, view.on_transition)

            def draw(step: dict[str, bytes]) -> None:
                for handler, frame in zip(handlers, decode_step(step), strict=True):
                    handler(frame)

            row = {"num_envs": b, "payload_kb": sum(map(len, steps[0].values())) / 1024}
            for name, function in (("parse only (baseline)", parse_step), ("skip", skip_step),
                                   ("decode", decode_step), ("draw", draw)):  # fmt: skip
                row[name] = timed(function, steps, warmup)
            recording.flush()
            recording.disconnect()
            results.append(row)
            print(f"B={b:5d} {row['payload_kb']:9.0f} KB/step  " + "  ".join(
                f"{name} {row[name]['median_ms']:.2f}/{row[name]['p99_ms']:.2f} ms"
                for name in ("parse only (baseline)", "skip", "decode", "draw")))  # fmt: skip
    largest = results[-1]
    return {
        "results": results,
        "draw_median_ms_4": results[0]["draw"]["median_ms"],
        "max_drawn_steps_per_s_4": 1e3 / results[0]["draw"]["median_ms"],
        "max_drawn_steps_per_s_largest": 1e3 / largest["draw"]["median_ms"],
        "skip_vs_draw_largest": largest["skip"]["median_ms"] / largest["draw"]["median_ms"],
        "largest_num_envs": largest["num_envs"],
    }


if __name__ == "__main__":
    report(main())
