"""What the builder counts for diagnostics: events by kind, why recognitions were refused,
how probes of origins past a star's legs ended, and drives that stalled. Nothing here feeds a
decision."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum

from island_mapping.core.builder.events import EventKind


class Refusal(StrEnum):
    """Why a revisit hypothesis (or a whole recognition) was refused."""

    NOT_CONVERGED = "not_converged"
    RESIDUAL = "residual"
    WEAK_CONSTRAINT = "weak_constraint"  # slides along a hallway: aliases along it
    OUTSIDE_SEARCH_RADIUS = "outside_search_radius"
    OUTSIDE_HEADING_WINDOW = "outside_heading_window"
    INLIERS = "inliers"
    AMBIGUOUS = "ambiguous"  # the model fits at distinct places
    ORIGIN_TOO_FAR = "origin_too_far"
    PATH_BLOCKED = "path_blocked"
    LOCALIZATION_CHECK = "localization_check"
    DRIFT_TOO_LARGE = "drift_too_large"  # the search could not cover where the island may be
    LOOK_ALIKE = "look_alike"  # another island that may be here fits as well
    NOT_AT_PLACE = "not_at_place"  # the loop-closure gate: seen from the next place
    OUTSIDE_UNCERTAINTY = "outside_uncertainty"  # the gate: beyond the propagated covariance
    TURNED_ALIAS = "turned_alias"  # the island fits as well turned by a quarter/half turn
    FAR_LOOK_ALIKE = "far_look_alike"  # a clipped window: an island anywhere fits as well
    TOPOLOGY = "topology"  # the explorer's gate: no exit of the island faces the arrival


class ProbeOutcome(StrEnum):
    """How the check of an origin past the star's legs ended."""

    KEPT = "kept"
    FELL_BACK = "fell_back"


@dataclass
class Diagnostics:
    """counts: events by kind; revisit_refusals: refusal reason -> count; probes: probe
    outcome -> count (keys are plain strings, as written to summary.json)."""

    counts: dict[EventKind, int] = field(default_factory=lambda: {k: 0 for k in EventKind})
    revisit_refusals: dict[str, int] = field(default_factory=dict)
    probes: dict[str, int] = field(
        default_factory=lambda: {o.value: 0 for o in ProbeOutcome}
    )
    drive_stalls: int = 0  # drives onto a point that ended where the robot pushed at a wall

    def refuse(self, reason: Refusal) -> None:
        """Count one refusal."""
        key = reason.value
        self.revisit_refusals[key] = self.revisit_refusals.get(key, 0) + 1

    def probed(self, outcome: ProbeOutcome) -> None:
        """Count one probe's outcome."""
        self.probes[outcome.value] += 1
