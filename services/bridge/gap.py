"""`hamnet bridge gap`: how far our FR3 model (`hamnet sim`) is from one no one here wrote
(franky-sim's MuJoCo FR3 behind the libfranka protocol), measured on the same commands.

One seeded sequence of safe commands (random policy actions through the deploy safety
filter, 1 kHz references) is planned closed-loop on our sim, from the posture franky-sim
starts at; the same commands are then replayed open-loop, in real time, by the bridge
(`BridgeCore` and the franky driver) on a franky-sim this command starts on loopback.
Planning on our sim keeps the sequence reproducible (no wall clock in it) and lets both
arms run exactly the same references. Per joint it reports the RMS difference of the two
arms' positions after each policy step, and each arm's RMS tracking error against the
reference it was holding then; a table, then one JSON line; `--out` writes the JSON
(`bridge-gap.json`) and a plot of the traces (`bridge-gap.png`).

Our sim executes a command as `VectorEnv.step` does (`BatchPhysics.set_gains` and `step`),
without episodes: the arm alone, every contact other than the arm's own pairs switched off
(no table, no object), nominal joint dynamics (no randomization). Its joint friction is the
identified one by default (`--friction-mode`): franky-sim's arm carries Menagerie's
identified friction and adds only gravity to the commanded torques, so it stands for an FR3
that does not compensate its own friction; the sim's training default, the compensated arm
a real FR3 presents behind libfranka, differs from franky-sim by that. The sim's physics step is
2.5 ms, so it follows the 1 kHz references by the sample in effect at the middle of each
step (`at_physics_steps`). Both follow the same law, kp (q_ref - q) - kd dq on top of
gravity compensation (the franky driver sends no reference velocity, for this reason).
franky-sim's references play on its own clock (`Driver.clock`), which runs below real time
on a loaded machine: both arms get them at the rate their physics runs.
"""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from hamnet.bridge.core import BridgeCommand, BridgeCore
from hamnet.bridge.franky_driver import CONTROL_PERIOD_S, FrankyDriver, FrankyDriverConfig
from hamnet.bridge.franky_sim import franky_sim
from hamnet.fr3.limits import JOINT_NAMES
from hamnet.messages.safe_command import Command
from hamnet.runtime.cli import parse
from hamnet.runtime.errors import ConfigError
from hamnet.safety.filter import SafetyFilter
from hamnet.safety.references import TrajectoryConfig
from hamnet.sim.objects.library import ObjectSet
from hamnet.sim.physics import BatchPhysics
from hamnet.sim.robot import JOINT_FRICTION, FrictionMode
from hamnet.sim.world import build_world

STALL_S = 5.0
"""Longest wall time a policy period may take on the robot's clock before the replay stops
waiting for it (a dead franky-sim's clock stands still)."""
ACTION_WIDTH = 21
"""The policy's raw action: joint residual, stiffness, damping ratio (7 each)."""


@dataclass(frozen=True)
class GapConfig:
    """The command sequence and where the report goes."""

    steps: int = 300
    """Policy steps (each one policy period of real time on franky-sim)."""
    seed: int = 0
    """Seed of the random policy actions."""
    policy_period_s: float = 0.1
    """Policy period, s (the paper's 10 Hz); references at libfranka's 1 kHz."""
    action_std: float = 0.7
    """Standard deviation of the random actions before their clip to [-1, 1]."""
    friction_mode: FrictionMode = "identified"
    """Our sim's joint friction (`hamnet.sim.robot.JOINT_FRICTION`, nominal): identified, as
    franky-sim's arm has it, or compensated, as the sim trains by default."""
    out: Path | None = None
    """Folder for bridge-gap.json and bridge-gap.png; nothing written when unset."""

    def __post_init__(self) -> None:
        if self.steps < 1:
            raise ConfigError(f"--steps must be >= 1, got {self.steps}")
        if not self.action_std > 0.0:
            raise ConfigError("--action-std must be > 0")
        if self.friction_mode not in JOINT_FRICTION:
            raise ConfigError(f"--friction-mode: no mode {self.friction_mode!r}")


@dataclass(frozen=True)
class Run:
    """One command sequence and what each arm did with it (N policy steps)."""

    commands: list[Command]
    """N commands, each (1, S, J) references at 1 kHz and (1, J) gains."""
    q_sim: np.ndarray
    """(N, J) our sim's joint positions after each step, rad."""
    lowest_z: float
    """Lowest height of any arm body's origin above the base over the run, m (franky-sim's
    floor is at the base)."""


