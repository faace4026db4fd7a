"""The committed `*_pb2.py` files must be what the committed schemas generate."""

from __future__ import annotations

import pytest

from hamnet.proto.generate import PROTO_DIR, generate


def test_generated_modules_match_the_schemas() -> None:
    """A schema edited without `python -m hamnet.proto.generate` leaves stale modules: the
    regenerated text differs from the committed file and this fails."""
    pytest.importorskip("grpc_tools")
    generated = generate()
    assert generated, "protoc produced nothing"
    stale = [name for name, text in generated.items() if (PROTO_DIR / name).read_text() != text]
    assert not stale, f"stale generated code, run `python -m hamnet.proto.generate`: {stale}"
    committed = {p.name for p in PROTO_DIR.glob("*_pb2.py*")}
    assert committed == set(generated), f"orphan or missing modules: {committed ^ set(generated)}"
