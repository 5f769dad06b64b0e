"""What the island builder tells its driver: commands (follow, or drive with a twist) and
events (attempt started, failed at once, island accepted, dismissed, revisited, handed back),
and the JSON form of an event."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from island_msgs_py.types import Edge, ExitUpdate, Island, Pose2D

from island_msgs_py import json_io


class CommandMode(StrEnum):
    FOLLOW = "follow"  # the hall follower drives
    DRIVE = "drive"  # the builder drives: publish (v, w)
    IDLE = "idle"  # managed mode, waiting: another controller (the explorer) drives


class DismissReason(StrEnum):
    MEASURE = "measure"  # max_i(R_i/T_i) did not reach the eq. 3 bound
    LOCALIZATION_CHECK = "localization_check"  # the origin's own data did not localize


class EventKind(StrEnum):
    ATTEMPT_STARTED = "attempt_started"
    ATTEMPT_FAILED_AT_ONCE = "attempt_failed_at_once"
    ISLAND_ACCEPTED = "island_accepted"
    ATTEMPT_DISMISSED = "attempt_dismissed"
    HANDED_BACK = "handed_back"  # the robot is back at the origin facing theta 0
    ISLAND_REVISITED = "island_revisited"  # a known island recognised: no new island
    HANDED_OVER = "handed_over"  # managed mode: the explorer handed the robot over
    STOPPED = "stopped"  # managed mode: following stopped at the explorer's request
    # managed mode: a star fitted more than one known island (or one, and a look-alike
    # elsewhere); the builder holds its decision until the explorer confirms one or rejects all
    REVISIT_HYPOTHESIS = "revisit_hypothesis"


@dataclass(frozen=True)
class Hypothesis:
    """A known island the robot may be at: island_id, the robot's pose in its frame [m, rad]
    by the star's fit, and the fit's inlier fraction [-]."""

    island_id: int
    pose: Pose2D
    inlier_fraction: float


@dataclass(frozen=True)
class BuilderEvent:
    """Something the builder decided.

    anchor_odom: the attempt pose in the odometry frame; legs_m: the legs driven so far as
    (bearing in the origin frame [rad], length [m]); measure: the best normalized measure
    max_i(R_i/T_i) so far; bound: E_min/epsilon at the attempt; partial: a dismissed star that
    did not do all four legs. island_revisited: revisited_island_id, island_pose (the robot in
    that island's frame when recognised [m, rad]; at island_pose_t_s [s] when that was before
    the event: a held star confirmed after a rehearsal), residual_m (RMS of the fit [m]) and,
    when it was added or made cheaper, the edge from the previous island. exit_updates: exits the
    event's edge explored (managed mode), to apply after the island and the edge.
    revisit_hypothesis: `hypotheses`, the known islands the star fitted (best first).
    """

    kind: EventKind
    t_s: float
    odom_pose: Pose2D
    epsilon_m: float
    anchor_odom: Pose2D | None = None
    measure: float = 0.0
    bound: float = 0.0
    legs_m: tuple[tuple[float, float], ...] = ()
    partial: bool = False
    island: Island | None = None
    edge: Edge | None = None
    accepted_island_id: int | None = None
    reason: DismissReason | None = None
    revisited_island_id: int | None = None
    island_pose: Pose2D | None = None
    island_pose_t_s: float | None = None
    residual_m: float | None = None
    exit_updates: tuple[ExitUpdate, ...] = ()
    hypotheses: tuple[Hypothesis, ...] = ()


@dataclass(frozen=True)
class BuilderCommand:
    """What to do now: FOLLOW, or DRIVE with v [m/s] and w [rad/s]; events since the last call."""

    mode: CommandMode
    v_mps: float = 0.0
    w_radps: float = 0.0
    events: tuple[BuilderEvent, ...] = ()


def event_to_dict(e: BuilderEvent) -> dict[str, object]:
    """The JSON form of a builder event (poses as {x, y, theta}, m and rad)."""
    d: dict[str, object] = {
        "kind": e.kind.value,
        "t_s": e.t_s,
        "odom_pose": json_io.pose_to_dict(e.odom_pose),
        "epsilon_m": e.epsilon_m,
        "measure": e.measure,
        "bound": e.bound,
        "legs_m": [list(leg) for leg in e.legs_m],
        "partial": e.partial,
        "anchor_odom": json_io.pose_to_dict(e.anchor_odom) if e.anchor_odom else None,
    }
    if e.island is not None:
        d["island"] = json_io.island_to_dict(e.island)
    if e.edge is not None:
        d["edge"] = json_io.edge_to_dict(e.edge)
    if e.accepted_island_id is not None:
        d["accepted_island_id"] = e.accepted_island_id
    if e.reason is not None:
        d["reason"] = e.reason.value
    if e.revisited_island_id is not None:
        d["revisited_island_id"] = e.revisited_island_id
    if e.island_pose is not None:
        d["island_pose"] = json_io.pose_to_dict(e.island_pose)
    if e.island_pose_t_s is not None:
        d["island_pose_t_s"] = e.island_pose_t_s
    if e.residual_m is not None:
        d["residual_m"] = e.residual_m
    if e.exit_updates:
        d["exit_updates"] = [json_io.exit_update_to_dict(u) for u in e.exit_updates]
    if e.hypotheses:
        d["hypotheses"] = [{"island": h.island_id, "pose": json_io.pose_to_dict(h.pose),
                            "inlier_fraction": h.inlier_fraction} for h in e.hypotheses]
    return d