class ArmSim:
    """Our sim's arm alone: one environment of the sim's world and physics, contacts off
    except the arm's own pairs, with the nominal joint friction of `friction_mode`."""

    def __init__(self, seed: int = 0, friction_mode: FrictionMode = "identified") -> None:
        self.world = world = build_world(ObjectSet.procedural(1, seed))
        self.physics = BatchPhysics(world, 1, nthread=1)
        nominal = np.array([[1.0, 1.0, JOINT_FRICTION[friction_mode].nominal]])  # (1, 3)
        self.physics.set_joint_dynamics(np.array([0]), nominal)
        others = np.setdiff1d(np.arange(world.model.ngeom), self.physics.robot_geoms)
        self.physics.fields["geom_contype"][:, others] = 0
        self.physics.fields["geom_conaffinity"][:, others] = 0
        self.steps_per_period: int | None = None

    def reset(self, q: np.ndarray) -> np.ndarray:
        """Put the arm at rest at q (J,); the object (colliding with nothing) far away."""
        far = np.array([[0.0, 0.0, -50.0]])
        self.physics.set_state(np.array([0]), q[None], far, np.array([[1.0, 0.0, 0.0, 0.0]]))
        return self.q

    @property
    def q(self) -> np.ndarray:
        """(J,) joint positions, rad."""
        return self.physics.qpos[0, self.world.robot_qpos].copy()

    @property
    def dq(self) -> np.ndarray:
        """(J,) joint velocities, rad/s."""
        return self.physics.qvel[0, self.world.robot_dof].copy()

    def lowest_z(self) -> float:
        """Lowest arm body origin above the base, m."""
        return float(self.physics.bind("xpos")[0, self.world.robot_bodies, 2].min())

    def execute(self, command: Command) -> np.ndarray:
        """One command (1 kHz references) as `VectorEnv.step` runs it; returns q (J,)."""
        self.physics.set_gains(command.kp, command.kd, command.tau_limit)
        timestep = self.physics.timestep
        self.physics.step(at_physics_steps(command.q_ref, CONTROL_PERIOD_S, timestep), 1)
        return self.q


def at_physics_steps(q_ref: np.ndarray, sample_period_s: float, timestep: float) -> np.ndarray:
    """References (B, S, J) played one per `sample_period_s`, as (B, N, J) one per physics
    step: the sample in effect at the middle of each step (N = S * sample_period / timestep,
    which must be whole)."""
    steps = q_ref.shape[1] * sample_period_s / timestep
    if abs(steps - round(steps)) > 1e-6:
        raise ConfigError(
            f"{q_ref.shape[1]} samples of {sample_period_s} s are not whole "
            f"{timestep} s physics steps"
        )
    middle = (np.arange(round(steps)) + 0.5) * timestep / sample_period_s
    return q_ref[:, np.minimum(middle.astype(int), q_ref.shape[1] - 1)]


def plan(q0: np.ndarray, config: GapConfig) -> Run:
    """Random actions through the safety filter, closed-loop on our sim from q0 (J,)."""
    sim = ArmSim(config.seed, config.friction_mode)
    sim.reset(q0)
    trajectory = TrajectoryConfig(
        control_rate_hz=1.0 / CONTROL_PERIOD_S, policy_period_s=config.policy_period_s
    )
    safety = SafetyFilter(q0[None], trajectory=trajectory)
    rng = np.random.default_rng(config.seed)
    commands, q_sim, lowest = [], [], np.inf
    for step in range(config.steps):
        action = np.clip(config.action_std * rng.standard_normal((1, ACTION_WIDTH)), -1, 1)
        out = safety.command(action, sim.q[None], sim.dq[None], step)
        command = Command(out.q_ref, out.kp, out.kd, out.tau_limit)
        commands.append(command)
        q_sim.append(sim.execute(command))
        lowest = min(lowest, sim.lowest_z())
    return Run(commands, np.array(q_sim), float(lowest))


def replay(core: BridgeCore, commands: list[Command], period_s: float) -> np.ndarray:
    """The commands through the bridge core, one per policy period of the driver's clock;
    returns (N, J) the measured positions at the end of each period (just before the next
    command)."""
    clock = core.driver.clock
    q = []
    tick = clock()
    for step, command in enumerate(commands):
        errors = core.execute(BridgeCommand(step, core.episode_id, command), step)
        tick += period_s
        wall = time.monotonic() + STALL_S
        while clock() < tick and time.monotonic() < wall:
            time.sleep(CONTROL_PERIOD_S)
        reading = core.read()
        errors += core.poll()
        if errors or reading is None:
            names = ", ".join(f"{e.name} ({e.reason})" for e in errors) or "no reading"
            raise RuntimeError(f"the robot stopped at step {step}: {names}")
        q.append(reading.q)
    return np.array(q)


