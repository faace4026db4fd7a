"""Resumable snapshots of a run at an iteration boundary: arrays in one safetensors file,
everything else in one JSON file, next to the policy's checkpoint. No pickle anywhere.

Layout under `<run_dir>/checkpoints/`:
- `latest.safetensors`: the policy's weights with its input statistics
  (`hamnet.policy.weights`), loadable by `hamnet policy --checkpoint`;
- `state.safetensors`: every other array, keyed `<part>.<name>`: Adam's moments, the reward
  scaler, the episode tracker, torch's global RNG and, in-process, each rollout worker's sim,
  perception caches, safety filter, carry, observation, percepts and generators;
- `state.json`: counters, learning rate, numpy generator states, the parts' other metadata,
  and the run's identity (architecture, sim config, steps per rollout) a resume must match.

Each part gives `snapshot() -> (arrays, meta)` and takes `restore(arrays, meta)`; `nest` and
`part` put parts together under prefixes. Arrays come back as numpy arrays; torch parts copy
them into torch-allocated tensors (`torch.tensor`), since float results can depend on where
an operand lies in memory.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from pathlib import Path
from typing import Any, Protocol, TypeVar, runtime_checkable

import numpy as np
import torch
from safetensors.numpy import load_file, save_file
from torch import Tensor

Arrays = dict[str, np.ndarray]
"""Arrays of a restored snapshot, by name."""
Snapshot = tuple[dict[str, "np.ndarray | Tensor"], dict[str, Any]]
"""(arrays or tensors by name, JSON-serialisable metadata) of one part."""

STATE_ARRAYS = "state.safetensors"
STATE_META = "state.json"
T = TypeVar("T")


class ResumeError(ValueError):
    """A snapshot that cannot continue this run: missing, incomplete or made for another run."""


@runtime_checkable
class Resumable(Protocol):
    """A part whose whole state a snapshot holds."""

    def snapshot(self) -> Snapshot:
        """(arrays, meta) that `restore` takes back."""

    def restore(self, arrays: Arrays, meta: dict[str, Any]) -> None:
        """Continue exactly where `snapshot` was taken (on a part built from the same config)."""


def nest(parts: dict[str, Snapshot]) -> Snapshot:
    """One snapshot of named parts: arrays under `<name>.`, metadata under `<name>`."""
    arrays = {
        f"{name}.{key}": value for name, (held, _) in parts.items() for key, value in held.items()
    }
    return arrays, {name: meta for name, (_, meta) in parts.items()}


def part(arrays: Arrays, meta: dict[str, Any], name: str) -> tuple[Arrays, Any]:
    """The arrays and metadata `nest` put under `name`."""
    prefix = f"{name}."
    return {
        key[len(prefix) :]: value for key, value in arrays.items() if key.startswith(prefix)
    }, meta[name]


def fields_of(value: object) -> dict[str, np.ndarray | Tensor]:
    """The array or tensor fields of a dataclass, by name (None fields left out)."""
    return {
        f.name: getattr(value, f.name)
        for f in dataclasses.fields(value)
        if getattr(value, f.name) is not None
    }


def tensor_dataclass(cls: type[T], arrays: Arrays) -> T:
    """A dataclass of tensors from `fields_of`'s arrays (torch-allocated copies; None where absent)."""
    return cls(
        **{
            f.name: torch.tensor(arrays[f.name]) if f.name in arrays else None
            for f in dataclasses.fields(cls)
        }
    )


def array_dataclass(cls: type[T], arrays: Arrays) -> T:
    """A dataclass of numpy arrays from `fields_of`'s arrays (copies)."""
    return cls(**{f.name: np.array(arrays[f.name]) for f in dataclasses.fields(cls)})


def generator_state(generator: torch.Generator) -> np.ndarray:
    """A torch generator's state, (N,) uint8."""
    return generator.get_state().numpy()


def set_generator_state(generator: torch.Generator, state: np.ndarray) -> None:
    """Put back what `generator_state` gave."""
    generator.set_state(torch.tensor(state))


def optimizer_snapshot(optimizer: torch.optim.Optimizer) -> Snapshot:
    """Adam's (or any torch optimizer's) per-parameter tensors and its param groups (lr)."""
    state = optimizer.state_dict()
    arrays = {
        f"{index}.{name}": value
        for index, held in state["state"].items()
        for name, value in held.items()
    }
    return arrays, {"param_groups": state["param_groups"]}


