"""Scan times read from a log, checked before anything is built on them (pure: numpy only).

Times are parsed at the precision the file gives (`float` of the text); what a file lost cannot
be recovered, so a log whose scans share timestamps (times printed with `%g`: `1.13486e+09`
puts hundreds of scans on a handful of times) is refused, naming the log and the lines. Small
steps back in time (timestamp jitter: 4 of the Intel log's 910 scans go back, by up to 1 s) are
counted; a larger one (a restarted clock, concatenated logs) is refused.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from island_mapping.logs.errors import LogFormatError

MAX_BACKWARD_S = 5.0
"""A scan time more than this before an earlier scan's is an error, not jitter [s]."""


class LogTimeError(LogFormatError):
    """Scan times that cannot be used (duplicate, collapsed, going far back); the message names
    the log and the lines."""


@dataclass(frozen=True)
class TimeReport:
    """What the scan times look like: steps back (jitter) and the largest of them [s]."""

    scans: int
    backwards: int
    max_backward_s: float

    def as_dict(self) -> dict[str, float | int]:
        return {"scans": self.scans, "backwards": self.backwards,
                "max_backward_s": round(self.max_backward_s, 6)}


def check_scan_times(times_s: npt.ArrayLike, source: str,
                     where: npt.ArrayLike | None = None) -> TimeReport:
    """Refuse duplicate or collapsed scan times and large steps back; count small ones.

    `where`: (S,) line numbers (or message indices) of the scans, for the error message."""
    t = np.asarray(times_s, dtype=np.float64).reshape(-1)
    loc = (np.arange(1, t.size + 1) if where is None
           else np.asarray(where, dtype=np.int64).reshape(-1))
    if not np.all(np.isfinite(t)):
        k = int(np.flatnonzero(~np.isfinite(t))[0])
        raise LogTimeError(f"{source}:{loc[k]}: scan time is not finite")
    if t.size < 2:
        return TimeReport(int(t.size), 0, 0.0)
    distinct = np.unique(t).size
    if distinct < t.size:
        _, first = np.unique(t, return_index=True)
        dup = np.setdiff1d(np.arange(t.size), first)
        k = int(dup[0])
        raise LogTimeError(
            f"{source}: {t.size - distinct} of {t.size} scans share a timestamp with another "
            f"({distinct} distinct times; first at line {loc[k]}, t = {t[k]!r}): the log's times "
            f"have too few digits (printed with %g?); export it with full-precision times")
    run_max = np.maximum.accumulate(t)
    back = run_max - t
    if float(back.max()) > MAX_BACKWARD_S:
        k = int(np.argmax(back))
        raise LogTimeError(
            f"{source}:{loc[k]}: scan time {t[k]!r} s is {back[k]:.3f} s before an earlier "
            f"scan's (more than {MAX_BACKWARD_S:g} s: a restarted clock or joined logs?)")
    return TimeReport(int(t.size), int(np.sum(back > 0)), float(back.max()))
