"""The base of every bad-input error in the project (standard library only).

Each package keeps its own error types (`WorldError`, `GraphFormatError`, `BagError`,
`ConversionError`, ...); each derives from `InputError`, so whoever meets one can tell bad input
from a bug without knowing every package: the `islands` tool prints it as one line and exits 2,
a node counts the message as bad and skips it. The message names the file, topic or argument,
the field and the limit that was broken.
"""

from __future__ import annotations


class InputError(ValueError):
    """Input (a file, a message, a request, a command-line value) that breaks its format or a
    documented limit; the message says where, which field and which limit."""
