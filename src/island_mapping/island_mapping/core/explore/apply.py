"""The explorer's requests as the builder takes them: one dispatch for the builder node and
the offline harness (`evaluation.explore_exits`), so a live run and a log or benchmark run
treat every request alike."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from island_mapping.core.builder import BuilderError, IslandBuilder
from island_mapping.core.explore.requests import Abort, Confirm, Docked, Handover, Reject, Request


class FollowerAction(Enum):
    """What the hall follower must do once the builder took a request."""

    KEEP = "keep"  # as it is
    STOP = "stop"  # the explorer takes the robot back
    RESTART = "restart"  # the edge's record starts at the handover


@dataclass(frozen=True)
class Applied:
    """What a builder request did: a message for the caller's log or reply, and the
    follower's action."""

    message: str
    follower: FollowerAction = FollowerAction.KEEP


def apply_to_builder(builder: IslandBuilder, r: Request) -> Applied:
    """Give the builder one request of the explorer. BuilderError when it cannot take it (an
    unknown island or exit, no decision held, busy) or `r` is a map request; the builder's
    state is then unchanged."""
    if isinstance(r, Reject):
        builder.reject()
        return Applied("held star rejected: its island is built")
    if isinstance(r, Docked):
        builder.on_docked(r.island_id, r.origin_odom)
        return Applied(f"docked at island {r.island_id}")
    if isinstance(r, Confirm):
        builder.confirm(r.island_id)
        return Applied(f"held star confirmed at island {r.island_id}")
    if isinstance(r, Abort):
        if not builder.abort():
            why = ("it is not in managed mode" if not builder.hooks.managed
                   else f"it is busy ({builder.state}); ask again")
            raise BuilderError(f"abort: the builder cannot give the robot back: {why}")
        return Applied("following stopped", FollowerAction.STOP)
    if isinstance(r, Handover):
        builder.handover(r.island_id, r.exit_index, r.prefix)
        return Applied(f"handed over at island {r.island_id} by exit {r.exit_index}",
                       FollowerAction.RESTART)
    raise BuilderError(f"{type(r).__name__} is a request for the map, not the builder")


__all__ = ["Applied", "FollowerAction", "apply_to_builder"]
