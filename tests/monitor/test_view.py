"""The monitor's core end to end without Zenoh: real sim messages (and scripted perception,
policy, safety and trainer messages) go through the monitor's decoders into the view,
which writes an .rrd file; reading it back finds the robot posed where the sim says its
paddle is, the focus environment's scene, object, clouds and module activations, the
reward terms, success rate, safety events and trainer metrics."""

from __future__ import annotations

import numpy as np
import pytest
import rerun as rr

from hamnet.monitor.blueprint import (
    DAGGER_METRICS,
    DEFAULT_TIMELINE,
    PPO_METRICS,
    THROUGHPUT_METRICS,
    TRAINING_TIMELINE,
    blueprint,
)
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
from hamnet.monitor.palette import REWARD_COLOURS
from hamnet.monitor.robot import RobotView
from hamnet.monitor.view import MonitorView
from hamnet.runtime.tensor import from_tensor
from hamnet.sim.scene import NUM_BASE
from hamnet.sim.scene_view import save_scene
from hamnet.task.rewards import REWARD_NAMES
from tests.monitor.recorded import (
    TRANSITIONS_PER_ITERATION,
    B,
    L,
    M,
    Rrd,
    action,
    clip_event,
    dagger_metrics,
    drawn_ee,
    metrics,
    sim_messages,
    statistics_event,
    tokens,
    xyzw_matrix,
)

ENV = 1
"""The environment in focus (not 0, so that a wrong row shows)."""
STEPS = 7
TIMEOUT = 3
ITERATIONS = 3
"""Trainer iterations published after the sim's steps."""


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
    view.on_event(decode_event(clip_event(5, ENV)))
    view.on_event(decode_event(statistics_event(6)))
    for iteration in range(1, ITERATIONS + 1):
        sent.setdefault("metrics", []).append(metrics(iteration, rng))
        view.on_metrics(decode_metrics(sent["metrics"][-1]))
    sent["metrics"].append(dagger_metrics(ITERATIONS + 1, rng))  # the DAgger tab's plots
    view.on_metrics(decode_metrics(sent["metrics"][-1]))
    recording.flush()
    recording.disconnect()
    return Rrd(path), sent


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
    assert sorted(rrd.rows("/robot/fr3_paddle", "Transform3D:translation")) == list(
        range(STEPS + 1)
    )
    for state in sent["state"]:
        ee = from_tensor(state.ee_pos_rot6d, np.float32, (B, 9))[ENV, :3]
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
    expected = "CLIPPED_CARTESIAN [cartesian_clip] clipped 2 of 10 commands; 1 envs (env in focus)"
    assert text == {5: [expected]}
    assert rrd.rows("/safety/clip_rate/cartesian_clip", "Scalars:scalars") == {6: [0.25]}
    assert rrd.rows("/safety/clip_rate/joint_limits", "Scalars:scalars") == {6: [0.0]}
    assert "/safety/clip_rate/torque_preclip" not in rrd.entities  # no command: no share
    success = [m.scalars["success_rate"] for m in sent["metrics"]]
    by_iteration = rrd.rows("/trainer/success_rate", "Scalars:scalars", "iteration")
    assert by_iteration == {i + 1: [s] for i, s in enumerate(success)}
    by_transitions = rrd.rows("/trainer/success_rate", "Scalars:scalars", "env_transitions")
    assert by_transitions == {
        (i + 1) * TRANSITIONS_PER_ITERATION: [s] for i, s in enumerate(success)
    }
    assert rrd.rows("/trainer/return/goal", "Scalars:scalars") == {  # the newest step
        STEPS: [sent["metrics"][-1].scalars["return/goal"]]
    }


def test_every_view_of_the_layout_shows_logged_entities(run) -> None:
    """The blueprint in the file names views by entity path: a path renamed in the view but
    not in the blueprint (an empty panel) fails here."""
    rrd, _ = run
    assert len(rrd.view_origins) == 29
    for origin in rrd.view_origins:
        assert any(e == origin or e.startswith(origin.rstrip("/") + "/") for e in rrd.entities), (
            origin
        )


def test_the_view_opens_on_the_step_timeline(run) -> None:
    rrd, _ = run
    assert rrd.blueprint_values("TimePanelBlueprint:timeline") == [[DEFAULT_TIMELINE]] == [["step"]]


