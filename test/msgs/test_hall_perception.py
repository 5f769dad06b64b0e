"""hall_perception.perceive: what a scan says about the hallway, checked against its definition
written out directly (every bearing's trigonometry per call) on scans with gaps, bad values and
rings of different sizes, and on a corridor whose answer is known."""

from __future__ import annotations

import math

import numpy as np
import pytest
from island_msgs_py.hall_perception import (
    HallPerceptionConfig,
    Perception,
    PerceptionError,
    fit_wall,
    perceive,
)


def perceive_by_definition(ranges_m: np.ndarray, angles_rad: np.ndarray,
                           c: HallPerceptionConfig) -> Perception:
    """The perception as defined in the module docstring, nothing computed ahead."""
    r = np.where(np.isnan(ranges_m) | (ranges_m <= 0), np.inf, ranges_m)
    a = np.arctan2(np.sin(angles_rad), np.cos(angles_rad))
    ok = np.isfinite(r)
    rr = np.where(ok, r, 0.0)
    x = np.where(ok, rr * np.cos(a), np.nan)
    y = np.where(ok, rr * np.sin(a), np.nan)
    sides = []
    for sign in (1.0, -1.0):
        d = a - sign * math.pi / 2.0
        off = np.abs(np.arctan2(np.sin(d), np.cos(d)))
        perp = int(np.argmin(off))
        perp_m = float(r[perp] * abs(math.sin(a[perp])))
        is_open = not perp_m <= c.open_side_m
        sel = ok & (off <= math.radians(c.side_half_angle_deg))
        sel &= np.abs(np.nan_to_num(y)) <= c.open_side_m
        pts = np.stack([x[sel], y[sel]], axis=1)
        sides.append((is_open, *fit_wall(pts, math.inf if is_open else perp_m, c.fit_tolerance_m)))
    (l_open, l_dist, l_ang), (r_open, r_dist, r_ang) = sides
    # the path: radius + path margin, or less where a side wall is nearer (its echoes within
    # the fit tolerance kept out), never below radius + narrow margin
    clear = min(l_dist, r_dist) - c.robot_radius_m - c.fit_tolerance_m
    half = c.robot_radius_m + min(c.path_margin_m, max(c.narrow_margin_m, clear))
    front_free = float(r[int(np.argmin(np.abs(a)))])
    front = cone = front_free
    in_path = ok & (np.nan_to_num(x) > 0)
    in_path &= np.abs(np.nan_to_num(y)) <= half
    if np.any(in_path):
        front = min(front, float(np.min(x[in_path])))
    ahead = in_path & (np.abs(a) <= math.radians(30.0))  # the cone of front_cone_m
    if np.any(ahead):
        cone = min(cone, float(np.min(x[ahead])))
    wall = None
    if l_ang is not None and r_ang is not None and abs(l_ang - r_ang) <= math.radians(8.0):
        wall = 0.5 * (l_ang + r_ang)
    return Perception(front, front_free, l_open, r_open, l_dist, r_dist, wall, cone)


@pytest.mark.parametrize("n", [12, 16, 24])
def test_perceive_equals_its_definition_on_random_scans(n: int) -> None:
    rng = np.random.default_rng(n)
    cfg = HallPerceptionConfig()
    angles = np.arange(n) * (2.0 * math.pi / n) + 0.1 * (n == 24)  # unwrapped, one ring offset
    walls = 0
    for _ in range(400):
        ranges = rng.uniform(0.3, 4.0, n)
        ranges[rng.random(n) < 0.2] = np.inf
        ranges[rng.random(n) < 0.03] = np.nan
        ranges[rng.random(n) < 0.03] = -1.0
        if rng.random() < 0.5:  # a corridor: both side walls straight, some barely wide enough
            half = rng.uniform(0.3, 1.6)
            side = np.abs(np.sin(angles)) > 0.5
            ranges[side] = half / np.abs(np.sin(angles[side]))
        want = perceive_by_definition(ranges, angles, cfg)
        assert perceive(ranges, angles, cfg) == want
        walls += want.wall_angle_rad is not None
    assert walls > 50  # the corridors gave wall fits: the fitting path was compared too


def test_perceive_in_a_corridor_and_bad_scans() -> None:
    cfg = HallPerceptionConfig()
    angles = np.arange(16) * (2.0 * math.pi / 16)
    sin = np.abs(np.sin(angles))
    ranges = np.where(sin > 0.3, 1.0 / np.maximum(sin, 1e-9), np.inf)  # walls at +-1 m
    p = perceive(ranges, angles, cfg)
    assert p.left_dist_m == pytest.approx(1.0) and p.right_dist_m == pytest.approx(1.0)
    assert p.wall_angle_rad == pytest.approx(0.0, abs=1e-9)
    assert not p.left_open and not p.right_open and p.front_free_m == math.inf
    with pytest.raises(PerceptionError, match="must be non-empty and match"):
        perceive(ranges[:3], angles, cfg)
    bad = angles.copy()
    bad[2] = np.nan
    with pytest.raises(PerceptionError, match="NaN or infinite bearing"):
        perceive(ranges, bad, cfg)


def narrow_hall_scan(half_m: float, angles: np.ndarray, front_m: float = np.inf,
                     blind_m: float = 0.4) -> np.ndarray:
    """A ring centred in a hallway `half_m` either side, a wall `front_m` ahead, echoes nearer
    than `blind_m` lost (a sonar's minimum range, counted from the robot centre)."""
    sin, cos = np.abs(np.sin(angles)), np.cos(angles)
    side = np.where(sin > 1e-9, half_m / np.maximum(sin, 1e-9), np.inf)
    ahead = np.full(angles.shape, np.inf)
    if math.isfinite(front_m):
        hit = (cos > 1e-9) & (np.abs(np.tan(angles)) * front_m <= half_m)
        ahead[hit] = front_m / cos[hit]
    r = np.minimum(side, ahead)
    return np.where(r < blind_m, np.inf, r)


def test_a_hallway_barely_wider_than_the_robot_is_open_ahead() -> None:
    """HouseExpo 1451's central hallway: 0.77 m wide, a 0.25 m robot. Its walls, heard on the
    oblique transducers, are beside the path, not in it; a wall across the hallway still is,
    and without the narrowing (narrow margin = path margin) the hallway reads blocked."""
    angles = np.arange(16) * (2.0 * math.pi / 16)
    cfg = HallPerceptionConfig()
    open_hall = perceive(narrow_hall_scan(0.385, angles), angles, cfg)
    assert open_hall.front_m == math.inf and open_hall.front_cone_m == math.inf
    assert open_hall.left_dist_m == pytest.approx(0.385, abs=0.01)
    walled = perceive(narrow_hall_scan(0.385, angles, front_m=1.5), angles, cfg)
    assert walled.front_m == pytest.approx(1.5)
    rigid = HallPerceptionConfig(narrow_margin_m=cfg.path_margin_m)
    assert perceive(narrow_hall_scan(0.385, angles), angles, rigid).front_m < 0.5
    wide = perceive(narrow_hall_scan(1.0, angles), angles, cfg)  # a wide hallway: as before
    assert wide == perceive(narrow_hall_scan(1.0, angles), angles, rigid)
