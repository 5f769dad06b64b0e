"""island_msgs_py.geometry: pose algebra, frames, scans -> points, points vs segments."""

from __future__ import annotations

import math

import numpy as np
import pytest
from island_msgs_py.geometry import (
    GeometryError,
    clearance_m,
    closest_on_segment_rows,
    closest_on_segments,
    compose_poses,
    from_frame,
    inverse_poses,
    point_segment_distance,
    ranges_to_points,
    relative_poses,
    to_frame,
    wrap_angles,
)
from island_msgs_py.types import Pose2D, wrap_angle

RNG_SEED = 5


def _poses(n: int, rng: np.random.Generator) -> np.ndarray:
    return np.stack(
        [rng.uniform(-5, 5, n), rng.uniform(-5, 5, n), rng.uniform(-math.pi, math.pi, n)], axis=1
    )


def test_wrap_angles_agrees_with_the_scalar_wrap() -> None:
    a = np.random.default_rng(RNG_SEED).uniform(-20.0, 20.0, 500)
    w = wrap_angles(a)
    assert np.all(np.abs(w) <= math.pi)
    assert w == pytest.approx([wrap_angle(float(v)) for v in a], abs=1e-12)
    assert np.allclose(np.cos(w), np.cos(a)) and np.allclose(np.sin(w), np.sin(a))


def test_pose_algebra_matches_pose2d_and_round_trips() -> None:
    rng = np.random.default_rng(RNG_SEED)
    a, b = _poses(50, rng), _poses(50, rng)
    ab = compose_poses(a, b)
    for i in range(50):
        want = Pose2D.from_array(a[i]).compose(Pose2D.from_array(b[i]))
        assert ab[i] == pytest.approx(want.as_array(), abs=1e-12)
        rel = Pose2D.from_array(b[i]).relative_to(Pose2D.from_array(a[i]))
        assert relative_poses(a, b)[i] == pytest.approx(rel.as_array(), abs=1e-12)
        inv = Pose2D.from_array(a[i]).inverse()
        assert inverse_poses(a)[i] == pytest.approx(inv.as_array(), abs=1e-12)
    back = compose_poses(a, relative_poses(a, b))
    assert back[:, :2] == pytest.approx(b[:, :2], abs=1e-12)
    assert wrap_angles(back[:, 2] - b[:, 2]) == pytest.approx(0.0, abs=1e-12)
    assert compose_poses(a, inverse_poses(a)) == pytest.approx(np.zeros((50, 3)), abs=1e-12)
    # One pose against many rows broadcasts; a (3,) pose is one row.
    assert compose_poses(a[0], b) == pytest.approx(compose_poses(np.tile(a[0], (50, 1)), b))
    with pytest.raises(GeometryError, match=r"\(N, 3\) poses"):
        compose_poses(np.zeros((2, 2)), b)


def test_points_to_and_from_a_frame() -> None:
    rng = np.random.default_rng(RNG_SEED)
    pts = rng.uniform(-3, 3, (40, 2))
    frame = Pose2D(1.0, -2.0, 0.7)
    out = from_frame(pts, frame)
    for p, q in zip(pts, out, strict=True):
        want = frame.compose(Pose2D(float(p[0]), float(p[1]), 0.0))
        assert q == pytest.approx([want.x, want.y], abs=1e-12)
    assert to_frame(out, frame) == pytest.approx(pts, abs=1e-12)
    assert np.array_equal(from_frame(pts, frame.as_array()), out)  # a (3,) array works too
    assert from_frame(np.zeros((0, 2)), frame).shape == (0, 2)
    with pytest.raises(GeometryError, match="frame"):
        to_frame(pts, [1.0, 2.0])


def test_ranges_to_points() -> None:
    r = np.array([1.0, np.inf, 2.0, np.nan])
    a = np.array([0.0, 0.5, math.pi / 2, 1.0])
    local = ranges_to_points(r, a)
    assert local == pytest.approx(np.array([[1.0, 0.0], [0.0, 2.0]]))
    world_pts = ranges_to_points(r, a, Pose2D(1.0, 2.0, math.pi / 2))
    assert world_pts == pytest.approx(np.array([[1.0, 3.0], [-1.0, 2.0]]))
    with pytest.raises(GeometryError):
        ranges_to_points(r, a[:2])


def test_point_segment_distance_and_closest_points() -> None:
    segs = np.array([[0.0, 0.0, 2.0, 0.0], [3.0, 3.0, 3.0, 4.0], [5.0, 5.0, 5.0, 5.0]])
    pts = np.array([[1.0, 0.5], [-1.0, 0.0], [3.0, 5.0], [5.0, 6.0]])
    d = point_segment_distance(pts, segs)
    assert d.shape == (4, 3)
    assert d[0, 0] == pytest.approx(0.5)  # foot inside the segment
    assert d[1, 0] == pytest.approx(1.0)  # beyond an end: distance to that end
    assert d[2, 1] == pytest.approx(1.0)
    assert d[3, 2] == pytest.approx(1.0)  # a zero-length segment is a point
    idx, foot, dist = closest_on_segments(pts, segs)
    assert idx.tolist() == [0, 0, 1, 2]
    assert foot == pytest.approx(np.array([[1.0, 0.0], [0.0, 0.0], [3.0, 4.0], [5.0, 5.0]]))
    assert dist == pytest.approx(d.min(axis=1))
    foot_rows, dist_rows = closest_on_segment_rows(pts[[0, 2]], segs[[1, 0]])
    assert foot_rows == pytest.approx(np.array([[3.0, 3.0], [2.0, 0.0]]))
    assert dist_rows == pytest.approx([math.hypot(2.0, 2.5), math.hypot(1.0, 5.0)])


def test_clearance_of_points_and_segment_ends() -> None:
    segs = np.array([[0.0, 0.0, 1.0, 0.0], [3.0, 3.0, 3.0, 4.0]])
    assert clearance_m([[0.5, 0.3]], segs)[0] == pytest.approx(0.3)
    assert clearance_m([[-0.3, -0.4]], segs)[0] == pytest.approx(0.5)
    assert clearance_m([[1.0, 1.0]], np.zeros((0, 4)))[0] == math.inf


def test_clearance_in_chunks_equals_point_by_point() -> None:
    rng = np.random.default_rng(RNG_SEED)
    segs = rng.uniform(-10, 10, (3000, 4))  # many walls: several chunks of points
    pts = rng.uniform(-10, 10, (1000, 2))
    many = clearance_m(pts, segs)
    one_by_one = np.array([clearance_m(p[None], segs)[0] for p in pts])
    assert np.array_equal(many, one_by_one)
    assert many == pytest.approx(point_segment_distance(pts, segs).min(axis=1), abs=1e-12)