def test_every_series_has_a_name_and_a_colour_of_its_own_in_its_plot(run) -> None:
    """Reward terms keep their colours in every plot; safety stages, modules and trainer
    returns differ from each other; the values are named by reward term, not values[i]."""
    rrd, _ = run
    plots = {
        "rewards": [f"/rewards/{t}" for t in REWARD_NAMES],
        "clip rate": ["/safety/clip_rate/cartesian_clip", "/safety/clip_rate/joint_limits"],
        "returns": [f"/trainer/return/{t}" for t in (*REWARD_NAMES, "total")],
        "success": ["/trainer/success_rate", "/episodes/success_rate"],
    }
    for plot, paths in plots.items():
        names = [n for p in paths for n in rrd.static(p, "SeriesLines:names")[0]]
        colours = [c for p in paths for c in rrd.static(p, "SeriesLines:colors")[0]]
        assert len(set(names)) == len(set(colours)) == len(paths), plot
    for path in ("/policy/values", "/policy/modules"):
        names, colours = (rrd.static(path, f"SeriesLines:{c}")[0] for c in ("names", "colors"))
        assert len(set(names)) == len(set(colours)) == len(names), path
    assert rrd.static("/policy/values", "SeriesLines:names")[0] == [
        f"value: {t}" for t in REWARD_NAMES
    ]
    reward = rrd.static("/rewards/goal", "SeriesLines:colors")[0]
    assert rrd.static("/trainer/return/goal", "SeriesLines:colors")[0] == reward
    assert set(REWARD_NAMES) <= set(REWARD_COLOURS)


def test_the_learning_curves_say_why_they_are_empty_until_the_first_metrics(run) -> None:
    rrd, sent = run
    status = [text for (text,) in rrd.static("/trainer/status", "TextDocument:text")]
    assert "No trainer metrics yet" in status[0] and "hamnet trainer" in status[0]
    assert status[-1].startswith(f"**iteration {len(sent['metrics'])}**")
    assert len(status) == 1 + len(sent["metrics"])


def test_without_a_sim_the_learning_curves_are_on_the_trainers_steps(tmp_path) -> None:
    path = tmp_path / "trainer.rrd"
    recording = rr.RecordingStream("test_monitor_trainer_only")
    recording.save(path)
    view = MonitorView(recording)
    rng = np.random.default_rng(0)
    for iteration in (1, 2):
        view.on_metrics(decode_metrics(metrics(iteration, rng)))
    recording.flush()
    recording.disconnect()
    assert sorted(Rrd(path).rows("/trainer/success_rate", "Scalars:scalars")) == [1, 2]


def test_a_training_runs_layout_shows_only_what_a_trainer_publishes(tmp_path) -> None:
    """`--layout training`, for a run without a sim: every view of it shows logged trainer
    entities (none of the scene's or the focus environment's, which stay empty there), and
    it opens on the env_transitions timeline."""
    path = tmp_path / "training.rrd"
    recording = rr.RecordingStream("test_monitor_training")
    recording.save(path, default_blueprint=blueprint("training"))
    view = MonitorView(recording)
    rng = np.random.default_rng(0)
    for iteration in (1, 2):
        view.on_metrics(decode_metrics(metrics(iteration, rng)))
    view.on_metrics(decode_metrics(dagger_metrics(3, rng)))
    recording.flush()
    recording.disconnect()
    rrd = Rrd(path)
    assert len(rrd.view_origins) == 3 + len(PPO_METRICS + DAGGER_METRICS + THROUGHPUT_METRICS)
    for origin in rrd.view_origins:
        assert origin.startswith("/trainer/"), origin
        assert any(e == origin or e.startswith(origin + "/") for e in rrd.entities), origin
    assert rrd.blueprint_values("TimePanelBlueprint:timeline") == [[TRAINING_TIMELINE]]
    assert sorted(rrd.rows("/trainer/success_rate", "Scalars:scalars")) == [1, 2, 3]


def test_show_scene_files_open_with_a_layout_a_camera_and_a_legend(tmp_path) -> None:
    """`hamnet sim --show-scene` writes `save_scene`'s file: its blueprint places the eye
    outside the scene, and the legend and pedestal are logged."""
    path = tmp_path / "scene.rrd"
    save_scene(path, seed=5)
    rrd = Rrd(path)
    assert sorted(rrd.view_origins) == [
        "/",
        "/legend",
    ]  # the blueprint stores views in no fixed order
    [[eye]] = rrd.blueprint_values("EyeControls3D:position")
    assert np.linalg.norm(eye) > 1.5  # m from the robot: the table and the arm fit
    assert {"/legend", "/scene/pedestal"} <= rrd.entities
