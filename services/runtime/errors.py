"""The one error a command raises for a value it cannot run with, and how `hamnet` shows it.

A flag out of range, an endpoint that is not a locator, a missing Zenoh config file, a
session Zenoh refuses to open: each is a `ConfigError`, which the command line's entry
prints as one line (`hamnet sim: num_envs must be >= 1, got 0`) with exit status 2.
"""

from __future__ import annotations


class ConfigError(Exception):
    """A value given to a command (flag, stack-file entry, config file) it cannot run with.

    Not a ValueError on purpose: tyro catches ValueErrors raised while it builds a nested
    config and draws them in a multi-line box; this one reaches `parse` and `hamnet` as is.
    """
