"""Recipes: the canonical JSON of every parameter that produced an asset.

The SHA-256 of the canonical JSON is the asset's cache key (``recipe_hash``).
Canonical means: keys sorted, no whitespace, UTF-8, tuples as lists, NumPy
scalars and arrays as plain numbers and lists, and no NaN or Infinity (JSON has
none, and a recipe holding one is a bug upstream).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Mapping

import numpy as np

from ..errors import ValidationError


def _plain(value, where: str):
    if isinstance(value, Mapping):
        out = {}
        for key, item in value.items():
            if not isinstance(key, str):
                raise ValidationError(f"{where}", key, "recipe keys must be strings")
            out[key] = _plain(item, f"{where}.{key}" if where else key)
        return out
    if isinstance(value, (list, tuple)):
        return [_plain(item, f"{where}[{i}]") for i, item in enumerate(value)]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist(), where)
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        if not math.isfinite(value):
            raise ValidationError(where or "recipe", value, "recipe values must be finite")
        return value
    if value is None or isinstance(value, str):
        return value
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    raise ValidationError(where or "recipe", value, f"cannot store a {type(value).__name__} in a recipe")


def canonical_json(recipe: Mapping) -> str:
    """The canonical JSON text of ``recipe`` (a mapping of plain values)."""
    if not isinstance(recipe, Mapping):
        raise ValidationError("recipe", recipe, "a recipe is a mapping of parameter names to values")
    return json.dumps(_plain(recipe, ""), sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


def recipe_hash(recipe: Mapping | str) -> str:
    """SHA-256 (hex) of the canonical JSON of ``recipe`` (or of an already canonical string)."""
    text = recipe if isinstance(recipe, str) else canonical_json(recipe)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()
