"""A stack file that rewires ports: `compose/shadow.yaml` runs a second policy whose `state`,
`tokens` and `scene` ports read another stack's keys (remapped, no code changed) and whose
actions go to its own namespace. Here the other stack is sim -> perception -> policy ->
safety as processes on real Zenoh; the shadow answers the very steps that stack's sim
publishes, while its own namespace has no sim at all."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

from hamnet.proto.policy_pb2 import PolicyAction
from hamnet.proto.sim_pb2 import RobotState
from hamnet.runtime import contract
from hamnet.runtime.pubsub import DropCounter, Inbox
from hamnet.runtime.transport import TransportConfig, open_session
from tests.conftest import transport_args
from tests.stack.up import up

ROOT = Path(__file__).resolve().parents[2]
STATE, ACTION = contract.topic("sim/<w>/state"), contract.topic("policy/<w>/action")


def test_a_shadow_policy_answers_another_stacks_states_through_remapped_ports(
    spawn, transport: TransportConfig, tmp_path: Path
) -> None:
    net = transport_args(transport)
    source = [spawn("sim", "--num-envs", "2", "--num-objects", "2", "--nthread", "1", *net),
              spawn("perception", "--random-init", *net),
              spawn("policy", "--random-init", "hamnet", *net), spawn("safety", *net)]  # fmt: skip
    shadow = dataclasses.replace(transport, namespace=f"{transport.namespace}shadow")
    stack = tmp_path / "shadow.yaml"
    stack.write_text((ROOT / "compose/shadow.yaml").read_text()
                     .replace("hamnet/demo/", f"hamnet/{transport.namespace}/"))  # fmt: skip
    session = open_session(transport)
    inbox = Inbox(session, DropCounter())
    inbox.subscribe("state", STATE.key(transport.namespace, w="0"), RobotState)
    inbox.subscribe("shadow", ACTION.key(shadow.namespace, w="0"), PolicyAction)
    inbox.subscribe("shadow_state", STATE.key(shadow.namespace, w="0"), RobotState)
    states, answered, own_states = set(), [], 0
    try:
        with up(stack, shadow, "--duration-s", "120", cwd=tmp_path) as run:
            deadline = time.monotonic() + 90
            while len(answered) < 10:
                for process in source:
                    assert process.poll() is None, process.stdout.read()
                assert run.process.poll() is None, run.output
                assert time.monotonic() < deadline, f"{len(answered)} shadow actions:\n{run.output}"
                received = inbox.get(timeout=0.5)
                if received is None:
                    continue
                if received.name == "state":
                    states.add(received.value.header.step)
                elif received.name == "shadow":
                    answered.append(received.value.header.step)
                else:
                    own_states += 1
        settled = time.monotonic() + 1.0  # the states of the last answers, still on their way
        while (left := settled - time.monotonic()) > 0:
            if (received := inbox.get(timeout=left)) is not None and received.name == "state":
                states.add(received.value.header.step)
    finally:
        session.close()
    assert set(answered) <= states, "the shadow answers the other stack's steps"
    assert own_states == 0, "no sim runs in the shadow's namespace"