def rms(x: np.ndarray) -> np.ndarray:
    """Root mean square over the first axis."""
    return np.sqrt(np.mean(np.square(x), axis=0))


def report(run: Run, q_franky: np.ndarray, config: GapConfig) -> dict:
    """The per-joint numbers (rad) and what they came from, JSON-ready."""
    held = np.array([c.q_ref[0, -1] for c in run.commands])  # (N, J) reference after a step
    gap = run.q_sim - q_franky
    return {
        "joints": list(JOINT_NAMES),
        "rms_gap_rad": rms(gap).tolist(),
        "max_gap_rad": np.abs(gap).max(axis=0).tolist(),
        "rms_tracking_sim_rad": rms(run.q_sim - held).tolist(),
        "rms_tracking_franky_rad": rms(q_franky - held).tolist(),
        "range_sim_rad": np.ptp(run.q_sim, axis=0).tolist(),
        "range_franky_rad": np.ptp(q_franky, axis=0).tolist(),
        "lowest_body_z_m": run.lowest_z,
        "start_q_rad": run.commands[0].q_ref[0, 0].tolist(),
        "config": {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(config).items()},
    }


def table(numbers: dict) -> str:
    """The per-joint numbers as a text table, mrad."""
    columns = ("rms_gap_rad", "max_gap_rad", "rms_tracking_sim_rad", "rms_tracking_franky_rad")
    lines = ["joint       rms gap  max gap  rms track sim  rms track franky  (mrad)"]
    for j, name in enumerate(numbers["joints"]):
        row = [numbers[k][j] * 1e3 for k in columns]
        lines.append(f"{name:<10} {row[0]:8.2f} {row[1]:8.2f} {row[2]:14.2f} {row[3]:17.2f}")
    return "\n".join(lines)


def plot(run: Run, q_franky: np.ndarray, period_s: float, path: Path) -> None:
    """Per joint: the held reference and both arms' positions after each step."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = period_s * np.arange(1, len(q_franky) + 1)
    held = np.array([c.q_ref[0, -1] for c in run.commands])
    figure, axes = plt.subplots(len(JOINT_NAMES), 1, figsize=(10, 14), sharex=True)
    for j, axis in enumerate(axes):
        axis.plot(t, held[:, j], "k:", lw=1, label="reference")
        axis.plot(t, run.q_sim[:, j], lw=1, label="hamnet sim")
        axis.plot(t, q_franky[:, j], lw=1, label="franky-sim (bridge)")
        axis.set_ylabel(f"q{j + 1} (rad)")
    axes[0].legend(loc="upper right", ncol=3)
    axes[-1].set_xlabel("time (s)")
    figure.tight_layout()
    figure.savefig(path, dpi=80)
    plt.close(figure)


def measure(config: GapConfig) -> tuple[Run, np.ndarray, dict]:
    """Start franky-sim, plan on our sim from its posture, replay on it; the run, franky's
    positions (N, J) and the numbers."""
    with franky_sim() as (host, _):
        driver = FrankyDriver(FrankyDriverConfig(host=host, realtime="ignore"))
        core = BridgeCore(driver, config.policy_period_s)
        try:
            q0 = core.read().q
            run = plan(q0, config)
            started = driver.clock(), time.monotonic()
            q_franky = replay(core, run.commands, config.policy_period_s)
            rate = (driver.clock() - started[0]) / (time.monotonic() - started[1])
        finally:
            driver.close()
    numbers = report(run, q_franky, config)
    numbers["franky_sim_real_time_factor"] = rate
    return run, q_franky, numbers


def main(argv: Sequence[str]) -> int:
    """Run `hamnet bridge gap`; prints the table, then the numbers as one JSON line."""
    config = parse(GapConfig, argv, "hamnet bridge gap", __doc__)
    run, q_franky, numbers = measure(config)
    print(table(numbers))
    if config.out is not None:
        config.out.mkdir(parents=True, exist_ok=True)
        (config.out / "bridge-gap.json").write_text(json.dumps(numbers, indent=1) + "\n")
        plot(run, q_franky, config.policy_period_s, config.out / "bridge-gap.png")
    print(json.dumps(numbers))
    return 0
