"""Regenerate the committed protobuf Python modules from the `.proto` files of this folder.

The generated `*_pb2.py`/`*_pb2.pyi` files are committed so that installing needs no protoc;
`tests/proto/test_generated_code.py` fails when they are stale. Run after editing a schema:

    python -m hamnet.proto.generate

Needs `grpcio-tools` (a dev dependency), which bundles protoc.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

PROTO_DIR = Path(__file__).resolve().parent
"""The folder holding the schemas and the generated modules (installed as `hamnet.proto`)."""


def generate() -> dict[str, str]:
    """Compile every schema and return the generated files' text by file name.

    The schemas are compiled as `hamnet/proto/<name>.proto` so that the generated imports
    read `from hamnet.proto import common_pb2`.
    """
    from grpc_tools import protoc  # dev dependency: imported only when generating

    include = Path(protoc.__file__).parent / "_proto"
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp, "src", "hamnet", "proto")
        out = Path(tmp, "out")
        src.mkdir(parents=True)
        out.mkdir()
        schemas = sorted(PROTO_DIR.glob("*.proto"))
        for schema in schemas:
            shutil.copy(schema, src / schema.name)
        args = [
            "protoc",
            f"-I{Path(tmp, 'src')}",
            f"-I{include}",
            f"--python_out={out}",
            f"--pyi_out={out}",
            *(f"hamnet/proto/{schema.name}" for schema in schemas),
        ]
        if protoc.main(args) != 0:
            raise RuntimeError(f"protoc failed on {[s.name for s in schemas]}")
        generated = Path(out, "hamnet", "proto")
        return {path.name: path.read_text() for path in sorted(generated.iterdir())}


def main() -> None:
    """Write the generated modules next to the schemas."""
    for name, text in generate().items():
        (PROTO_DIR / name).write_text(text)
        print(f"wrote {PROTO_DIR / name}")


if __name__ == "__main__":
    main()
