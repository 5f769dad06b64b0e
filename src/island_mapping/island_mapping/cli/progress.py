"""Progress display for long `islands` commands: a `progress(done, total)` callback over tqdm."""

from __future__ import annotations

import sys
from typing import NoReturn, TextIO

from tqdm import tqdm

# Redraw at most this often on a terminal [s].
TTY_INTERVAL_S = 0.2
# Elsewhere (a log file, CI) tqdm cannot redraw in place: a new status this often [s].
LOG_INTERVAL_S = 10.0


class ProgressBar:
    """A `progress(done, total)` callback that shows a tqdm bar on `stream` (stderr by default):
    `label:  40%|####      | 40/100 [00:02<00:03, 19.8it/s]`. The bar closes (and ends its
    line) when `done` reaches `total`; a later call with another total starts a new bar."""

    def __init__(self, label: str, stream: TextIO | None = None) -> None:
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        isatty = getattr(self.stream, "isatty", None)
        self._interval_s = TTY_INTERVAL_S if isatty is not None and isatty() else LOG_INTERVAL_S
        self._bar: tqdm[NoReturn] | None = None  # a bar without an iterable
        self._finished_total: int | None = None  # the total of the bar that last completed

    def __call__(self, done: int, total: int) -> None:
        if self._bar is None and done >= total and total == self._finished_total:
            return  # that bar is complete and shown already
        bar = self._bar
        if bar is None or bar.total != total:
            self.close()
            self._finished_total = None
            bar = self._bar = tqdm(total=total, desc=self.label, file=self.stream, leave=True,
                                   mininterval=self._interval_s, dynamic_ncols=True)
        bar.update(done - bar.n)
        if done >= total:
            self.close()
            self._finished_total = total

    def close(self) -> None:
        """End the current bar (its last state stays on the stream)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None
