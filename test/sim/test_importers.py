"""Floor-plan importers: PGM/PNG readers, wall tracing, Willow and HouseExpo imports."""

from __future__ import annotations

import json
import math
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
from island_sim.core.images import read_pgm, read_png
from island_sim.core.importers import (
    ImageImportConfig,
    grid_to_segments,
    import_image,
    rectangles_to_segments,
)
from island_sim.core.sonar import SonarConfig, SonarModel
from island_sim.core.world import World, WorldError
from island_sim.core.world_loader import load_world


def _png_chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


def _paeth(a: int, b: int, c: int) -> int:
    p = a + b - c
    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
    return a if pa <= pb and pa <= pc else (b if pb <= pc else c)


def _encode_png(pixels: np.ndarray, color: int, filters: list[int], palette: bytes = b"") -> bytes:
    """A minimal PNG writer (8-bit) that applies the given filter type to each row in turn."""
    h = pixels.shape[0]
    rows = pixels.reshape(h, -1).astype(np.int64)
    bpp = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}[color]
    out = bytearray()
    prev = np.zeros(rows.shape[1], dtype=np.int64)
    for y in range(h):
        f = filters[y % len(filters)]
        cur = rows[y]
        enc = []
        for i in range(cur.size):
            left = int(cur[i - bpp]) if i >= bpp else 0
            up = int(prev[i])
            ul = int(prev[i - bpp]) if i >= bpp else 0
            pred = [0, left, up, (left + up) >> 1, _paeth(left, up, ul)][f]
            enc.append((int(cur[i]) - pred) & 0xFF)
        out += bytes([f]) + bytes(enc)
        prev = cur
    ihdr = struct.pack(">IIBBBBB", pixels.shape[1], h, 8, color, 0, 0, 0)
    data = b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", ihdr)
    if palette:
        data += _png_chunk(b"PLTE", palette)
    return data + _png_chunk(b"IDAT", zlib.compress(bytes(out))) + _png_chunk(b"IEND", b"")


def _ray_blocked(world: World, ox: float, oy: float, ang: float) -> bool:
    return bool(np.isfinite(world.raycast([ox, oy], [ang]).distance_m[0]))


# ----------------------------------------------------------------------------- tracing


def test_single_pixel_becomes_a_square() -> None:
    occ = np.zeros((5, 5), dtype=bool)
    occ[1, 3] = True  # row 1 from the bottom, column 3
    segs = grid_to_segments(occ, 0.5, origin_m=(10.0, 20.0), simplify_tol_px=0.0)
    pts = {tuple(p) for p in segs.reshape(-1, 2).tolist()}
    assert pts == {(11.5, 20.5), (12.0, 20.5), (12.0, 21.0), (11.5, 21.0)}
    assert segs.shape == (4, 4)


def test_outline_is_closed_and_counter_clockwise_around_walls() -> None:
    occ = np.zeros((6, 8), dtype=bool)
    occ[1:4, 1:3] = True
    occ[1, 3:6] = True  # an L-shaped wall
    segs = grid_to_segments(occ, 1.0, simplify_tol_px=0.0)
    assert segs.shape == (6, 4)
    # Closed: every end point is some segment's start point.
    starts = {tuple(s) for s in segs[:, 0:2].tolist()}
    assert all(tuple(e) in starts for e in segs[:, 2:4].tolist())
    # Counter-clockwise: positive signed area (shoelace).
    area = 0.5 * np.sum(segs[:, 0] * segs[:, 3] - segs[:, 2] * segs[:, 1])
    assert area == pytest.approx(2 * 3 + 3)


def test_diagonal_wall_is_simplified_and_does_not_leak() -> None:
    n = 40
    occ = np.zeros((n + 2, n + 2), dtype=bool)
    for i in range(n):
        occ[i + 1, i + 1] = True  # a one-pixel diagonal line: 8-connected only
    segs = grid_to_segments(occ, 0.1, simplify_tol_px=1.0)
    assert segs.shape[0] <= 8  # one outline, not 40 squares or a 160-step staircase
    world = World(segs)
    # Rays crossing the diagonal anywhere, including exactly through pixel corners, are blocked.
    for k in np.linspace(0.35, 3.75, 60):
        assert _ray_blocked(world, k + 0.5, k - 0.5, math.pi * 0.75)
    unsimplified = grid_to_segments(occ, 0.1, simplify_tol_px=0.0)
    assert unsimplified.shape[0] > 100


