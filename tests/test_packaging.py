"""Packaging: the folders map onto one `hamnet` namespace and nothing is left out."""

from __future__ import annotations

import tomllib
from pathlib import Path

import hamnet
import hamnet.proto

ROOT = Path(__file__).resolve().parents[1]


def declared_packages() -> set[str]:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    return set(config["tool"]["setuptools"]["packages"])


def test_every_service_folder_is_a_declared_subpackage() -> None:
    """A new folder under services/ that pyproject.toml does not list would be missing from
    a non-editable install (wheel, Docker image); this catches it."""
    on_disk = {"hamnet", "hamnet.proto"} | {
        "hamnet." + ".".join(path.parent.relative_to(ROOT / "services").parts)
        for path in (ROOT / "services").glob("*/**/__init__.py")
    }
    assert declared_packages() == on_disk


def test_folders_are_imported_under_the_hamnet_namespace() -> None:
    assert Path(hamnet.__file__).parent == ROOT / "services"
    assert Path(hamnet.proto.__file__).parent == ROOT / "proto"
