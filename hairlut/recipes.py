"""Recipe files (TOML) and their validation against a schema of defaults.

A schema is a nested dict whose leaves are :class:`Field` s.  ``resolve`` merges
a user mapping over the defaults and raises :class:`hairlut.errors.ValidationError`
naming the key path (``bands.light_specular``) for an unknown key, a wrong type
or a value out of range.
"""

from __future__ import annotations

import os
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from . import errors
from .files import regular_file


@dataclass(frozen=True)
class Field:
    default: object
    types: tuple[type, ...]
    check: Callable[[object], str | None] | None = None  # returns a reason when the value is bad
    doc: str = ""


def resolve(schema: Mapping, given: Mapping | None, where: str = "") -> dict:
    """Defaults of ``schema`` overridden by ``given``; every key path validated."""
    given = dict(given or {})
    out = {}
    for key in given:
        if key not in schema:
            raise errors.ValidationError(f"{where}{key}", given[key], f"unknown key; known: {', '.join(schema)}")
    for key, spec in schema.items():
        path = f"{where}{key}"
        if isinstance(spec, Mapping):
            sub = given.get(key, {})
            if not isinstance(sub, Mapping):
                raise errors.ValidationError(path, sub, "expected a table of keys")
            out[key] = resolve(spec, sub, path + ".")
            continue
        value = given.get(key, spec.default)
        if isinstance(value, bool) and bool not in spec.types:
            raise errors.ValidationError(path, value, f"expected {' or '.join(t.__name__ for t in spec.types)}")
        if not isinstance(value, spec.types):
            raise errors.ValidationError(path, value, f"expected {' or '.join(t.__name__ for t in spec.types)}")
        if isinstance(value, int) and not isinstance(value, bool) and float in spec.types and int not in spec.types:
            value = float(value)
        if spec.check is not None and (reason := spec.check(value)):
            raise errors.ValidationError(path, value, reason)
        out[key] = value
    return out


def load_toml(path: str | os.PathLike) -> dict:
    """Parse a TOML recipe file, with hairlut errors for a missing or malformed file."""
    path = regular_file(path, "a TOML file", missing="no such recipe file")
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise errors.FormatError(path, f"not valid TOML ({exc})") from None


def get_path(mapping: Mapping, dotted: str):
    """The value at ``a.b.c`` of a nested mapping, or None where the path does not exist."""
    node = mapping
    for key in dotted.split("."):
        if not isinstance(node, Mapping) or key not in node:
            return None
        node = node[key]
    return node


def set_path(mapping: dict, dotted: str, value) -> None:
    """Set ``a.b.c`` in a nested dict (for command-line overrides)."""
    keys = dotted.split(".")
    node = mapping
    for key in keys[:-1]:
        node = node.setdefault(key, {})
        if not isinstance(node, dict):
            raise errors.ValidationError(dotted, value, f"{key} is not a table")
    node[keys[-1]] = value


def apply_overrides(recipe: dict, pairs) -> dict:
    """Apply ``KEY=VALUE`` overrides (``a.b.c=3``; the value is a TOML literal, else a bare string)."""
    for pair in pairs:
        key, sep, text = str(pair).partition("=")
        if not sep or not key.strip():
            raise errors.ValidationError("set", pair, "expected KEY=VALUE, e.g. kernel.p=100")
        try:
            value = tomllib.loads(f"v = {text}")["v"]
        except tomllib.TOMLDecodeError:
            value = text  # a bare word such as auto
        set_path(recipe, key.strip(), value)
    return recipe
