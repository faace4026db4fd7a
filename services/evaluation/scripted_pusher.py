"""The scripted pusher (`hamnet.trainer.collection.scripted_pusher`) on the held-out episodes
a policy is evaluated on: the easy stage's reference (`scripts/scripted_push.py`,
docs/results/scripted-push.json)."""

from __future__ import annotations

import dataclasses

from hamnet.sim.env import StepResult
from hamnet.trainer.collection.scripted_pusher import PusherConfig, ScriptedPusher
from hamnet.trainer.results.evaluate import HeldOut, held_out_worker, play_held_out
from hamnet.trainer.runners.run_config import RunConfig

NO_CLOUDS = "state-mlp"
"""The pusher reads no clouds: its held-out worker is built as this architecture's (no
perception), on the same environments as every other policy's."""


def scripted_held_out(
    config: RunConfig, episodes: int, pusher: PusherConfig | None = None, env_transitions: int = 0
) -> HeldOut:
    """The pusher on the held-out episodes a policy of `config`'s run is evaluated on
    (`hamnet.trainer.results.evaluate`), one per environment, acting in the run's action
    space through the training profile's filter at the schedule counter `env_transitions`."""
    worker = held_out_worker(dataclasses.replace(config, architecture=NO_CLOUDS), episodes)
    script = ScriptedPusher(worker.env, worker.safety.config.action_magnitude, pusher)

    def step() -> StepResult:
        action = script.actions(worker.observation, env_transitions)
        result = worker.env.step(worker.command(action, env_transitions))
        worker.start(result.reset_ids, result.observation)
        return result

    return play_held_out(worker.observation, step)
