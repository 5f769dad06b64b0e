"""What the explorer says and asks (`core.explore.mission`): its state and status, the
command per scan, and its requests to the builder (docked, handover, abort, and the answers
to a held decision: confirm, reject) and to the map (blocked exits, side exits)."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from island_msgs_py.types import ControlStrategy, ExitUpdate, NewExit, Pose2D


class ExplorerState(StrEnum):
    WAITING = "waiting"  # for the builder's first island
    CHOOSING = "choosing"  # at an island: the next exit (waits for the map to hold the island)
    NAVIGATING = "navigating"  # by the map to the island of the chosen exit
    DEPARTING = "departing"  # turning to the exit, through its gate
    HANDED_OVER = "handed_over"  # the builder and the hall follower drive
    RETURNING = "returning"  # back to the island left (the exit took too long)
    LOST = "lost"  # an arrival did not localize: the builder takes over from the last island
    REHEARSING = "rehearsing"  # testing where a held star may be, by a known island's edge
    DONE = "done"


@dataclass(frozen=True)
class Docked:
    """Tell the builder: the robot is docked at island_id's origin, at origin_odom."""

    island_id: int
    origin_odom: Pose2D


@dataclass(frozen=True)
class Handover:
    """Tell the builder: explore from island_id by exit exit_index, having driven prefix."""

    island_id: int
    exit_index: int | None
    prefix: ControlStrategy


@dataclass(frozen=True)
class Abort:
    """Ask the builder to stop following (the explorer takes the robot back)."""


@dataclass(frozen=True)
class Confirm:
    """Tell the builder: its held star was at island_id (the rehearsal found its neighbour)."""

    island_id: int


@dataclass(frozen=True)
class Reject:
    """Tell the builder: its held star was at none of its hypotheses (build its island)."""


Request = Docked | Handover | Abort | Confirm | Reject | ExitUpdate | NewExit


@dataclass(frozen=True)
class ExplorerCommand:
    """Who answers this scan: the explorer (drive=True, with v [m/s], w [rad/s]) or the builder
    side; and the requests for the builder and the map made during this step."""

    drive: bool
    v_mps: float = 0.0
    w_radps: float = 0.0
    requests: tuple[Request, ...] = ()


@dataclass(frozen=True)
class ExplorerStatus:
    """What the explorer is doing (for `/explorer/status`)."""

    state: ExplorerState
    island_id: int | None
    target: tuple[int, int] | None
    exits_left: int
    done: bool
    reason: str

    def to_dict(self) -> dict[str, object]:
        return {"state": self.state.value, "island": self.island_id,
                "target": None if self.target is None else list(self.target),
                "exits_left": self.exits_left, "done": self.done, "reason": self.reason}
