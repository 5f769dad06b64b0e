"""Sonar ring model: ideal ranges vs an independent ray cast, specularity, beam width, noise."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from island_msgs_py.types import Pose2D
from island_sim.core.sonar import SonarConfig, SonarError, SonarModel
from island_sim.core.world import World
from island_sim.core.world_loader import load_world

IDEAL = SonarConfig(ideal=True)
NOISELESS = SonarConfig(noise_std_m=0.0)


def _room() -> World:
    """A 10 x 8 m room with a pillar and a slanted wall."""
    segs = [
        [0, 0, 10, 0], [10, 0, 10, 8], [10, 8, 0, 8], [0, 8, 0, 0],
        [4, 3, 5, 3], [5, 3, 5, 4], [5, 4, 4, 4], [4, 4, 4, 3],
        [7, 6, 9, 7.5],
    ]
    return World(np.array(segs, dtype=np.float64), name="room")


def _independent_ray(segs: np.ndarray, ox: float, oy: float, ang: float) -> float:
    """Distance to the nearest wall along one ray, one segment at a time (no numpy tricks)."""
    ux, uy = math.cos(ang), math.sin(ang)
    best = math.inf
    for x1, y1, x2, y2 in segs.tolist():
        ex, ey = x2 - x1, y2 - y1
        den = ux * ey - uy * ex
        if abs(den) < 1e-15:
            continue
        wx, wy = x1 - ox, y1 - oy
        t = (wx * ey - wy * ex) / den
        v = (wx * uy - wy * ux) / den
        if t > 0 and 0 <= v <= 1:
            best = min(best, t)
    return best


def test_ideal_ranges_equal_independent_cast() -> None:
    world = _room()
    model = SonarModel(IDEAL)
    rng = np.random.default_rng(7)
    checked = 0
    for _ in range(40):
        pose = Pose2D(rng.uniform(0.5, 9.5), rng.uniform(0.5, 7.5), rng.uniform(-math.pi, math.pi))
        if 3.5 < pose.x < 5.5 and 2.5 < pose.y < 4.5:
            continue
        ranges = model.scan(world, pose)
        for i, b in enumerate(model.angles_rad):
            a = pose.theta + b
            ox = pose.x + IDEAL.ring_radius_m * math.cos(a)
            oy = pose.y + IDEAL.ring_radius_m * math.sin(a)
            d = _independent_ray(world.segments, ox, oy, a)
            if IDEAL.range_min_m <= d <= IDEAL.range_max_m:
                assert ranges[i] == pytest.approx(d + IDEAL.ring_radius_m, abs=1e-3)
                checked += 1
            else:
                assert math.isinf(ranges[i])
    assert checked > 300


def test_ideal_ranges_equal_independent_cast_in_paper_fig4() -> None:
    # 130 segments: World.raycast goes through the spatial index here.
    from island_sim.core.worlds_builtin import BUILTIN_FREE_RECTS

    world = load_world("paper_fig4")
    rects = BUILTIN_FREE_RECTS["paper_fig4"]()
    rng = np.random.default_rng(11)
    poses = []
    for k in rng.choice(len(rects), 30):
        x0, y0, x1, y1 = rects[k]
        poses.append([rng.uniform(x0, x1), rng.uniform(y0, y1), rng.uniform(-math.pi, math.pi)])
    model = SonarModel(IDEAL)
    scans = model.scan_many(world, np.array(poses))
    finite = 0
    for (x, y, th), ranges in zip(poses, scans, strict=True):
        for b, r in zip(model.angles_rad, ranges, strict=True):
            ox = x + IDEAL.ring_radius_m * math.cos(th + b)
            oy = y + IDEAL.ring_radius_m * math.sin(th + b)
            d = _independent_ray(world.segments, ox, oy, th + b)
            if IDEAL.range_min_m <= d <= IDEAL.range_max_m:
                assert r == pytest.approx(d + IDEAL.ring_radius_m, abs=1e-3)
                finite += 1
            else:
                assert math.isinf(r)
    assert finite > 200
    assert model.scan_many(world, np.zeros((0, 3))).shape == (0, 16)


def test_angles_and_limits() -> None:
    model = SonarModel(SonarConfig(num_transducers=8, first_angle_deg=10.0))
    assert model.angles_rad.shape == (8,)
    assert model.angles_rad[0] == pytest.approx(math.radians(10.0))
    assert np.allclose(np.diff(model.angles_rad), math.radians(45.0))
    assert model.scan_limits_m() == pytest.approx((0.15 + 0.225, 6.5 + 0.225))


def test_specular_loss_at_grazing_incidence() -> None:
    wall = World(np.array([[-20.0, 3.0, 20.0, 3.0]]))
    # Transducer 0 looks 60 deg from the wall normal: every ray in its 25 deg cone is > 30 deg.
    pose = Pose2D(0.0, 0.0, math.radians(30.0))
    assert math.isfinite(SonarModel(IDEAL).scan(world=wall, pose=pose)[0])
    assert math.isinf(SonarModel(NOISELESS).scan(wall, pose)[0])
    # Head-on the same wall echoes.
    head_on = SonarModel(NOISELESS).scan(wall, Pose2D(0.0, 0.0, math.pi / 2))[0]
    assert head_on == pytest.approx(3.0, abs=1e-9)


def test_beam_width_hides_a_narrow_gap() -> None:
    # A wall at y = 3 with a 0.3 m gap on the axis, a back wall at y = 6.
    segs = np.array([[-5.0, 3.0, -0.15, 3.0], [0.15, 3.0, 5.0, 3.0], [-5.0, 6.0, 5.0, 6.0]])
    world = World(segs)
    pose = Pose2D(0.0, 0.0, math.pi / 2)
    ideal = SonarModel(IDEAL).scan(world, pose)[0]
    wide = SonarModel(NOISELESS).scan(world, pose)[0]
    assert ideal == pytest.approx(6.0, abs=1e-9)  # the axis ray goes through the gap
    assert 3.0 <= wide < 3.2  # the cone sees the wall beside the gap: the gap is invisible
    # The off-axis echo is reported on the axis, longer than the perpendicular distance.
    assert wide > 3.0


def test_off_axis_echo_wins_when_nearer() -> None:
    # A wall 4 m ahead and a small plate 2 m away, 12.5 deg off the axis, facing the transducer.
    off = math.radians(90.0 - 12.5)
    tx, ty = 0.0, 0.225  # transducer 0 position for a robot at the origin facing +y
    cx, cy = tx + 2.0 * math.cos(off), ty + 2.0 * math.sin(off)
    px, py = -math.sin(off) * 0.1, math.cos(off) * 0.1  # plate half-length 0.1 m, perpendicular
    segs = np.array([[-10.0, 4.0, 10.0, 4.0], [cx - px, cy - py, cx + px, cy + py]])
    world = World(segs)
    pose = Pose2D(0.0, 0.0, math.pi / 2)
    assert SonarModel(IDEAL).scan(world, pose)[0] == pytest.approx(4.0, abs=1e-9)
    wide = SonarModel(NOISELESS).scan(world, pose)[0]
    assert wide == pytest.approx(2.0 + 0.225, abs=1e-6)


def test_range_limits() -> None:
    far = World(np.array([[-20.0, 7.0, 20.0, 7.0]]))
    pose = Pose2D(0.0, 0.0, math.pi / 2)
    assert math.isinf(SonarModel(IDEAL).scan(far, pose)[0])
    near = World(np.array([[-20.0, 0.3, 20.0, 0.3]]))  # 0.075 m from the transducer
    assert math.isinf(SonarModel(IDEAL).scan(near, pose)[0])
    ok = World(np.array([[-20.0, 6.6, 20.0, 6.6]]))  # 6.375 m from the transducer
    assert SonarModel(IDEAL).scan(ok, pose)[0] == pytest.approx(6.6)


def test_noise_is_seeded_and_reproducible() -> None:
    world = _room()
    model = SonarModel(SonarConfig(noise_std_m=0.05))
    pose = Pose2D(2.0, 2.0, 0.3)
    a = model.scan(world, pose, np.random.default_rng(3))
    b = model.scan(world, pose, np.random.default_rng(3))
    c = model.scan(world, pose, np.random.default_rng(4))
    assert np.array_equal(a, b)
    fin = np.isfinite(a) & np.isfinite(c)
    assert fin.sum() >= 4 and not np.allclose(a[fin], c[fin])
    # Default generator of a model is seeded too.
    m1, m2 = SonarModel(model.config, seed=5), SonarModel(model.config, seed=5)
    assert np.array_equal(m1.scan(world, pose), m2.scan(world, pose))
    # Noise statistics: many scans of the same pose scatter with the configured std.
    poses = np.tile(pose.as_array(), (400, 1))
    many = model.scan_many(world, poses, np.random.default_rng(1))
    clean = SonarModel(SonarConfig(noise_std_m=0.0)).scan(world, pose)
    col = int(np.argmax(np.isfinite(clean) & (clean < 5.0)))
    resid = many[:, col] - clean[col]
    assert abs(resid.mean()) < 0.01
    assert resid.std() == pytest.approx(0.05, rel=0.15)


def test_scan_many_matches_scan() -> None:
    world = _room()
    model = SonarModel(NOISELESS)
    poses = np.array([[1.0, 1.0, 0.0], [8.0, 2.0, 2.0], [2.5, 6.0, -1.0]])
    many = model.scan_many(world, poses)
    assert many.shape == (3, 16)
    for i, row in enumerate(poses):
        assert np.array_equal(many[i], model.scan(world, Pose2D.from_array(row)))
    with pytest.raises(SonarError, match="poses"):
        model.scan_many(world, np.zeros((2, 2)))
    with pytest.raises(SonarError, match="NaN"):
        model.scan_many(world, np.array([[0.0, np.nan, 0.0]]))


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"num_transducers": 0}, "num_transducers"),
        ({"rays_per_beam": 0}, "rays_per_beam"),
        ({"ring_radius_m": -1.0}, "ring_radius_m"),
        ({"beam_width_deg": 190.0}, "beam_width_deg"),
        ({"range_min_m": 3.0, "range_max_m": 2.0}, "range_max_m"),
        ({"reflect_deg": 0.0}, "reflect_deg"),
        ({"noise_std_m": -0.1}, "noise_std_m"),
        ({"noise_std_m": float("nan")}, "noise_std_m"),
        ({"num_transducers": 2.5}, "num_transducers"),
    ],
)
def test_config_validation(kwargs: dict[str, object], field: str) -> None:
    with pytest.raises(SonarError, match=field):
        SonarConfig(**kwargs)  # type: ignore[arg-type]


def test_core_does_not_import_rclpy() -> None:
    code = (
        "import sys, island_sim.core.sonar, island_sim.core.world; "
        "sys.exit(1 if any(m.startswith('rclpy') for m in sys.modules) else 0)"
    )
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0
