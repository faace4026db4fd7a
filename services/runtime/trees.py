"""Trees of tensors: the policy inputs of a batch are dataclasses (and dicts) whose leaves
are (N, ...) tensors or None. The trainer selects, concatenates and interleaves their rows
leaf by leaf with one walker; the policy service's chunk assembler does the same."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

from torch import Tensor


def zip_trees(trees: list[Any], join: Callable[[list[Tensor]], Tensor]) -> Any:
    """One tree from trees of the same structure, each leaf the `join` of theirs there.

    Leaves are tensors or None (None stays None); inner nodes are dicts, tuples and
    dataclasses.
    """
    first = trees[0]
    if first is None:
        return None
    if isinstance(first, Tensor):
        return join(trees)
    if isinstance(first, dict):
        return {key: zip_trees([tree[key] for tree in trees], join) for key in first}
    if isinstance(first, tuple):
        return tuple(zip_trees([tree[i] for tree in trees], join) for i in range(len(first)))
    if dataclasses.is_dataclass(first):
        changes = {
            f.name: zip_trees([getattr(tree, f.name) for tree in trees], join)
            for f in dataclasses.fields(first)
        }
        return dataclasses.replace(first, **changes)
    raise TypeError(f"cannot walk a {type(first).__name__}")


def take_rows(tree: Any, rows: Tensor) -> Any:
    """The rows `rows` (K,) of every tensor in a tree."""
    return zip_trees([tree], lambda leaves: leaves[0][rows])
