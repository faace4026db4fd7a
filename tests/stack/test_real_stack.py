"""compose/real.yaml under `hamnet up`, secure as shipped, with franky-sim (the libfranka
protocol on loopback) as the FR3 and the cameras' `sim` source in place of RealSense: the
bridge (franky driver), the cameras, perception from their frames, the student policy on
random weights and safety at 1 kHz close the loop for hundreds of steps (thousands in the
slow run) with zero robot errors; a forged out-of-limit command is dropped by the router
and a NaN action is rejected by safety, so neither reaches the robot; when the policy is
killed the watchdog brings the arm to rest."""

from __future__ import annotations

import os
import signal
import uuid
from pathlib import Path

import numpy as np
import pytest
import yaml

from hamnet.fr3.limits import FR3
from hamnet.launcher.certs_cli import main as certs
from hamnet.launcher.stack import load
from hamnet.policy.registry import build, with_changes
from hamnet.policy.weights import save_checkpoint
from hamnet.proto.common_pb2 import Header
from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.proto.safety_pb2 import SafeCommand, SafetyEvent, SafetyEventKind
from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime.codec import encode
from hamnet.runtime.tensor import from_tensor, to_tensor
from hamnet.runtime.transport import TransportConfig, free_port
from hamnet.security.certs import issue
from tests.franky_sim import franky_sim
from tests.security.clients import Running
from tests.stack.up import up

COMPOSE = Path(__file__).resolve().parents[2] / "compose"
REST_STATES = 10
"""Consecutive states within 1 mrad of each other that show the arm at rest: how long the
brake takes depends on how fast franky-sim steps on the loaded machine, so the test waits
for them rather than a fixed time (test_franky_stack.py times the watchdog's stop)."""


SPACE = load(COMPOSE / "real.yaml").services["safety"].args["safety.action-magnitude.space"]
"""The action space real.yaml's safety filter reads (it drops actions of another): the test's
student acts in it, and so does the broken policy's NaN action."""


def real_stack(folder: Path, host: str) -> tuple[Path, str]:
    """compose/real.yaml for franky-sim at `host` and simulated cameras, in `folder`, with
    its certificates; returns its path and its router's endpoint."""
    document = yaml.safe_load((COMPOSE / "real.yaml").read_text())
    services = document["services"]
    # franky-sim steps in Python: on 2 loaded cores its clock can stall past the 0.1 s that
    # means a lost link on a real FR3, so this test allows it a second (and a command
    # deadline of 2 s: the whole stack shares those 2 cores).
    services["robot"]["args"].update({"franky.host": host, "franky.realtime": "ignore",
                                      "franky.link-timeout-s": 1.0, "franky.deadline-s": 2.0})  # fmt: skip
    services["camera"]["args"] = {"source": "sim"}
    services["perception"]["args"].update(segmenter="mask")
    # Random weights at PyTorch's initialization, whose mean drives the arm (an orthogonal
    # output layer, the default, starts it near 0 and the test must see the arm follow).
    config = with_changes("student", init="torch", action_space=SPACE)
    weights = folder / "student.safetensors"
    save_checkpoint(weights, build("student", config, seed=0), 1)
    services["policy"]["args"] = {"weights": str(weights), "deterministic": True}
    # The test kills the policy to see the watchdog bring the arm to rest: restarted, as the
    # stack file's default would, it acts again and safety rightly follows it.
    services["policy"]["restart"] = {"max_restarts": 0}
    services["policy"]["critical"] = False
    for auxiliary in ("monitor", "record", "watch"):
        del services[auxiliary]
    endpoint = f"tls/127.0.0.1:{free_port()}"
    document["secure"].update(tls_dir=str(folder / "certs"), listen=endpoint,
                              access=str(COMPOSE / "secure" / "router.json5"))  # fmt: skip
    document.update(outputs=[], duration_s=600)  # a bound; the test stops it
    path = folder / "real.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    assert certs(["stack", str(path)]) == 0
    for identity in ("monitor", "record"):  # the test reads (and forges) as these
        issue(folder / "certs", identity, days=1)
    return path, endpoint


