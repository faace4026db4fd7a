"""The monitor's core end to end without Zenoh: real sim messages (and scripted perception,
policy, safety and trainer messages) go through the monitor's decoders into the view,
which writes an .rrd file; reading it back finds the robot posed where the sim says its
paddle is, the focus environment's scene, object, clouds and module activations, the
reward terms, success rate, safety events and trainer metrics."""

from __future__ import annotations


import numpy as np
import pytest
import rerun as rr

from hamnet.monitor.blueprint import blueprint
from hamnet.monitor.config import ViewConfig
from hamnet.monitor.decode import (
    decode_action,
    decode_event,
    decode_metrics,
    decode_scene,
    decode_state,
    decode_tokens,
    decode_transition,
)
from hamnet.monitor.robot import RobotView
from hamnet.monitor.view import MonitorView
from hamnet.proto.common_pb2 import Header
from hamnet.proto.safety_pb2 import SafetyEvent, SafetyEventKind
from hamnet.proto.trainer_pb2 import Metrics
from hamnet.runtime.tensor import from_tensor, to_tensor
from hamnet.sim.scene import NUM_BASE
from tests.monitor.recorded import B, L, M, Rrd, action, drawn_ee, sim_messages, tokens, xyzw_matrix

ENV = 1
"""The environment in focus (not 0, so that a wrong row shows)."""
STEPS = 7
TIMEOUT = 3


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> tuple[Rrd, dict[str, list]]:
    """Every message of STEPS steps drawn into an .rrd file; returns it and the messages."""
    path = tmp_path_factory.mktemp("monitor") / "view.rrd"
    rng = np.random.default_rng(0)
    sent: dict[str, list] = {"state": [], "scene": [], "transition": [], "tokens": [], "action": []}
    recording = rr.RecordingStream("test_monitor")
    recording.save(path, default_blueprint=blueprint())
    view = MonitorView(recording, ViewConfig(env=ENV))
    for topic, message in sim_messages(STEPS, TIMEOUT):
        sent[topic].append(message)
        step = message.header.step
        if topic == "state":
            view.on_state(decode_state(message, ENV))
            sent["tokens"].append(tokens(step, rng))
            view.on_clouds(decode_tokens(sent["tokens"][-1], ENV))
            sent["action"].append(action(step, rng))
            view.on_action(decode_action(sent["action"][-1], ENV))
        elif topic == "scene":
            view.on_scene(decode_scene(message, ENV))
        else:
            view.on_transition(decode_transition(message, ENV, drawn=True))
    view.on_event(decode_event(clip_event()))
    view.on_event(decode_event(statistics_event()))
    view.on_metrics(decode_metrics(Metrics(header=Header(step=1), iteration=4,
                                           scalars={"loss/policy": 0.25, "kl": 0.01})))  # fmt: skip
    recording.flush()
    recording.disconnect()
    return Rrd(path), sent


def clip_event() -> SafetyEvent:
    message = SafetyEvent(header=Header(step=5), kind=SafetyEventKind.CLIPPED_CARTESIAN,
                          stage="cartesian_clip", reason="clipped 2 of 10 commands")  # fmt: skip
    to_tensor(np.array([ENV], np.int32), message.env_ids)
    return message


def statistics_event() -> SafetyEvent:
    message = SafetyEvent(header=Header(step=6), stage="", reason="statistics over 5 s")
    message.stages.add(stage="cartesian_clip", commands=40, clipped=10, max_excess=0.1)
    message.stages.add(stage="joint_limits", commands=40, clipped=0)
    message.stages.add(stage="torque_preclip", commands=0, clipped=0)
    return message


def test_robot_geometry_is_logged_once_and_matches_the_model(run) -> None:
    """Every geom of the FR3 model is drawn exactly once, static, under its body; the
    capsule `fr3_link2_arm` (fromto 0 0 0 -> 0 -0.15 0 in fr3.xml) spans those points."""
    rrd, _ = run
    robot = RobotView()
    counts = {"boxes": "Boxes3D:half_sizes", "capsules": "Capsules3D:lengths",
              "cylinders": "Cylinders3D:lengths"}  # fmt: skip
    drawn = sum(len(v) for body in robot.paths for kind, column in counts.items()
                for v in rrd.static(f"/{body}/{kind}", column))  # fmt: skip
    assert drawn == robot.model.ngeom == 15
    for path in robot.paths:
        assert not any(s for s, _ in rrd.batches[f"/{path}"]), "a body pose was logged static"
    caps = "/robot/fr3_link2/capsules"
    starts = np.array(rrd.static(caps, "Capsules3D:translations")[0])  # (2, 3)
    lengths = np.array(rrd.static(caps, "Capsules3D:lengths")[0])
    quats = rrd.static(caps, "Capsules3D:quaternions")[0]
    ends = [s + n * xyzw_matrix(q)[:, 2] for s, n, q in zip(starts, lengths, quats, strict=True)]
    arm = np.argmin(np.abs(lengths - 0.15))
    segment = sorted([tuple(np.round(starts[arm], 6)), tuple(np.round(ends[arm], 6))])
    np.testing.assert_allclose(segment, [(0, -0.15, 0), (0, 0, 0)], atol=1e-6)


