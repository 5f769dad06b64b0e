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
    front_free = float(r[int(np.argmin(np.abs(a)))])
    front = cone = front_free
    in_path = ok & (np.nan_to_num(x) > 0)
    in_path &= np.abs(np.nan_to_num(y)) <= c.robot_radius_m + c.path_margin_m
    if np.any(in_path):
        front = min(front, float(np.min(x[in_path])))
    ahead = in_path & (np.abs(a) <= math.radians(30.0))  # the cone of front_cone_m
    if np.any(ahead):
        cone = min(cone, float(np.min(x[ahead])))
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
        if rng.random() < 0.5:  # a corridor: both side walls straight
            half = rng.uniform(0.8, 1.6)
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
