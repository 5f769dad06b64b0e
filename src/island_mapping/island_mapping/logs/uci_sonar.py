"""The UCI wall-following robot's sonar readings (`sensor_readings_24.data`): an optional header
line, then 24 ranges [m] and the motion label per line."""

from __future__ import annotations

import math
import os
from collections.abc import Iterable

import numpy as np

from island_mapping.core.sonar_ring import RING_SENSORS, SonarReadings
from island_mapping.logs.errors import LogFormatError


def parse_sonar_ring(
    lines: Iterable[str], source: str = "<sonar>", limit: int | None = None
) -> SonarReadings:
    """Parse the UCI `sensor_readings_24.data` text: an optional header line (`S1,...,OUTPUT`),
    then `r1,...,r24,Label` per line. At most `limit` readings are read. Raises LogFormatError
    naming the line number on a malformed line."""
    ranges: list[list[float]] = []
    labels: list[str] = []
    for lineno, line in enumerate(lines, start=1):
        if limit is not None and len(ranges) >= limit:
            break
        text = line.strip()
        if not text:
            continue
        parts = [p.strip() for p in text.split(",")]
        if lineno == 1 and parts[0].upper() == "S1":
            continue  # the header
        if len(parts) != RING_SENSORS + 1:
            raise LogFormatError(
                f"{source}:{lineno}: expected {RING_SENSORS} ranges and a label, "
                f"got {len(parts)} fields"
            )
        try:
            vals = [float(p) for p in parts[:RING_SENSORS]]
        except ValueError as exc:
            raise LogFormatError(f"{source}:{lineno}: not a range ({exc})") from None
        if not all(math.isfinite(v) and v >= 0 for v in vals):
            raise LogFormatError(f"{source}:{lineno}: a range is negative, NaN or infinite")
        if not parts[-1] or parts[-1][0].isdigit():
            raise LogFormatError(f"{source}:{lineno}: missing motion label")
        ranges.append(vals)
        labels.append(parts[-1])
    return SonarReadings(np.asarray(ranges, dtype=np.float64).reshape(-1, RING_SENSORS),
                         tuple(labels))


def read_sonar_ring(path: str | os.PathLike[str], limit: int | None = None) -> SonarReadings:
    """Read a UCI sonar-ring file (see `parse_sonar_ring`)."""
    try:
        with open(path, encoding="utf-8") as f:
            return parse_sonar_ring(f, str(path), limit)
    except OSError as exc:
        raise LogFormatError(f"{path}: cannot read sonar readings ({exc.strerror})") from None
