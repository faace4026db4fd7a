"""Parsed YAML -> frozen config dataclasses, with errors that name the offending key.

The dataclasses of `hamnet.launcher.stack` are the schema of a stack file: their fields are
the allowed keys, their type hints the allowed values and their docstrings the
documentation. `build` walks a parsed YAML document against them, so that a typo or a
wrong type fails with its path, e.g.
`services.sim.restart.max_restart: unknown key (did you mean 'max_restarts'?)`.
"""

from __future__ import annotations

import dataclasses
import difflib
import types
import typing
from collections.abc import Mapping
from typing import Any, TypeVar

T = TypeVar("T")


class SchemaError(ValueError):
    """A document that does not fit the schema; the message starts with the key's path."""


def join(where: str, key: object) -> str:
    """Path of `key` inside `where`: `services.sim`."""
    return f"{where}.{key}" if where else str(key)


def build(cls: type[T], data: object, where: str = "") -> T:
    """Build the dataclass `cls` from a mapping, converting and checking every value.

    Raises:
        SchemaError: unknown or missing key, wrong type, or a value its `__post_init__`
            rejects; the message names the key's path.
    """
    if not isinstance(data, Mapping):
        raise SchemaError(_at(where, f"expected a mapping, got {describe(data)}"))
    hints = typing.get_type_hints(cls)
    known = [f.name for f in dataclasses.fields(cls) if f.init]  # type: ignore[arg-type]
    values = {}
    for key, value in data.items():
        if key not in known:
            close = difflib.get_close_matches(str(key), known, n=1)
            hint = f"did you mean {close[0]!r}?" if close else f"expected one of {', '.join(known)}"
            raise SchemaError(f"{join(where, key)}: unknown key ({hint})")
        values[key] = convert(hints[key], value, join(where, key))
    for f in dataclasses.fields(cls):  # type: ignore[arg-type]
        required = f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
        if f.init and required and f.name not in values:
            raise SchemaError(f"{join(where, f.name)}: missing key")
    try:
        return cls(**values)
    except ValueError as error:
        raise SchemaError(_at(where, str(error))) from None


def _at(where: str, message: str) -> str:
    return f"{where}: {message}" if where else message


def convert(hint: Any, value: object, where: str) -> Any:
    """`value` checked against the type hint `hint` (and converted: list -> tuple, int -> float)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        return _convert_union(args, value, where)
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise SchemaError(f"{where}: expected a list, got {describe(value)}")
        return tuple(convert(args[0], item, f"{where}[{i}]") for i, item in enumerate(value))
    if origin is Mapping:
        if not isinstance(value, Mapping):
            raise SchemaError(f"{where}: expected a mapping, got {describe(value)}")
        for key in value:
            if not isinstance(key, str):
                raise SchemaError(f"{join(where, key)}: keys must be strings, got {describe(key)}")
        return {key: convert(args[1], item, join(where, key)) for key, item in value.items()}
    if dataclasses.is_dataclass(hint):
        return build(hint, value, where)
    return _convert_scalar(hint, value, where)


def _convert_union(args: tuple[Any, ...], value: object, where: str) -> Any:
    if value is None:
        if type(None) in args:
            return None
        raise SchemaError(f"{where}: expected {_name(args)}, got null")
    if type(value) in args:  # exact match first: 4 stays an int in `str | int | float`
        return value
    for arg in args:
        if dataclasses.is_dataclass(arg) and isinstance(value, Mapping):
            return build(arg, value, where)  # its own errors name the key inside it
    for arg in args:
        if arg is type(None):
            continue
        try:
            return convert(arg, value, where)
        except SchemaError:
            continue
    raise SchemaError(f"{where}: expected {_name(args)}, got {describe(value)}")


def _convert_scalar(hint: Any, value: object, where: str) -> Any:
    is_number = isinstance(value, int | float) and not isinstance(value, bool)
    if hint is bool and isinstance(value, bool):
        return value
    if hint is int and is_number and float(value).is_integer():  # type: ignore[arg-type]
        return int(value)  # type: ignore[call-overload]
    if hint is float and is_number:
        return float(value)  # type: ignore[arg-type]
    if hint is str and (isinstance(value, str) or (is_number and isinstance(value, int))):
        return str(value)  # YAML reads `worker: 0` as a number
    raise SchemaError(f"{where}: expected {_name((hint,))}, got {describe(value)}")


_NAMES = {str: "a string", int: "an integer", float: "a number", bool: "true or false",
          type(None): "null"}


def _name(hints: tuple[Any, ...]) -> str:
    names = []
    for hint in hints:
        origin = typing.get_origin(hint)
        if origin is tuple:
            names.append("a list")
        elif origin is Mapping or dataclasses.is_dataclass(hint):
            names.append("a mapping")
        else:
            names.append(_NAMES.get(hint, getattr(hint, "__name__", str(hint))))
    return " or ".join(dict.fromkeys(names))


def describe(value: object) -> str:
    """How a YAML value reads in an error message: `a list`, `the string 'x'`."""
    if isinstance(value, Mapping):
        return "a mapping"
    if isinstance(value, list | tuple):
        return "a list"
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, str):
        return f"the string {value!r}"
    return f"the number {value!r}"