def test_rectangles_to_segments_union() -> None:
    segs = rectangles_to_segments([(0.0, 0.0, 10.0, 2.0), (4.0, 2.0, 6.0, 8.0)])
    assert segs.shape == (8, 4)
    assert {tuple(s) for s in segs.tolist()} >= {(0.0, 0.0, 0.0, 2.0), (6.0, 8.0, 6.0, 2.0)}
    with pytest.raises(WorldError, match="multiples"):
        rectangles_to_segments([(0.0, 0.0, 1.1, 2.0)])
    with pytest.raises(WorldError, match="x1 <= x0"):
        rectangles_to_segments([(1.0, 0.0, 1.0, 2.0)])


# ----------------------------------------------------------------------------- readers


def _room_image(h: int = 30, w: int = 40) -> np.ndarray:
    img = np.full((h, w), 255, dtype=np.uint8)
    img[0, :] = img[-1, :] = img[:, 0] = img[:, -1] = 0
    img[2:6, 2:6] = 0  # a pillar near the TOP-left of the picture
    img[h // 3, w // 2] = 128  # a grey pixel: not dark enough for a wall
    return img


def test_read_pgm_binary_ascii_16bit(tmp_path: Path) -> None:
    img = _room_image()
    p5 = tmp_path / "a.pgm"
    p5.write_bytes(b"P5\n# a comment\n40 30\n255\n" + img.tobytes())
    assert np.array_equal(read_pgm(p5), img)
    p2 = tmp_path / "b.pgm"
    p2.write_text("P2\n40 30 # size\n255\n" + " ".join(str(v) for v in img.ravel()) + "\n")
    assert np.array_equal(read_pgm(p2), img)
    p16 = tmp_path / "c.pgm"
    p16.write_bytes(b"P5 40 30 65535\n" + (img.astype(">u2") * 257).tobytes())
    assert np.array_equal(read_pgm(p16), img)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        (b"P6\n2 2\n255\n" + bytes(12), "not a PGM"),
        (b"P5\n40 30\n255\n" + bytes(10), "truncated"),
        (b"P5\n40", "truncated PGM header"),
        (b"P5\nforty 30\n255\n", "bad PGM header"),
        (b"P5\n0 30\n255\n", "bad PGM size"),
    ],
)
def test_read_pgm_errors(tmp_path: Path, text: bytes, match: str) -> None:
    p = tmp_path / "bad.pgm"
    p.write_bytes(text)
    with pytest.raises(WorldError, match=match) as info:
        load_world(p)
    assert "bad.pgm" in str(info.value)


@pytest.mark.parametrize("filters", [[0], [1], [2], [3], [4], [0, 1, 2, 3, 4]])
def test_read_png_all_filters(tmp_path: Path, filters: list[int]) -> None:
    rng = np.random.default_rng(5)
    img = rng.integers(0, 256, (9, 13)).astype(np.uint8)
    p = tmp_path / "g.png"
    p.write_bytes(_encode_png(img, 0, filters))
    assert np.array_equal(read_png(p), img)


def test_read_png_colour_types(tmp_path: Path) -> None:
    img = _room_image(12, 16)
    rgb = np.repeat(img[:, :, None], 3, axis=2)
    (tmp_path / "rgb.png").write_bytes(_encode_png(rgb, 2, [4, 1]))
    assert np.array_equal(read_png(tmp_path / "rgb.png"), img)
    rgba = np.concatenate([rgb, np.full((*img.shape, 1), 255, np.uint8)], axis=2)
    (tmp_path / "rgba.png").write_bytes(_encode_png(rgba, 6, [3]))
    assert np.array_equal(read_png(tmp_path / "rgba.png"), img)
    idx = (img > 0).astype(np.uint8)
    (tmp_path / "pal.png").write_bytes(_encode_png(idx, 3, [0], palette=bytes([0] * 3 + [255] * 3)))
    assert np.array_equal(read_png(tmp_path / "pal.png"), np.where(idx > 0, 255, 0))


