"""Arriving at an island: look around, localize in its model, search if unsure, dock on its origin.

`localize_multi` is pure; `localize_and_dock` is a motion generator (see `route.motion`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator
from dataclasses import dataclass, replace

import numpy as np
from island_msgs_py.geometry import closest_on_segments, from_frame
from island_msgs_py.types import FloatArray, Island, Pose2D, wrap_angle

from island_mapping.core.lines import thin_evenly
from island_mapping.core.localize import LocalizationResult, LocalizeConfig, localize
from island_mapping.core.route.config import NavigateConfig
from island_mapping.core.route.motion import Command, Drive, go_to, look_around

# Guesses whose trusted fits lie within this of the nearest one agree with it [m].
_AGREE_M = 0.1


@dataclass(frozen=True)
class Fix:
    """The localization an arrival is judged by: the robot's pose in the island frame, whether
    it is trusted, and the fit it came from."""

    island_id: int
    pose: Pose2D
    trusted: bool
    result: LocalizationResult
    # Where the island's origin lies in the odometry frame after docking, by the last
    # trusted look (None: not trusted, or not known).
    origin_odom: Pose2D | None = None


FixHook = Callable[[Fix], None]
"""Called the moment an arrival's localization is known (evaluation reads the truth then)."""


def localize_multi(
    island: Island, points_robot: FloatArray, estimate: Pose2D, cfg: NavigateConfig,
    max_shift_m: float = math.inf,
) -> tuple[LocalizationResult, bool]:
    """Localize from initial guesses around `estimate`; (best result, trusted).

    The best result is the converged one with the smallest residual (any result when none
    converged); trusted = it converged with a residual below `max_residual_m`. A fit whose
    heading left the estimate's by more than `max_turn_deg`, whose position left it by more
    than `max_shift_m` [m], or that constrains the position less than `min_fit_constraint`,
    counts as not converged.
    """
    r = cfg.search_radius_m
    n = math.floor(r / cfg.search_step_m + 1e-9)
    offs = np.arange(-n, n + 1) * cfg.search_step_m
    dths = (0.0, math.radians(cfg.search_heading_deg), -math.radians(cfg.search_heading_deg))
    guesses = sorted(
        ((dx, dy, dth) for dx in offs for dy in offs for dth in dths),
        key=lambda g: math.hypot(g[0], g[1]) + abs(g[2]),
    )
    points_robot = thin_evenly(points_robot, cfg.max_points)  # evenly: the look-around is redundant
    best: LocalizationResult | None = None
    good: list[Pose2D] = []
    for dx, dy, dth in guesses:
        init = Pose2D(estimate.x + dx, estimate.y + dy, wrap_angle(estimate.theta + dth))
        res = localize(island.model, points_robot, init, cfg.localize)
        turned = abs(wrap_angle(res.pose.theta - estimate.theta)) > math.radians(cfg.max_turn_deg)
        shifted = math.hypot(res.pose.x - estimate.x, res.pose.y - estimate.y) > max_shift_m
        if (turned or shifted or res.constraint < cfg.min_fit_constraint) and res.converged:
            res = replace(res, converged=False)
        if best is None or (res.converged, -res.residual_m) > (best.converged, -best.residual_m):
            best = res
        if res.converged and res.residual_m <= cfg.max_residual_m:
            good.append(res.pose)
            # Guesses go outward from the estimate: stop once the nearest good fits agree.
            agree = [p for p in good if math.hypot(p.x - good[0].x, p.y - good[0].y) <= _AGREE_M]
            if len(agree) >= cfg.min_agreeing:
                break
    assert best is not None
    return best, bool(best.converged and best.residual_m <= cfg.max_residual_m)


# Turns of a fit tried for an alias: a quarter either way and a half [rad].
_ALIAS_TURNS_RAD = (0.5 * math.pi, math.pi, -0.5 * math.pi)


def turned_alias(island: Island, points_robot: FloatArray, fit: LocalizationResult,
                 cfg: NavigateConfig) -> bool:
    """Does the island fit the points as well from the fit's position turned by a quarter or
    half turn (converged, the residual within max_residual_m, the matched share within
    alias_margin of the fit's)?"""
    pts = thin_evenly(points_robot, cfg.max_points)
    for turn in _ALIAS_TURNS_RAD:
        init = Pose2D(fit.pose.x, fit.pose.y, wrap_angle(fit.pose.theta + turn))
        alt = localize(island.model, pts, init, cfg.localize)
        near = abs(wrap_angle(alt.pose.theta - init.theta)) <= math.radians(cfg.max_turn_deg)
        if (alt.converged and near and alt.residual_m <= cfg.max_residual_m
                and alt.matched_fraction >= fit.matched_fraction - cfg.alias_margin):
            return True
    return False


