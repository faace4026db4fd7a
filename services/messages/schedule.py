"""Schedule (trainer -> sim, safety, policy): the trainer's env_transitions counter, which
the sim's curricula and the safety filter's annealing of xi and eps_x follow.
"""

from __future__ import annotations

from hamnet.proto.common_pb2 import Header
from hamnet.proto.trainer_pb2 import Schedule


def decode(message: Schedule) -> int:
    """The trainer's env_transitions counter."""
    return int(message.env_transitions)


def encode(env_transitions: int, iteration: int) -> Schedule:
    """Schedule after `iteration` updates: the counter only."""
    return Schedule(header=Header(step=iteration), env_transitions=int(env_transitions))
