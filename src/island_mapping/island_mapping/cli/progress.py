"""A one-line progress bar for long `islands` commands (no dependency)."""

from __future__ import annotations

import math
import sys
import time
from typing import Any


class ProgressBar:
    """A one-line text progress bar on a stream (no dependency): `label [####....] 40/100`."""

    def __init__(self, label: str, stream: Any = None, width: int = 30,
                 min_interval_s: float = 0.2) -> None:
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.width = width
        self.min_interval_s = min_interval_s
        self._last = -math.inf
        self._last_tenth = -1
        isatty = getattr(self.stream, "isatty", None)
        self._tty = bool(isatty and isatty())

    def __call__(self, done: int, total: int) -> None:
        now = time.monotonic()
        frac = done / total if total else 1.0
        if not self._tty:  # a log file: one line per tenth, no carriage returns
            tenth = min(10, int(frac * 10))
            if tenth > self._last_tenth:
                self._last_tenth = tenth
                self.stream.write(f"{self.label}: {tenth * 10}% ({done}/{total})\n")
                self.stream.flush()
            return
        if done < total and now - self._last < self.min_interval_s:
            return
        self._last = now
        filled = round(frac * self.width)
        bar = "#" * filled + "." * (self.width - filled)
        end = "\n" if done >= total else ""
        self.stream.write(f"\r{self.label} [{bar}] {done}/{total}{end}")
        self.stream.flush()
