"""`hamnet bridge gap` on a short sequence: both arms move, the numbers are finite, one row
per joint, and our sim lands within a few mrad of franky-sim (the RMS gap of
docs/results/bridge-gap.json over 300 steps; the bound leaves about 3x)."""

from __future__ import annotations

import json

import numpy as np

from hamnet.bridge.gap import ArmSim, at_physics_steps
from hamnet.cli import main
from hamnet.fr3.limits import JOINT_NAMES

GAP = 0.01
"""RMS gap bound per joint, rad (measured: see docs/results/bridge-gap.json)."""


def test_a_short_sequence_moves_both_arms_and_reports_every_joint(tmp_path, capsys) -> None:
    assert main(["bridge", "gap", "--steps", "20", "--out", str(tmp_path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    numbers = json.loads(lines[-1])
    assert json.loads((tmp_path / "bridge-gap.json").read_text()) == numbers
    assert (tmp_path / "bridge-gap.png").stat().st_size > 0
    assert [line.split()[0] for line in lines[1:-1]] == list(JOINT_NAMES)
    for name, values in numbers.items():
        if name.endswith("_rad") and name != "start_q_rad":
            assert len(values) == len(JOINT_NAMES) and np.isfinite(values).all(), name
    assert max(numbers["range_sim_rad"]) > 0.05 and max(numbers["range_franky_rad"]) > 0.05
    assert max(numbers["rms_gap_rad"]) < GAP


def test_references_follow_the_physics_steps_by_the_sample_at_their_middle() -> None:
    q_ref = np.arange(10.0)[None, :, None]  # (1, S=10, 1): one sample per ms
    assert at_physics_steps(q_ref, 0.001, 0.0025)[0, :, 0].tolist() == [1.0, 3.0, 6.0, 8.0]


def test_the_gaps_arm_has_franky_sims_friction_unless_asked_for_the_compensated_one() -> None:
    """franky-sim's arm carries Menagerie's identified friction and does not compensate it,
    so the gap's arm must have it too; the sim's training default (the compensated arm, 5%
    nominal) would show franky-sim's missing compensation as a model error."""
    for mode, fraction in (("identified", 1.0), ("compensated", 0.05)):
        sim = ArmSim(friction_mode=mode)  # type: ignore[arg-type]
        dofs = sim.world.robot_dof
        written = sim.physics.fields["dof_frictionloss"][0, dofs]  # (J,) N m
        np.testing.assert_allclose(written, fraction * np.array([1.137] * 4 + [0.763, 0.44, 0.248]))
