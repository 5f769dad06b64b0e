"""Exceptions of the recording package (no rclpy import)."""

from __future__ import annotations

from island_msgs_py.errors import InputError


class BagError(InputError):
    """A recording could not be written or read (bad path, unknown type, bad data)."""


class MessageTypeError(BagError):
    """A message type name is malformed, or its definition/class is not installed."""


class BagCorruptError(BagError):
    """An MCAP file is truncated or corrupted.

    `path` is the file, `offset` the byte offset of the first record that could not be read,
    `intact_messages` how many complete messages precede it (readable, recoverable).
    """

    def __init__(self, path: str, offset: int, reason: str, intact_messages: int) -> None:
        self.path = path
        self.offset = offset
        self.reason = reason
        self.intact_messages = intact_messages
        super().__init__(
            f"{path}: {reason} at byte offset {offset}; the {intact_messages} complete messages "
            f"before it are readable (`islands bag recover {path}` writes them to a clean bag)"
        )


class CarmenFormatError(BagError):
    """A CARMEN log line could not be parsed (the message names the file and line number)."""
