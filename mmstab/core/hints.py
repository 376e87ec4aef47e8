"""What the loaders add to a refusal: the closest valid key, the unit of an angle.

:func:`mmstab.core.files.validate` names a misspelt key with the valid key closest to it
(:func:`did_you_mean`, difflib) and refuses an angle that looks like degrees
(:func:`degrees_given`) before the schema's bounds, whose message then says ``[rad]``.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Sequence
from typing import Any

#: A value above this in magnitude, where the unit is radians, is taken as degrees [rad].
DEGREES_LIKELY = 2 * math.pi + 1e-6


def did_you_mean(key: str, known: Sequence[str]) -> str:
    """``"; did you mean 'X'?"`` for the valid key closest to ``key`` (difflib), else ``""``.

    Args:
        key: the key the file has.
        known: the valid keys at that place.
    """
    close = difflib.get_close_matches(key, [str(k) for k in known], n=1, cutoff=0.6)
    return f"; did you mean '{close[0]}'?" if close else ""


def unknown_keys(err: Any) -> list[str]:
    """The keys of a jsonschema error's mapping that its closed schema does not list (sorted)."""
    schema = err.schema if isinstance(err.schema, dict) else {}
    if not isinstance(err.instance, dict) or schema.get("additionalProperties") is not False:
        return []
    return sorted(str(k) for k in set(err.instance) - set(schema.get("properties", {})))


def unit_hint(schema: Any) -> str:
    """`` [rad]`` after a bound's message on an angle (the schema's ``unit``), else ``""``."""
    unit = schema.get("unit") if isinstance(schema, dict) else None
    return f" [{unit}]" if unit else ""


def degrees_given(node: Any, schema: Any, trail: list[Any]) -> tuple[list[Any], str] | None:
    """The first number of ``|value| > 2 pi`` where radians are expected, and why, or None.

    Walks ``node`` along ``schema`` (``properties``, ``items``, every ``oneOf`` / ``anyOf``
    branch); the angles are the schemas marked ``"unit": "rad"``
    (:data:`mmstab.core.schema.RAD`).

    Returns:
        (the field's path as keys and indices, the message naming the unit), or None.
    """
    if not isinstance(schema, dict):
        return None
    number = isinstance(node, (int, float)) and not isinstance(node, bool)
    if schema.get("unit") == "rad" and number and abs(node) > DEGREES_LIKELY:
        msg = (
            f"{node} looks like degrees; the unit is radians "
            f"({node} deg = {math.radians(node):.4g} rad)"
        )
        return trail, msg
    found = [
        degrees_given(node, b, trail) for b in schema.get("oneOf", []) + schema.get("anyOf", [])
    ]
    if isinstance(node, dict):
        props = schema.get("properties", {})
        found += [degrees_given(node[k], sub, [*trail, k]) for k, sub in props.items() if k in node]
    elif isinstance(node, list) and isinstance(schema.get("items"), dict):
        found += [degrees_given(v, schema["items"], [*trail, i]) for i, v in enumerate(node)]
    return next((f for f in found if f is not None), None)