def restore_optimizer(
    optimizer: torch.optim.Optimizer, arrays: Arrays, meta: dict[str, Any]
) -> None:
    """Put back what `optimizer_snapshot` gave."""
    state: dict[int, dict[str, Tensor]] = {}
    for key, value in arrays.items():
        index, name = key.split(".", 1)
        state.setdefault(int(index), {})[name] = torch.tensor(value)
    groups = [
        {**group, "betas": tuple(group["betas"])} if "betas" in group else group
        for group in meta["param_groups"]
    ]
    optimizer.load_state_dict({"state": state, "param_groups": groups})


def _tensors_to_numpy(arrays: dict[str, np.ndarray | Tensor]) -> Arrays:
    """Independent contiguous numpy copies (safetensors refuses shared memory)."""
    as_numpy = lambda v: v.detach().cpu().numpy() if isinstance(v, Tensor) else v
    return {key: np.array(as_numpy(value), order="C") for key, value in arrays.items()}


def write(directory: Path, snapshot: Snapshot) -> None:
    """Write `snapshot` into `directory` (each file replaced whole, never half-written)."""
    arrays, meta = snapshot
    directory.mkdir(parents=True, exist_ok=True)
    partial = directory / f"{STATE_ARRAYS}.partial"
    save_file(_tensors_to_numpy(arrays), str(partial))
    os.replace(partial, directory / STATE_ARRAYS)
    partial = directory / f"{STATE_META}.partial"
    partial.write_text(json.dumps(meta, indent=1))
    os.replace(partial, directory / STATE_META)


def read(directory: Path) -> tuple[Arrays, dict[str, Any]]:
    """The snapshot `write` left in `directory` (ResumeError when there is none)."""
    paths = directory / STATE_ARRAYS, directory / STATE_META
    missing = [path.name for path in paths if not path.is_file()]
    if missing:
        raise ResumeError(f"no snapshot to resume in {directory} (missing {', '.join(missing)})")
    return load_file(str(paths[0])), json.loads(paths[1].read_text())


def as_json(value: object) -> Any:
    """`value` (dataclasses at any depth, tuples, paths) as it reads back from JSON."""
    plain = lambda v: dataclasses.asdict(v) if dataclasses.is_dataclass(v) else str(v)
    return json.loads(json.dumps(value, default=plain))


def _leaves(value: Any, path: str) -> dict[str, Any]:
    """Nested dicts flattened to `a.b.c` keys."""
    if not isinstance(value, dict):
        return {path: value}
    return {
        key: leaf
        for name, inner in value.items()
        for key, leaf in _leaves(inner, f"{path}.{name}").items()
    }


def check_identity(saved: dict[str, Any], current: dict[str, Any], directory: Path) -> None:
    """ResumeError naming every setting where the snapshot's run differs from this one."""
    before, now = _leaves(saved, "run"), _leaves(as_json(current), "run")
    differ = [key for key in sorted(before.keys() | now.keys()) if before.get(key) != now.get(key)]
    if differ:
        shown = "; ".join(
            f"{key[4:]}: {before.get(key)!r} there, {now.get(key)!r} here" for key in differ[:4]
        )
        more = f" (and {len(differ) - 4} more)" if len(differ) > 4 else ""
        raise ResumeError(
            f"cannot resume {directory}: its run differs from this command line: {shown}{more}"
        )


def trim_metrics(path: Path, iteration: int) -> None:
    """Drop the rows of iterations after `iteration` (written after the snapshot, before a
    crash) and a row cut short, so the resumed run's rows follow on."""
    if not path.is_file():
        return
    lines = path.read_text().splitlines(keepends=True)
    kept = [line for line in lines if line.endswith("\n") and _iteration(line) <= iteration]
    if len(kept) != len(lines):
        path.write_text("".join(kept))


def _iteration(line: str) -> float:
    """The iteration of a metrics row; infinite for a row that does not parse."""
    try:
        return json.loads(line)["iteration"]
    except (json.JSONDecodeError, KeyError, TypeError):
        return math.inf


def read_run(run_dir: Path, identity: dict[str, object]) -> Snapshot:
    """The snapshot in `run_dir/checkpoints`, once it is known to be of the run `identity`
    (`RunConfig.identity`; ResumeError otherwise)."""
    arrays, meta = read(run_dir / "checkpoints")
    check_identity(meta["run"], identity, run_dir)
    return arrays, meta
