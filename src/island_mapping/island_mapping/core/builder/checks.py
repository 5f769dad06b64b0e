"""Localization checks and registrations of scan points onto an island's line model.

- `localizes_back`: the new-island check (do the points seen at an origin come back to it from
  offset, and for a probe also turned, guesses?); recognitions must pass it too.
- `leg_heading`: the turn that registers a star leg's echoes onto the earlier legs' model.
- `register_look`: where a look-around's points fit in a model, from the odometric guess.
"""

from __future__ import annotations

import math

from island_msgs_py.types import FloatArray, LineModel, Pose2D, wrap_angle

from island_mapping.core.builder.config import BuilderConfig
from island_mapping.core.localize import localize

REGISTER_GATE_SIGMAS = 3.0
"""A leg's registered turn is kept within this many sigmas of its innovation (odometry's heading
variance plus register_sigma_deg's): 99.7 % of right fits pass, a wrong wall's 90 deg does not."""


def localizes_back(
    cfg: BuilderConfig, model: LineModel, points_robot: FloatArray, at: Pose2D,
    turn_rad: float = 0.0,
) -> bool:
    """The localization check: from `at` and from guesses `verify_offset_m` off it in four
    directions, do the robot-frame points converge within `verify_tol_m` of `at`? With
    turn_rad > 0 the guesses are also turned by +-turn_rad, and the fits' headings must
    agree within probe_agree_deg (a model that fits turned as well passes the position
    test alone)."""
    d = cfg.verify_offset_m
    turns = (0.0, turn_rad, -turn_rad) if turn_rad > 0.0 else (0.0,)
    headings: list[float] = []
    for dth in turns:
        for gx, gy in ((0.0, 0.0), (d, 0.0), (-d, 0.0), (0.0, d), (0.0, -d)):
            guess = Pose2D(at.x + gx, at.y + gy, at.theta + dth)
            res = localize(model, points_robot, guess, cfg.localize)
            if not res.converged or math.hypot(res.pose.x - at.x, res.pose.y - at.y) > (
                cfg.verify_tol_m
            ):
                return False
            headings.append(wrap_angle(res.pose.theta - at.theta))
    spread = max(headings) - min(headings)
    return turn_rad <= 0.0 or spread <= math.radians(cfg.probe_agree_deg)


def leg_heading(
    cfg: BuilderConfig, model: LineModel, points: FloatArray, gate_rad: float
) -> float | None:
    """The turn [rad] that registers a leg's `points` (anchor frame, placed by odometry)
    onto the earlier legs' `model`: the fit's heading from the identity when its steps
    settled with enough points matched and the turn is within `gate_rad` (the innovation
    gate); else None. Only the heading is used, so a fit that slid along a hallway (its
    position free along it: degenerate, not converged) still counts; one constrained in
    both axes must stay within verify_offset_m (farther is a wrong match)."""
    res = localize(model, points, Pose2D(0.0, 0.0, 0.0), cfg.localize)
    turned = wrap_angle(res.pose.theta)
    degenerate = res.constraint < cfg.localize.min_constraint
    if not res.settled or res.matched_fraction < cfg.localize.min_matched_fraction or (
        abs(turned) > gate_rad
    ) or (not degenerate and math.hypot(res.pose.x, res.pose.y) > cfg.verify_offset_m):
        return None
    return turned


def register_look(
    cfg: BuilderConfig, model: LineModel, points_robot: FloatArray, guess: Pose2D
) -> Pose2D:
    """The robot's pose in `model`'s frame: `points_robot` localized from the odometric
    `guess`. After a star and a drive, odometry has turned a few degrees (each full circle
    adds heading noise), and those degrees would turn the walls the points add to the
    island's model. The guess itself when the fit does not converge or moves more than
    verify_offset_m / probe_turn_deg."""
    res = localize(model, points_robot, guess, cfg.localize)
    moved = math.hypot(res.pose.x - guess.x, res.pose.y - guess.y)
    turned = abs(wrap_angle(res.pose.theta - guess.theta))
    if not res.converged or moved > cfg.verify_offset_m or turned > math.radians(
        cfg.probe_turn_deg
    ):
        return guess
    return res.pose