@pytest.mark.parametrize(
    "steps", [150, pytest.param(2000, marks=[pytest.mark.slow, pytest.mark.timeout(900)])]
)
def test_the_real_stack_drives_franky_sim_safely(tmp_path: Path, steps: int) -> None:
    with franky_sim() as (host, _):
        path, endpoint = real_stack(tmp_path, host)
        namespace = f"real{uuid.uuid4().hex[:8]}"
        with up(path, TransportConfig(namespace=namespace), cwd=tmp_path) as run:
            stack = Running(
                run, tmp_path / "certs", namespace, endpoint, deadline_s=120 + steps * 0.2
            )
            try:
                drive_then_kill(stack, steps)
            finally:
                stack.close()


def drive_then_kill(stack: Running, steps: int) -> None:
    states = stack.collect("sim/<w>/state", RobotState)
    actions = stack.collect("policy/<w>/action", PolicyAction)
    robot_events = stack.collect("bridge/<w>/event", SafetyEvent, "record")  # observers read it
    safety_events = stack.collect("safety/<w>/event", SafetyEvent)
    stack.wait(lambda: len(actions) >= 20, "the student acts on the bridge's states")
    forger = stack.client("monitor")
    forger.put(stack.key("safety/<w>/command"), encode(out_of_limit(states[-1])))
    stack.wait(lambda: len(actions) >= steps, f"{steps} actions")
    assert [e.reason for e in robot_events if e.kind == SafetyEventKind.ROBOT_ERROR] == []
    q = np.stack([from_tensor(s.q, np.float32, (1, 7))[0] for s in states])
    assert np.ptp(q, axis=0).max() > 0.05, "the arm did not follow the policy"
    assert np.all(np.abs(q[:, 0]) <= FR3.q_max[0]), "the forged command reached the robot"

    os.killpg(stack.run.started()["policy/0"][-1], signal.SIGKILL)
    stack.wait(
        lambda: any(e.kind == SafetyEventKind.WATCHDOG_STOP for e in safety_events), "the watchdog"
    )
    answered: set[int] = set()
    broken = stack.client("policy")  # only the policy's identity may publish actions

    def nan_answered_and_rejected() -> bool:
        """Answer the newest state with a NaN action (once), as a broken policy would."""
        step = states[-1].header.step
        if step not in answered:
            nan = PolicyAction(header=Header(step=step), action_space=SPACE)
            to_tensor(np.full((1, 21), np.nan, np.float32), nan.action)
            broken.put(stack.key("policy/<w>/action"), encode(nan))
            answered.add(step)
        return any(e.kind == SafetyEventKind.REJECTED_NONFINITE for e in safety_events)

    stack.wait(nan_answered_and_rejected, "the NaN rejected")
    stack.wait(lambda: at_rest(states[-REST_STATES:]), f"{REST_STATES} states at rest")
    assert [e.reason for e in robot_events if e.kind == SafetyEventKind.ROBOT_ERROR] == []


def at_rest(states: list[RobotState]) -> bool:
    """Whether `states` are REST_STATES states whose joints moved under 1 mrad between each."""
    if len(states) < REST_STATES:
        return False
    q = np.stack([from_tensor(s.q, np.float32, (1, 7))[0] for s in states])
    return bool(np.abs(np.diff(q, axis=0)).max() < 1e-3)


def out_of_limit(state: RobotState) -> SafeCommand:
    """A command for `state` driving joint 1 to 3.5 rad at full stiffness (limit 2.9)."""
    q_ref = np.repeat(from_tensor(state.q, np.float32, (1, 7))[:, None, :], 100, axis=1)
    q_ref[:, :, 0] = 3.5
    command = SafeCommand(header=Header(step=state.header.step + 1), control_dt=0.001)
    to_tensor(q_ref, command.q_ref)
    to_tensor(np.full((1, 7), 600.0, np.float32), command.kp)
    to_tensor(np.full((1, 7), 50.0, np.float32), command.kd)
    to_tensor(FR3.tau_max[None].astype(np.float32), command.tau_limit)
    return command
