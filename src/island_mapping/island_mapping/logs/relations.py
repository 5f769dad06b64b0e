"""Relation files of Kuemmerle et al. 2009 (`t1 t2 x y z roll pitch yaw` per line): the pose at
t2 in the frame of the pose at t1, in absolute UNIX time [s]; planar parts only are kept."""

from __future__ import annotations

import math
import os
from collections.abc import Iterable

import numpy as np

from island_mapping.core.relations import Relations
from island_mapping.logs.errors import LogFormatError


def parse_relations(lines: Iterable[str], source: str = "<relations>") -> Relations:
    """Parse `t1 t2 x y z roll pitch yaw` lines (blank lines and `#` comments skipped).

    Raises LogFormatError naming `source` and the 1-based line number on a malformed line.
    """
    t1: list[float] = []
    t2: list[float] = []
    rel: list[tuple[float, float, float]] = []
    for lineno, line in enumerate(lines, start=1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        parts = text.split()
        if len(parts) != 8:
            raise LogFormatError(
                f"{source}:{lineno}: expected 8 fields (t1 t2 x y z roll pitch yaw), "
                f"got {len(parts)}"
            )
        try:
            vals = [float(p) for p in parts]
        except ValueError as exc:
            raise LogFormatError(f"{source}:{lineno}: not a number ({exc})") from None
        if not all(math.isfinite(v) for v in vals):
            raise LogFormatError(f"{source}:{lineno}: NaN or infinite value")
        t1.append(vals[0])
        t2.append(vals[1])
        rel.append((vals[2], vals[3], vals[7]))
    return Relations(
        np.asarray(t1, dtype=np.float64),
        np.asarray(t2, dtype=np.float64),
        np.asarray(rel, dtype=np.float64).reshape(-1, 3),
    )


def read_relations(path: str | os.PathLike[str]) -> Relations:
    """Read a Kuemmerle relations file (see `parse_relations`)."""
    try:
        with open(path, encoding="utf-8") as f:
            return parse_relations(f, str(path))
    except OSError as exc:
        raise LogFormatError(f"{path}: cannot read relations file ({exc.strerror})") from None