def test_paddle_is_drawn_where_the_sim_reports_the_end_effector(run) -> None:
    """The paddle body's drawn pose, moved to site `ee` (0.09 m along its z), equals the
    end-effector position in each state of the focus environment (sim's own kinematics)."""
    rrd, sent = run
    assert sorted(rrd.rows("/robot/fr3_paddle", "Transform3D:translation")) == list(range(STEPS + 1))
    for state in sent["state"]:
        ee = from_tensor(state.ee_pose, np.float32, (B, 9))[ENV, :3]
        np.testing.assert_allclose(drawn_ee(rrd, state.header.step), ee, atol=1e-4)


def test_scene_object_and_goal_of_the_focus_environment(run) -> None:
    rrd, sent = run
    scenes = sent["scene"]
    assert [s.header.step for s in scenes] == [0, TIMEOUT, 2 * TIMEOUT]
    half_sizes = rrd.rows("/scene/base", "Boxes3D:half_sizes")
    assert sorted(half_sizes) == [0, TIMEOUT, 2 * TIMEOUT]
    for scene in scenes:
        row = list(from_tensor(scene.env_ids)).index(ENV)
        active = from_tensor(scene.cuboid_active)[row, :NUM_BASE]
        expected = from_tensor(scene.cuboid_half_size)[row, :NUM_BASE][active]
        np.testing.assert_allclose(half_sizes[scene.header.step], expected, rtol=1e-6)
        surface = rrd.rows("/object/surface", "Points3D:positions")[scene.header.step]
        np.testing.assert_allclose(surface, from_tensor(scene.object_points)[row], rtol=1e-6)
    poses = rrd.rows("/object", "Transform3D:translation")
    for state in sent["state"]:
        pose = from_tensor(state.privileged.object_pose)[ENV]
        np.testing.assert_allclose(poses[state.header.step][0], pose[:3], rtol=1e-6)
    goal = rrd.rows("/goal", "Transform3D:translation")[STEPS]
    np.testing.assert_allclose(goal[0], from_tensor(sent["state"][-1].goal_pose)[ENV, :3])


def test_clouds_and_module_activations_of_the_focus_environment(run) -> None:
    rrd, sent = run
    for name in ("object", "environment", "local"):
        clouds = rrd.rows(f"/clouds/{name}", "Points3D:positions")
        for message in sent["tokens"]:
            expected = from_tensor(getattr(message, f"{name}_cloud"))[ENV]
            np.testing.assert_allclose(clouds[message.header.step], expected)
    weights = rrd.rows("/policy/module_weights", "Tensor:data")
    for message in sent["action"]:
        tensor = weights[message.header.step][0]
        assert tensor["shape"] == [L, M] and tensor["names"] == ["layer", "module"]
        expected = from_tensor(message.module_weights)[ENV]
        np.testing.assert_allclose(np.array(tensor["buffer"]).reshape(L, M), expected)
    means = rrd.rows("/policy/modules", "Scalars:scalars")
    np.testing.assert_allclose(means[0], from_tensor(sent["action"][0].module_weights)[ENV].mean(0),
                               rtol=1e-6)  # fmt: skip


def test_rewards_success_rate_events_and_metrics(run) -> None:
    """Reward terms every step; after the timeouts at steps 2 and 5 (both environments,
    no success while held still) the success rate over 2 and 4 episodes is 0; the clip
    event is in the log and the statistics give the clipped share per stage."""
    rrd, sent = run
    names = list(sent["transition"][0].reward_names)
    assert names == ["success", "goal", "contact"]
    for name in names:
        terms = rrd.rows(f"/rewards/{name}", "Scalars:scalars")
        assert sorted(terms) == list(range(STEPS))
        column = names.index(name)
        for message in sent["transition"]:
            expected = from_tensor(message.reward_terms)[ENV, column]
            np.testing.assert_allclose(terms[message.header.step], [expected], rtol=1e-6)
    assert rrd.rows("/episodes/success_rate", "Scalars:scalars") == {2: [0.0], 5: [0.0]}
    assert sorted(rrd.rows("/episodes/return", "Scalars:scalars")) == [2, 5]
    text = rrd.rows("/safety/events", "TextLog:text")
    assert text == {5: ["CLIPPED_CARTESIAN [cartesian_clip] clipped 2 of 10 commands; "
                        "1 envs (env in focus)"]}  # fmt: skip
    assert rrd.rows("/safety/clip_rate/cartesian_clip", "Scalars:scalars") == {6: [0.25]}
    assert rrd.rows("/safety/clip_rate/joint_limits", "Scalars:scalars") == {6: [0.0]}
    assert "/safety/clip_rate/torque_preclip" not in rrd.entities  # no command: no share
    assert rrd.rows("/trainer/loss/policy", "Scalars:scalars", "iteration") == {4: [0.25]}
    assert rrd.rows("/trainer/kl", "Scalars:scalars") == {STEPS: [0.01]}  # newest step


def test_every_view_of_the_layout_shows_logged_entities(run) -> None:
    """The blueprint in the file names views by entity path: a path renamed in the view but
    not in the blueprint (an empty panel) fails here."""
    rrd, _ = run
    assert len(rrd.view_origins) == 11
    for origin in rrd.view_origins:
        assert any(e == origin or e.startswith(origin.rstrip("/") + "/") for e in rrd.entities), origin
