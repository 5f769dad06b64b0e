"""Line fitting (paper section 6): known walls come back from noisy laser and sonar points."""

from __future__ import annotations

import math

import numpy as np
import pytest
from island_mapping.core.lines import (
    LASER_LINE_FIT,
    LineFitConfig,
    LineFitError,
    fit_lines,
    fit_lines_with_support,
)
from island_msgs_py.geometry import ranges_to_points
from island_msgs_py.raycast import raycast
from island_msgs_py.types import LineModel, Pose2D
from island_sim.core.sonar import SonarModel
from island_sim.core.world import World

ROOM = np.array([[-3, -2, 3, -2], [3, -2, 3, 2], [3, 2, -3, 2], [-3, 2, -3, -2]], float)


def laser_points(walls: np.ndarray, origin: tuple[float, float], rng: np.random.Generator,
                 n_beams: int = 360, noise_m: float = 0.01) -> np.ndarray:
    a = np.radians((np.arange(n_beams) + 0.5) * 360.0 / n_beams)
    h = raycast(walls, np.array([origin]), a)
    ok = np.isfinite(h.distance_m)
    d = h.distance_m[ok]
    pts = np.c_[origin[0] + d * np.cos(a[ok]), origin[1] + d * np.sin(a[ok])]
    return pts + rng.normal(0.0, noise_m, pts.shape)


def match_wall(wall: np.ndarray, segs: np.ndarray) -> tuple[float, float, float]:
    """(max endpoint-to-wall-line offset, angle diff deg, covered fraction) of the best segment."""
    d = wall[2:4] - wall[0:2]
    length = float(np.hypot(*d))
    u = d / length
    n = np.array([-u[1], u[0]])
    best = (math.inf, math.inf, 0.0)
    for s in segs:
        off = max(abs(float((s[0:2] - wall[0:2]) @ n)), abs(float((s[2:4] - wall[0:2]) @ n)))
        sd = s[2:4] - s[0:2]
        ang = math.degrees(math.acos(min(1.0, abs(float(sd @ u)) / float(np.hypot(*sd)))))
        t = sorted([float((s[0:2] - wall[0:2]) @ u), float((s[2:4] - wall[0:2]) @ u)])
        cover = max(0.0, min(length, t[1]) - max(0.0, t[0])) / length
        if off < best[0]:
            best = (off, ang, cover)
    return best


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_laser_scan_recovers_the_four_walls_of_a_room(seed: int) -> None:
    rng = np.random.default_rng(seed)
    origin = tuple(rng.uniform(-1.0, 1.0, 2))
    pts = laser_points(ROOM, origin, rng)
    for cfg in (LineFitConfig(), LASER_LINE_FIT):
        segs = fit_lines(pts, cfg).segments
        assert 4 <= len(segs) <= 5
        for wall in ROOM:
            off, ang, cover = match_wall(wall, segs)
            assert off < 0.04 and ang < 1.5 and cover > 0.9, (wall, off, ang, cover)


def test_180_beam_half_scan_gives_the_walls_in_view() -> None:
    rng = np.random.default_rng(5)
    a = np.radians(np.arange(180) + 0.5)  # 0..180 deg like a SICK laser, looking +y
    h = raycast(ROOM, np.array([[0.0, 0.0]]), a)
    pts = np.c_[h.distance_m * np.cos(a), h.distance_m * np.sin(a)] + rng.normal(0, 0.01, (180, 2))
    segs = fit_lines(pts, LASER_LINE_FIT).segments
    assert len(segs) == 3  # right wall (upper half), top wall, left wall (upper half)
    off, ang, cover = match_wall(ROOM[2], segs)
    assert off < 0.03 and ang < 1.0 and cover > 0.95


def test_sonar_ring_points_accumulated_at_four_corners_recover_the_walls() -> None:
    rng = np.random.default_rng(7)
    sonar = SonarModel()
    world = World(ROOM)
    clouds = []
    for x, y in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]:
        pose = Pose2D(x, y, 0.0)
        clouds.append(ranges_to_points(sonar.scan(world, pose, rng), sonar.angles_rad, pose))
    pts = np.concatenate(clouds)
    segs = fit_lines(pts).segments
    assert 4 <= len(segs) <= 6
    for wall in ROOM:
        off, ang, _ = match_wall(wall, segs)
        assert off < 0.15 and ang < 5.0, (wall, off, ang)


def test_corner_points_are_split_into_two_segments() -> None:
    t = np.linspace(0.0, 2.0, 21)
    pts = np.concatenate([np.c_[t, np.zeros_like(t)], np.c_[np.zeros_like(t[1:]), t[1:]]])
    segs = fit_lines(pts, LASER_LINE_FIT).segments
    assert len(segs) == 2
    dirs = sorted(abs(math.degrees(math.atan2(s[3] - s[1], s[2] - s[0]))) % 180 for s in segs)
    assert dirs[0] == pytest.approx(0.0, abs=1.0) and dirs[1] == pytest.approx(90.0, abs=1.0)
    lengths = sorted(float(np.hypot(s[2] - s[0], s[3] - s[1])) for s in segs)
    assert lengths == pytest.approx([2.0, 2.0], abs=0.15)


def test_collinear_pieces_merge_across_a_small_gap_but_not_a_large_one() -> None:
    a = np.c_[np.linspace(0, 2, 21), np.zeros(21)]
    near = np.c_[np.linspace(2.6, 4.6, 21), np.full(21, 0.02)]  # 0.6 m gap
    far = np.c_[np.linspace(6.0, 8.0, 21), np.zeros(21)]  # 4 m gap
    cfg = LineFitConfig(cluster_dist_m=0.3, merge_gap_m=1.0)
    assert len(fit_lines(np.concatenate([a, near]), cfg)) == 1
    assert len(fit_lines(np.concatenate([a, far]), cfg)) == 2


def test_support_indices_point_back_to_the_input_rows() -> None:
    pts = np.c_[np.linspace(0, 2, 11), np.zeros(11)]
    pts = np.concatenate([pts, [[np.nan, 1.0]]])
    segs, support = fit_lines_with_support(pts)
    assert segs.shape == (1, 4) and sorted(support[0].tolist()) == list(range(11))


@pytest.mark.parametrize(
    "points",
    [
        np.zeros((0, 2)),
        np.array([[1.0, 2.0]]),
        np.array([[1.0, 2.0], [1.5, 2.0]]),
        np.full((6, 2), np.nan),
        np.array([[0.0, 0.0], [np.inf, 1.0], [1.0, np.nan]]),
        np.zeros((5, 2)),  # all points identical
        np.zeros((4, 3)),  # wrong shape
        "not points",
    ],
)
def test_degenerate_input_gives_an_empty_model_never_an_exception(points: object) -> None:
    model = fit_lines(points)  # type: ignore[arg-type]
    assert isinstance(model, LineModel) and len(model) == 0


def test_all_collinear_points_give_one_segment_spanning_them() -> None:
    pts = np.c_[np.linspace(-1, 1, 9), 0.5 * np.linspace(-1, 1, 9)]
    segs = fit_lines(pts).segments
    assert segs.shape == (1, 4)
    ends = sorted([tuple(np.round(segs[0, 0:2], 6)), tuple(np.round(segs[0, 2:4], 6))])
    assert ends == [(-1.0, -0.5), (1.0, 0.5)]


def test_bad_config_names_the_field() -> None:
    with pytest.raises(LineFitError, match="cluster_dist_m"):
        LineFitConfig(cluster_dist_m=float("nan"))
    with pytest.raises(LineFitError, match="min_points"):
        LineFitConfig(min_points=1)
