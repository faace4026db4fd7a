"""Layers that point one way: each package of `hamnet` imports only itself and packages of
lower layers, so nothing depends on what is built on top of it.

What this catches: a camera that imported perception for its frame type, a runtime that
imported security for a file layout, a pretrainer that imported the trainer for two helpers,
a bridge that imported a safety test double. Each would pass every other test while tying a
lower service to a higher one; here the import itself fails the suite, with its file and line.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

SERVICES = Path(__file__).resolve().parents[1] / "services"

LAYERS: dict[str, int] = {
    "proto": 0,
    "fr3": 0,
    "task": 0,
    "runtime": 1,
    "cli": 2,
    "messages": 2,
    "security": 2,
    "sim": 3,
    "safety": 3,
    "camera": 4,
    "perception": 5,
    "policy": 6,
    "trainer": 7,
    "pretrain": 7,
    "bridge": 7,
    "monitor": 7,
    "recorder": 7,
    "launcher": 8,
    "evaluation": 8,
    "tools": 8,
}
"""The layer of every package of `hamnet` (`proto` lives in proto/, `cli` is services/cli.py,
the `hamnet` command's registry, which imports only the runtime). A package may import itself
and packages of strictly lower layers, at module level or inside a function; packages of one
layer never import each other. `hamnet` itself (its `__init__` holds the version) and
`__main__` stand outside the layers. A new package gets its layer here before its first
import counts."""


def package_of(path: Path) -> str | None:
    """The package a file under services/ belongs to; None for the root's own files."""
    parts = path.relative_to(SERVICES).parts
    if len(parts) == 1:
        return None if parts[0] in ("__init__.py", "__main__.py") else Path(parts[0]).stem
    return parts[0]


def imported_packages(path: Path) -> Iterator[tuple[int, str, str]]:
    """(line, module as written, hamnet package) of every import of a hamnet package in the
    file, function-level ones included; imports of the bare root (`from hamnet import
    __version__`) are left out."""
    here = ["hamnet", *path.relative_to(SERVICES).parts[:-1]]
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            modules = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: resolved against the file's own package
                anchor = here[: len(here) - node.level + 1]
                base = ".".join(anchor + ([node.module] if node.module else []))
            # `from hamnet import sim` imports a package; `from hamnet import __version__` does not
            modules = [f"{base}.{a.name}" for a in node.names] if base == "hamnet" else [base]
        else:
            continue
        for module in modules:
            parts = module.split(".")
            if parts[0] == "hamnet" and len(parts) > 1 and not parts[1].startswith("__"):
                yield node.lineno, module, parts[1]


def test_every_package_has_a_layer() -> None:
    """A package added under services/ (or one removed) without a place in LAYERS fails here,
    so its imports are never left unchecked."""
    on_disk = {package_of(path) for path in SERVICES.glob("*/__init__.py")}
    modules = {package_of(path) for path in SERVICES.glob("*.py")} - {None}
    assert on_disk | modules | {"proto"} == set(LAYERS)


def test_imports_point_down() -> None:
    """Every import of a hamnet package by another one reaches a lower layer."""
    violations = []
    for path in sorted(SERVICES.rglob("*.py")):
        source = package_of(path)
        if source is None:
            continue
        for line, module, target in imported_packages(path):
            if target == source:
                continue
            where = f"{path.relative_to(SERVICES.parent)}:{line}: {module}"
            if target not in LAYERS:
                violations.append(f"{where} (package {target!r} has no layer)")
            elif LAYERS[target] >= LAYERS[source]:
                violations.append(
                    f"{where} ({source}, layer {LAYERS[source]}, imports {target}, "
                    f"layer {LAYERS[target]})"
                )
    assert not violations, "imports against the layers:\n" + "\n".join(violations)