def test_read_png_errors(tmp_path: Path) -> None:
    p = tmp_path / "x.png"
    p.write_bytes(b"definitely not a png")
    with pytest.raises(WorldError, match=r"x\.png: not a PNG"):
        load_world(p)
    good = _encode_png(_room_image(), 0, [0])
    p.write_bytes(good[:-30] + b"\x00" * 30)  # damaged image data
    with pytest.raises(WorldError, match=r"x\.png"):
        load_world(p)
    ihdr = struct.pack(">IIBBBBB", 4, 4, 1, 0, 0, 0, 0)  # 1-bit grey
    p.write_bytes(b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", ihdr) + _png_chunk(b"IEND", b""))
    with pytest.raises(WorldError, match="bit depth 1"):
        load_world(p)


def test_unreadable_and_wallless_images(tmp_path: Path) -> None:
    d = tmp_path / "dir.png"
    d.mkdir()
    with pytest.raises(WorldError, match=r"dir\.png: cannot read"):
        import_image(d)
    white = tmp_path / "white.pgm"
    white.write_bytes(b"P5\n4 4\n255\n" + bytes([255] * 16))
    with pytest.raises(WorldError, match="no occupied"):
        load_world(white)
    with pytest.raises(WorldError, match="resolution_m"):
        ImageImportConfig(resolution_m=0.0)


def test_image_import_geometry(tmp_path: Path) -> None:
    img = _room_image()
    (tmp_path / "room.pgm").write_bytes(b"P5\n40 30\n255\n" + img.tobytes())
    (tmp_path / "room.png").write_bytes(_encode_png(img, 0, [4]))
    for name in ("room.pgm", "room.png"):
        world = load_world(tmp_path / name, resolution_m=0.25)
        assert world.name == "room"
        assert world.bounds == pytest.approx((0.0, 0.0, 10.0, 7.5))  # 40 x 30 px at 0.25 m
        # Origin lower-left: the pillar drawn near the top of the picture is at high y.
        # Pillar rows 2..5 from the top -> y in [7.5 - 6 * 0.25, 7.5 - 2 * 0.25] = [6.0, 7.0].
        hit = world.raycast([0.3, 6.5], [0.0]).distance_m[0]
        assert hit == pytest.approx(0.5 - 0.3)
        assert world.raycast([0.3, 2.0], [0.0]).distance_m[0] == pytest.approx(9.75 - 0.3)
        sp = world.start_pose
        assert 0.25 < sp.x < 9.75 and 0.25 < sp.y < 7.25
        assert not (0.5 <= sp.x <= 1.5 and 6.0 <= sp.y <= 7.0)


# ----------------------------------------------------------------------------- real floor plans


def test_willow_import_is_a_usable_world(shared_data: Path) -> None:
    world = load_world(shared_data / "floorplans" / "willow-full.pgm")
    x0, y0, x1, y1 = world.bounds
    assert x1 - x0 == pytest.approx(54.0, abs=2.0)
    assert y1 - y0 == pytest.approx(58.7, abs=2.0)
    assert 500 <= world.segments.shape[0] <= 5000
    sp = world.start_pose
    img = read_pgm(shared_data / "floorplans" / "willow-full.pgm")
    row, col = img.shape[0] - 1 - int(sp.y / 0.1), int(sp.x / 0.1)
    assert img[row, col] >= 250  # a known-free pixel
    ranges = SonarModel(SonarConfig(ideal=True)).scan(world, sp)
    assert np.isfinite(ranges).sum() >= 8  # inside the building: walls all around
    a = np.linspace(0, 2 * math.pi, 36, endpoint=False)
    assert world.raycast([sp.x, sp.y], a).distance_m.min() >= 0.5


def test_houseexpo_import(shared_data: Path) -> None:
    path = shared_data / "floorplans" / "house_expo_room_0000.json"
    world = load_world(path)
    verts = np.array(json.loads(path.read_text())["verts"])
    assert world.segments.shape[0] == verts.shape[0]
    assert world.name == "0004d52d1aeeb8ae6de39d6bd993e992"
    sp = world.start_pose
    a = np.linspace(0, 2 * math.pi, 36, endpoint=False)
    r = world.raycast([sp.x, sp.y], a).distance_m
    assert np.all(np.isfinite(r)) and r.min() >= 0.5  # inside the closed polygon


@pytest.mark.parametrize(
    ("data", "match"),
    [
        ({"verts": [[0, 0], [1, 0]]}, "at least 3"),
        ({"verts": [[0, 0], [1, 0], [1, float("nan")]]}, "point 2 has a NaN"),
        ({"verts": [[0, 0, 1], [1, 0, 1], [1, 1, 1]]}, r"\[x, y\] pairs"),
        ({"verts": [[0, 0], [0, 0], [1, 1], [1, 1]]}, "fewer than 3 distinct"),
    ],
)
def test_houseexpo_errors(tmp_path: Path, data: dict[str, object], match: str) -> None:
    p = tmp_path / "house.json"
    p.write_text(json.dumps(data))
    with pytest.raises(WorldError, match=match) as info:
        load_world(p)
    assert "house.json" in str(info.value)
