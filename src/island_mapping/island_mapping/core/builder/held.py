"""A held decision (managed mode): a star that fits more than one known island is not decided
on the spot.

The Recognizer refuses a star's recognition when another island fits the points as well (a
look-alike, `Recognizer.hypotheses`). Deciding there builds a duplicate when the best fit was
the right place, and a false merge when it was not. With `BuilderHooks.hold_hypotheses` the
builder keeps the star (`Held`), tells the explorer which islands it may be at (the
`revisit_hypothesis` event, each hypothesis passing the loop-closure gate on its own), and
waits: the explorer gathers more evidence (it drives one of the island's edges and localizes
at its neighbour: Kuipers' rehearsal) and answers `confirm(island)` (the robot was at that
island: a loop closed, no new island) or `reject()` (the star's place is new: the builder
builds it as it would have).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

from island_msgs_py.types import FloatArray, Island, Pose2D

from island_mapping.core.builder.config import BuilderError
from island_mapping.core.builder.events import Hypothesis
from island_mapping.core.builder.recognition import Recognition
from island_mapping.core.builder.star import Attempt


@dataclass(frozen=True)
class HeldChoice:
    """One hypothesis: `rec`, the robot's pose in the island's frame when the decision was
    held, and `end`, the star's anchor in that frame (where the edge's record ended)."""

    rec: Recognition
    end: Pose2D


@dataclass
class Held:
    """The star whose decision waits for the explorer, with what the decision needs as it was
    when it was held: the odometric pose and covariance, epsilon [m] and the heading sigma
    since the last island [rad], and the time [s]."""

    attempt: Attempt
    choices: tuple[HeldChoice, ...]
    odom: Pose2D
    cov: FloatArray
    epsilon_m: float
    heading_sigma_rad: float
    t_s: float

    def choice(self, island_id: int) -> HeldChoice:
        """The hypothesis of island island_id; BuilderError when it is none of them."""
        for c in self.choices:
            if c.rec.island_id == island_id:
                return c
        raise BuilderError(f"confirm: island {island_id} is not a hypothesis of the held star "
                           f"(they are {[c.rec.island_id for c in self.choices]})")

    def now(self, choice: HeldChoice, odom_now: Pose2D) -> Recognition:
        """The hypothesis with the robot's pose in the island's frame now, by the odometry
        driven since the decision was held (the robot has moved to gather evidence)."""
        return replace(choice.rec, pose=choice.rec.pose.compose(odom_now.relative_to(self.odom)))

    def event_hypotheses(self) -> tuple[Hypothesis, ...]:
        return tuple(Hypothesis(c.rec.island_id, c.rec.pose, c.rec.inlier_fraction)
                     for c in self.choices)


def held_choices(hypotheses: Sequence[Recognition], islands: Mapping[int, Island],
                 anchor_in_robot: Pose2D, admits: Callable[[Recognition, Island, Pose2D], bool],
                 limit: int) -> tuple[HeldChoice, ...]:
    """The hypotheses (best first) that `admits` (the loop-closure gate, shown the anchor in
    the island frame) keeps, at most `limit`; anchor_in_robot: the star's anchor in the
    robot's frame."""
    out: list[HeldChoice] = []
    for h in hypotheses:
        island = islands.get(h.island_id)
        if island is None or any(c.rec.island_id == h.island_id for c in out):
            continue
        end = h.pose.compose(anchor_in_robot)
        if admits(h, island, end):
            out.append(HeldChoice(h, end))
        if len(out) >= limit:
            break
    return tuple(out)
