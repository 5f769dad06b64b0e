"""Which rclpy executor the nodes of an in-process run share (`islands explore --executor`).

Importing this module does not import rclpy (the CLI parses its arguments without ROS).
"""

from __future__ import annotations

import io
import sys
from enum import StrEnum
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rclpy.context import Context
    from rclpy.executors import Executor


class ExecutorKind(StrEnum):
    """The executor every node of a run shares."""

    EVENTS = "events"  # rclpy.experimental.EventsExecutor: callbacks dispatched in C++
    SINGLE_THREADED = "single_threaded"  # rclpy.executors.SingleThreadedExecutor


def make_executor(kind: ExecutorKind, ctx: Context) -> Executor:
    """An executor of `kind` on `ctx`; the single-threaded one where this rclpy has no events
    executor."""
    from rclpy.executors import SingleThreadedExecutor

    if kind is ExecutorKind.EVENTS:
        try:
            from rclpy.experimental import EventsExecutor
        except ImportError:
            return SingleThreadedExecutor(context=ctx)
        # It enables faulthandler on sys.stderr, which must have a file descriptor: not so
        # where stderr is captured (pytest, a notebook); the process's own stderr has one.
        captured = sys.stderr
        try:
            sys.stderr = sys.__stderr__ or captured
            return EventsExecutor(context=ctx)
        except (io.UnsupportedOperation, AttributeError, ValueError):
            return SingleThreadedExecutor(context=ctx)
        finally:
            sys.stderr = captured
    return SingleThreadedExecutor(context=ctx)
