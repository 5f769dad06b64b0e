"""The log readers' exception (no heavy imports)."""

from __future__ import annotations

from island_msgs_py.errors import InputError


class LogFormatError(InputError):
    """A log file could not be read or parsed; the message names the file, the line number and
    the problem."""
