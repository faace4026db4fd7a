"""Schedule (trainer -> sim, safety): the trainer's env_transitions counter, which the
sim's curricula and the safety filter's annealing of xi and eps_x follow.
"""

from __future__ import annotations

from hamnet.proto.trainer_pb2 import Schedule


def decode(message: Schedule) -> int:
    """The trainer's env_transitions counter."""
    return int(message.env_transitions)