def unconstrained_axis_rad(island: Island, points_robot: FloatArray, pose: Pose2D,
                           cfg: LocalizeConfig) -> float:
    """Direction in the island frame along which a fit at `pose` is least constrained [rad].

    The eigenvector of the smallest eigenvalue of sum n n^T over the matched points (n the unit
    direction from a point to its nearest model segment): in a hallway, the hallway's axis.
    """
    pts = from_frame(points_robot, pose)
    _, foot, dist = closest_on_segments(pts, island.model.segments)
    ok = (dist <= cfg.max_match_dist_m) & (dist > 1e-6)
    if not np.any(ok):
        return pose.theta
    n = (foot[ok] - pts[ok]) / dist[ok, None]
    _, vecs = np.linalg.eigh(n.T @ n)
    return math.atan2(float(vecs[1, 0]), float(vecs[0, 0]))


def localize_and_dock(
    d: Drive, island: Island, estimate: Pose2D, on_fix: FixHook | None = None,
    max_shift_m: float = math.inf,
) -> Generator[Command, None, Fix]:
    """Localize in the island from the estimate (the robot's pose in its frame), dock at its
    origin, and return the arrival's fix.

    The fix is the FIRST localization, or when that is not trusted the one the search along
    the hallway ended with (the one that says whether the robot found the island); `on_fix`
    sees it before docking starts. Docking (drive onto the origin, look again) does not change
    it; it stops when a look is not trusted. A finite `max_shift_m` [m] says the estimate is
    known that well (odometry since the island, not a route's end): a fit farther from it is
    not trusted, and there is no search along the hallway (it would find the far basin)."""
    c = d.cfg
    pts = yield from look_around(d)
    at = d.sense.odom  # where the look's points are in the robot's frame
    res, trusted = localize_multi(island, pts, estimate, c, max_shift_m)
    searchable = math.isinf(max_shift_m) and c.axis_search_step_m > 0 and c.axis_search_steps > 0
    searched = not trusted and searchable
    if searched:
        # Search from the fit nearest the estimate: the smallest residual may be a wrong
        # heading basin.
        if pts.shape[0] >= c.sparse_look_points:
            near = localize(island.model, thin_evenly(pts, c.max_points), estimate, c.localize)
            res, trusted = yield from search_along_axis(d, island, pts, near)
        else:
            # The look heard too little to fit and a fit's weak axis is noise: search from the
            # estimate along the heading the robot arrived on, a hallway's axis.
            res, trusted = yield from search_along_axis(
                d, island, pts, replace(res, pose=estimate), axis_rad=estimate.theta)
    if trusted and math.hypot(res.pose.x - estimate.x, res.pose.y - estimate.y) > (
            c.route_max_shift_m):
        trusted = False  # farther than a route's end can be: a look-alike place
    if trusted and d.spun_rad >= math.radians(c.alias_after_deg) and turned_alias(
            island, pts, res, c):
        trusted = False  # odometry's heading may be a quarter turn off: which one is unknown
    if trusted:
        d.spun_rad = 0.0
    fix = Fix(island.id, res.pose, trusted, res)
    if on_fix is not None:
        on_fix(fix)
    if not trusted:
        return fix
    est = res.pose
    if searched:  # the search moved the robot after the first look
        at = d.sense.odom
    for _ in range(c.dock_attempts):
        if math.hypot(est.x, est.y) <= c.dock_tol_m and abs(est.theta) <= math.radians(
            c.dock_tol_deg
        ):
            break
        o = d.sense.odom
        yield from go_to(d, o.compose(est.inverse()))  # the island origin in the odometry frame
        pts = yield from look_around(d)
        res, ok = localize_multi(island, pts, Pose2D(0.0, 0.0, 0.0), c)
        if not ok:
            break
        est, at = res.pose, d.sense.odom
    return replace(fix, origin_odom=at.compose(est.inverse()))


def search_along_axis(
    d: Drive, island: Island, pts: FloatArray, fit: LocalizationResult,
    axis_rad: float | None = None,
) -> Generator[Command, None, tuple[LocalizationResult, bool]]:
    """After an untrusted localization: look around again at points along its weak axis.

    A strategy may end well along a hallway from the target origin; there the look-around fits
    the island only in a degenerate basin (the along-hallway position unconstrained). The robot
    drives by odometry to +-k * step along that axis (k = 1..axis_search_steps, nearer first)
    from where it stood, looks around and localizes from the fit's prediction; it accepts the
    first trusted fit whose constraint is at least `axis_search_min_constraint`.
    `axis_rad` [rad, island frame]: search along this direction instead of the fit's weakest.
    """
    c = d.cfg
    at = d.sense.odom
    origin_odom = at.compose(fit.pose.inverse())  # where the fit puts the island origin
    if axis_rad is None:  # the fit's weakest direction [rad, island frame]
        axis_rad = unconstrained_axis_rad(island, pts, fit.pose, c.localize)
    axis = origin_odom.theta + axis_rad
    best, trusted = fit, False
    for k in range(1, c.axis_search_steps + 1):
        for sign in (1.0, -1.0):
            dist = sign * k * c.axis_search_step_m
            yield from go_to(
                d, Pose2D(at.x + dist * math.cos(axis), at.y + dist * math.sin(axis), at.theta))
            predicted = d.sense.odom.relative_to(origin_odom)
            look = yield from look_around(d)
            res, ok = localize_multi(island, look, predicted, c)
            if ok and res.constraint >= c.axis_search_min_constraint:
                return res, True
            best = res
    return best, trusted
