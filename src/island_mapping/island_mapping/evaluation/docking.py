"""Finding the simulated robot in an island and docking on its origin (paper section 8.2).

Simulator-backed (numpy + island_sim cores, no ROS):

1. `look_around`: rotate once in place collecting sonar points (in the robot frame by
   odometry);
2. `localize_multi`: localize them against the island's line model from several initial
   guesses around the current estimate, keep the converged result with the smallest residual;
3. `localize_and_dock`: when that is not trusted, look again at points along the fit's least
   constrained axis (a hallway); when trusted, drive by odometry onto the island origin
   (0, 0, 0) and re-localize, up to `dock_attempts` times, until within `dock_tol_m` /
   `dock_tol_deg`. The first trusted localization is checked against the robot's true pose in
   the island frame (the island's `origin_truth`, kept for evaluation only: `truth_in`).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from island_msgs_py.geometry import closest_on_segments, from_frame, to_frame
from island_msgs_py.types import FloatArray, Island, Pose2D, wrap_angle

from island_mapping.core.lines import thin_evenly
from island_mapping.core.localize import LocalizationResult, LocalizeConfig, localize
from island_mapping.evaluation.navigate import NavigateConfig, NavigateError, SimDriver


def look_around(sim: SimDriver) -> FloatArray:
    """Rotate once in place collecting scan points; return them in the final robot frame [m]."""
    pts = [sim.scan_points_odom()]
    c = sim.cfg
    done, last = 0.0, sim.robot.odom_pose.theta
    while done < 2.0 * math.pi:
        sim.step(0.0, c.turn_rate_radps)
        th = sim.robot.odom_pose.theta
        done += wrap_angle(th - last)
        last = th
        pts.append(sim.scan_points_odom())
    sim.step(0.0, 0.0)
    return to_frame(np.concatenate(pts, axis=0), sim.robot.odom_pose)


def localize_multi(
    island: Island, points_robot: FloatArray, estimate: Pose2D, cfg: NavigateConfig
) -> tuple[LocalizationResult, bool]:
    """Localize from initial guesses around `estimate`; (best result, trusted).

    The best result is the converged one with the smallest residual (any result when none
    converged); trusted = it converged with a residual below `max_residual_m`. A fit whose
    heading left the estimate's by more than `max_turn_deg`, or that constrains the position
    less than `min_fit_constraint`, counts as not converged.
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
        if (turned or res.constraint < cfg.min_fit_constraint) and res.converged:
            res = replace(res, converged=False)
        if best is None or (res.converged, -res.residual_m) > (best.converged, -best.residual_m):
            best = res
        if res.converged and res.residual_m <= cfg.max_residual_m:
            good.append(res.pose)
            # Guesses go outward from the estimate: stop once the nearest good fits agree.
            agree = [p for p in good if math.hypot(p.x - good[0].x, p.y - good[0].y) <= 0.1]
            if len(agree) >= cfg.min_agreeing:
                break
    assert best is not None
    return best, bool(best.converged and best.residual_m <= cfg.max_residual_m)


def truth_in(island: Island, true_pose: Pose2D) -> Pose2D:
    if island.origin_truth is None:
        raise NavigateError(f"island {island.id} has no origin_truth: cannot evaluate")
    return true_pose.relative_to(island.origin_truth)


def pose_error(a: Pose2D, b: Pose2D) -> tuple[float, float]:
    return math.hypot(a.x - b.x, a.y - b.y), abs(math.degrees(wrap_angle(a.theta - b.theta)))


def localize_and_dock(
    sim: SimDriver, island: Island, estimate: Pose2D
) -> tuple[bool, float, float]:
    """Localize in the island from the estimate, check against truth, dock at the origin.

    Returns (trusted localization, its position error [m], heading error [deg]) of the FIRST
    localization, or when that is not trusted of the one the search along the hallway ended
    with (the one that says whether the robot found the island); docking does not change it."""
    c = sim.cfg
    pts = look_around(sim)
    res, trusted = localize_multi(island, pts, estimate, c)
    if not trusted and c.axis_search_step_m > 0 and c.axis_search_steps > 0:
        # Search from the fit nearest the estimate: the smallest residual may be a wrong
        # heading basin (paper_fig4 edge 6->7: 2 of 12 starts failed so, 0 of 12 from here).
        if pts.shape[0] >= c.sparse_look_points:
            near = localize(island.model, thin_evenly(pts, c.max_points), estimate, c.localize)
            res, trusted = _search_along_axis(sim, island, pts, near)
        else:
            # The look heard too little to fit (a crossing's middle: 16 echoes in a full turn)
            # and a fit's weak axis is noise: search from the estimate along the heading the
            # robot arrived on, a hallway's axis (no fit from the estimate is needed for that).
            res, trusted = _search_along_axis(
                sim, island, pts, replace(res, pose=estimate), axis_rad=estimate.theta)
    err_m, err_deg = pose_error(res.pose, truth_in(island, sim.robot.true_pose))
    first = (trusted, err_m, err_deg)
    if not trusted:
        return first
    est = res.pose
    for _ in range(c.dock_attempts):
        if math.hypot(est.x, est.y) <= c.dock_tol_m and abs(est.theta) <= math.radians(
            c.dock_tol_deg
        ):
            break
        o = sim.robot.odom_pose
        sim.go_to(o.compose(est.inverse()))  # the island origin in the odometry frame
        pts = look_around(sim)
        res, ok = localize_multi(island, pts, Pose2D(0.0, 0.0, 0.0), c)
        if not ok:
            break
        est = res.pose
    return first


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


def _search_along_axis(
    sim: SimDriver, island: Island, pts: FloatArray, fit: LocalizationResult,
    axis_rad: float | None = None,
) -> tuple[LocalizationResult, bool]:
    """After an untrusted localization: look around again at points along its weak axis.

    A strategy may end well along a hallway from the target origin (e.g. an edge recorded across
    dismissed attempts); there the look-around fits the island only in a degenerate basin (the
    along-hallway position unconstrained). The robot drives by odometry to +-k * step along that
    axis (k = 1..axis_search_steps, nearer first) from where it stood, looks around and localizes
    from the fit's prediction; it accepts the first trusted fit whose constraint is at least
    `axis_search_min_constraint` (points on a plain hallway alias along it with a constraint
    just above the convergence threshold, so a search needs a clearly constrained fit).
    `axis_rad` [rad, island frame]: search along this direction instead of the fit's weakest.
    """
    c = sim.cfg
    at = sim.robot.odom_pose
    origin_odom = at.compose(fit.pose.inverse())  # where the fit puts the island origin
    if axis_rad is None:  # the fit's weakest direction [rad, island frame]
        axis_rad = unconstrained_axis_rad(island, pts, fit.pose, c.localize)
    axis = origin_odom.theta + axis_rad
    best, trusted = fit, False
    for k in range(1, c.axis_search_steps + 1):
        for sign in (1.0, -1.0):
            d = sign * k * c.axis_search_step_m
            sim.go_to(Pose2D(at.x + d * math.cos(axis), at.y + d * math.sin(axis), at.theta))
            predicted = sim.robot.odom_pose.relative_to(origin_odom)
            res, ok = localize_multi(island, look_around(sim), predicted, c)
            if ok and res.constraint >= c.axis_search_min_constraint:
                return res, True
            best = res
    return best, trusted
