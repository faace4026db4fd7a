"""The monitor's shell without a network: fed a burst of real sim messages with clouds and
actions faster than `--max-rate-hz`, it draws only the first step, drops the state,
clouds and action of every other step before decoding them (reason `rate`, counted as
Health reports drops), still counts every episode in the success rate, and counts and
survives a malformed payload."""

from __future__ import annotations

import numpy as np
import rerun as rr

from hamnet.monitor.config import MonitorLoopConfig, ViewConfig
from hamnet.monitor.shell import MonitorShell
from hamnet.monitor.view import MonitorView
from hamnet.runtime.codec import encode
from hamnet.runtime.service import ServiceIdentity
from tests.monitor.recorded import Rrd, action, sim_messages, tokens
from tests.scripted import ScriptedService

STEPS, TIMEOUT = 6, 3


def test_a_burst_is_thinned_to_the_rate_and_episodes_are_still_counted(tmp_path) -> None:
    rng = np.random.default_rng(0)
    queue: list[tuple[str, bytes]] = [("state", b"\xff not a RobotState")]
    for topic, message in sim_messages(STEPS, TIMEOUT):
        queue.append((topic, encode(message)))
        if topic == "state":
            step = message.header.step
            queue += [("tokens", encode(tokens(step, rng))), ("action", encode(action(step, rng)))]
    service = ScriptedService(lambda published: queue.pop(0) if queue else None,
                              identity=ServiceIdentity("monitor", "0"))  # fmt: skip
    path = tmp_path / "burst.rrd"
    recording = rr.RecordingStream("test_monitor_shell")
    recording.save(path)
    view = MonitorView(recording, ViewConfig(env=1, max_rate_hz=0.1))  # one step per 10 s
    shell = MonitorShell(service, view, MonitorLoopConfig())
    assert shell.run() == 0
    recording.flush()
    recording.disconnect()

    key = "hamnet/t/{}/0/{}".format
    skipped = STEPS  # steps 1..STEPS of STEPS + 1 states
    assert dict(service.drops.counts) == {
        (key("sim", "state"), "decode"): 1,
        (key("sim", "state"), "rate"): skipped,
        (key("perception", "tokens"), "rate"): skipped,
        (key("policy", "action"), "rate"): skipped,
    }
    assert (shell.pacer.drawn, shell.pacer.skipped) == (1, skipped)
    rrd = Rrd(path)
    drawn = {"/robot/fr3_paddle": "Transform3D:translation", "/clouds/local": "Points3D:positions",
             "/policy/module_weights": "Tensor:data", "/rewards/goal": "Scalars:scalars"}  # fmt: skip
    for entity, column in drawn.items():
        assert list(rrd.rows(entity, column)) == [0], entity
    assert sorted(rrd.rows("/scene/base", "Boxes3D:half_sizes")) == [0, TIMEOUT, 2 * TIMEOUT]
    assert view.success.finished == 2 * 2  # both environments timed out twice
    assert rrd.rows("/episodes/success_rate", "Scalars:scalars") == {2: [0.0], 5: [0.0]}
