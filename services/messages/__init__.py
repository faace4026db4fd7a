"""The contract's messages decoded into batched numpy dataclasses, one module per message
kind: each holds the decoded dataclass, its single `decode` (every tensor checked, a bad
payload raises `PayloadError` with the reason the inbox counts it under) and, where a
service produces the message, its `encode`. Shells and cores share these instead of
decoding the same message their own way.
"""
