"""Imported worlds start in their largest connected free region, not in a closed room."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from island_sim.core.freespace import free_space
from island_sim.core.world_loader import load_world

RES_M = 0.1


def _plan_image() -> np.ndarray:
    """A 60 x 30 m plan at 0.1 m/px (row 0 at the top): a closed 10 x 10 m room (the widest
    open space) and, apart from it, an E of 2 m corridors with more floor area."""
    img = np.zeros((300, 600), dtype=np.uint8)  # walls everywhere
    img[10:110, 460:560] = 255  # the closed room, near the top right
    img[200:220, 20:420] = 255  # corridor along the bottom (y 8..10 m)
    for x0 in (20, 200, 400):
        img[20:220, x0:x0 + 20] = 255  # three corridors up from it
    return img


def test_an_image_world_starts_outside_its_closed_room(tmp_path: Path) -> None:
    path = tmp_path / "plan.pgm"
    path.write_bytes(b"P5\n600 300\n255\n" + _plan_image().tobytes())
    world = load_world(path, resolution_m=RES_M)
    sp = world.start_pose
    assert not (46.0 <= sp.x <= 56.0 and 19.0 <= sp.y <= 29.0), sp  # not in the room
    assert free_space(world, sp).area_m2 > 120.0  # the corridors (the room: 9.5^2 m^2 free)


def test_a_houseexpo_plan_starts_in_its_largest_region(tmp_path: Path) -> None:
    # two closed polygons in one HouseExpo file is not possible: one polygon, a long U-shaped
    # corridor around a wide bay; the start lies in the polygon's free space
    verts = [[0, 0], [20, 0], [20, 12], [18, 12], [18, 2], [2, 2], [2, 12], [0, 12]]
    path = tmp_path / "u.json"
    path.write_text(json.dumps({"id": "u", "verts": verts}))
    world = load_world(path)
    sp = world.start_pose
    assert 0.25 < sp.x < 19.75 and 0.25 < sp.y < 11.75
    assert sp.y < 2.0 or sp.x < 2.0 or sp.x > 18.0  # inside the U's 2 m corridors
    assert free_space(world, sp).area_m2 > 40.0
