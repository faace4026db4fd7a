"""Ports: what a shell reads and writes, by local names.

A shell declares its ports ("state" is `sim/<w>/state`, "action" is `policy/<w>/action`)
and asks its service for their keys; it never builds a key itself. By default a port is its
topic's key in the service's namespace, for its own worker. `--remap PORT=KEY` (in a stack
file: the service's `remap` map) rewires a port to another key of the same topic, so a stack
can rewire services without code changes: the policy reading the states a replay publishes
in another namespace, a safety filter guarding worker 1's commands. KEY is a whole key
(`hamnet/replay/sim/0/state`) or a path in the service's namespace (`sim/1/state`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from hamnet.runtime import contract, keys
from hamnet.runtime.errors import ConfigError


@dataclass(frozen=True)
class Ports:
    """A shell's inputs and outputs: local name -> contract path (`sim/<w>/state`)."""

    inputs: Mapping[str, str]
    outputs: Mapping[str, str]

    def __post_init__(self) -> None:
        both = set(self.inputs) & set(self.outputs)
        if both:
            raise ValueError(f"ports {sorted(both)} are declared as inputs and outputs")
        for path in (*self.inputs.values(), *self.outputs.values()):
            contract.topic(path)  # KeyError for a path outside the contract

    def topic(self, port: str) -> contract.Topic:
        """The contract topic of `port`."""
        path = self.inputs.get(port) or self.outputs.get(port)
        if path is None:
            raise ConfigError(f"no port {port!r}; the ports are {', '.join(self.names)}")
        return contract.topic(path)

    @property
    def names(self) -> list[str]:
        return [*self.inputs, *self.outputs]

    def describe(self) -> str:
        """The ports as `--help` lists them."""
        lines = [f"  {name:<12} in   {path}" for name, path in self.inputs.items()]
        lines += [f"  {name:<12} out  {path}" for name, path in self.outputs.items()]
        return "ports (rewire one with --remap PORT=KEY):\n" + "\n".join(lines)

    def remapped(self, remap: Sequence[str], namespace: str) -> dict[str, str]:
        """`PORT=KEY` entries as port -> whole key; ConfigError for an unknown port, a
        malformed entry, or a key of another topic than the port's."""
        out: dict[str, str] = {}
        for entry in remap:
            port, sep, key = entry.partition("=")
            if not sep or not port or not key:
                raise ConfigError(f"--remap takes PORT=KEY, got {entry!r}")
            topic = self.topic(port)
            whole = key if key.startswith(f"{keys.ROOT}/") else f"{keys.ROOT}/{namespace}/{key}"
            if not topic.matches(whole):
                raise ConfigError(
                    f"--remap {entry}: port {port!r} carries {topic.template}, "
                    f"and {whole} is not one of its keys"
                )
            out[port] = whole
        return out

    def keys(self, namespace: str, remap: Sequence[str] = (), **fields: str) -> dict[str, str]:
        """Every port's key: its topic's key in `namespace` with `fields` (e.g. w="0"), or
        its remapped key."""
        wired = self.remapped(remap, namespace)
        out = {}
        for port in self.names:
            topic = self.topic(port)
            own = {name: fields[name] for name in topic.placeholders}
            out[port] = wired.get(port) or topic.key(namespace, **own)
        return out
