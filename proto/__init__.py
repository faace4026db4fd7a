"""The message contract: protobuf schemas (`*.proto`) and their generated Python modules.

Regenerate after editing a schema with `python -m hamnet.proto.generate`.
"""
