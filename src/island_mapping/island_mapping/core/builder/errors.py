"""The island builder's errors and the number checks its configurations share."""

from __future__ import annotations

import math

from island_msgs_py.errors import InputError


class BuilderError(InputError):
    """Bad input to the island builder (the message names the argument and the problem)."""


def check_numbers(owner: str, obj: object, names: tuple[str, ...], strict: bool) -> None:
    """Each named field of `obj` must be a finite number > 0 (strict) or >= 0."""
    for name in names:
        v = getattr(obj, name)
        ok = isinstance(v, int | float) and math.isfinite(v) and (v > 0 if strict else v >= 0)
        if not ok:
            bound = "> 0" if strict else ">= 0"
            raise BuilderError(f"{owner}.{name}: expected a finite number {bound}, got {v!r}")
