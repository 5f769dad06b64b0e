"""Occupancy images as grey-level arrays: binary/ASCII PGM and 8/16-bit PNG (standard library
and numpy only), every declared size bounded before any work; a bad file is a WorldError naming it.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np
import numpy.typing as npt
from island_msgs_py.limits import MAX_IMAGE_BYTES, MAX_IMAGE_FILE_BYTES

from island_msgs_py import inputs
from island_sim.core.world import WorldError

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_IHDR_BYTES = 13  # width, height (4 bytes each), depth, colour type, compression, filter, interlace


def _check_image_size(path: Path, kind: str, width: int, height: int, bytes_per_px: int) -> None:
    """WorldError naming the file unless the declared size is positive and decodes to at most
    MAX_IMAGE_BYTES."""
    if width <= 0 or height <= 0:
        raise WorldError(f"{path}: bad {kind} size {width}x{height} (both must be > 0)")
    if width * height * bytes_per_px > MAX_IMAGE_BYTES:
        raise WorldError(f"{path}: image of {width}x{height} pixels ({bytes_per_px} bytes each) "
                         f"decodes to {width * height * bytes_per_px} bytes, the limit is "
                         f"{MAX_IMAGE_BYTES}")


def read_pgm(path: Path) -> npt.NDArray[np.uint8]:
    """(H, W) grey levels 0-255 of a P5 (binary) or P2 (ASCII) PGM; row 0 is the top."""
    data = inputs.read_bytes(path, MAX_IMAGE_FILE_BYTES, WorldError, "PGM image")
    magic = data[:2]
    if magic not in (b"P5", b"P2"):
        raise WorldError(f"{path}: not a PGM image (magic {magic!r}, expected P5 or P2)")
    tokens: list[bytes] = []
    pos = 2
    # Header: width, height, maxval, separated by whitespace, with '#' comments.
    while len(tokens) < 3:
        while pos < len(data) and data[pos : pos + 1].isspace():
            pos += 1
        if pos >= len(data):
            raise WorldError(f"{path}: truncated PGM header")
        if data[pos : pos + 1] == b"#":
            nl = data.find(b"\n", pos)
            pos = len(data) if nl < 0 else nl + 1
            continue
        start = pos
        while pos < len(data) and not data[pos : pos + 1].isspace() and pos - start <= 32:
            pos += 1
        tokens.append(data[start:pos])
    names = ("width", "height", "maxval")
    width, height, maxval = (
        inputs.parse_int(tok.decode("latin-1"), f"{path}: bad PGM header {name}", WorldError)
        for name, tok in zip(names, tokens, strict=True))
    if not 0 < maxval < 65536:
        raise WorldError(f"{path}: PGM maxval must be in 1..65535, got {maxval}")
    _check_image_size(path, "PGM", width, height, 2 if maxval > 255 else 1)
    count = width * height
    if magic == b"P5":
        pos += 1  # exactly one whitespace byte after maxval
        dtype = np.dtype(">u2") if maxval > 255 else np.dtype(np.uint8)
        raw = data[pos : pos + count * dtype.itemsize]
        if len(raw) < count * dtype.itemsize:
            raise WorldError(f"{path}: PGM pixel data truncated ({len(raw)} bytes)")
        img = np.frombuffer(raw, dtype=dtype).astype(np.float64)
    else:
        try:
            img = np.array(data[pos:].split()[:count], dtype=np.float64)
        except ValueError as exc:
            raise WorldError(f"{path}: bad ASCII PGM pixel value") from exc
        if img.size < count:
            raise WorldError(f"{path}: PGM pixel data truncated ({img.size} of {count} values)")
        if not np.all(np.isfinite(img)):
            raise WorldError(f"{path}: ASCII PGM pixel value NaN or infinite")
    scaled = np.clip(np.round(img * (255.0 / maxval)), 0, 255).astype(np.uint8)
    return scaled.reshape(height, width)


def _png_chunks(path: Path, data: bytes) -> tuple[tuple[int, ...], bytes | None, bytes]:
    """(IHDR fields, PLTE body or None, the IDAT bodies joined) of a PNG file's bytes."""
    if not data.startswith(_PNG_SIGNATURE):
        raise WorldError(f"{path}: not a PNG image (bad signature)")
    pos = len(_PNG_SIGNATURE)
    header: tuple[int, ...] | None = None
    palette: bytes | None = None
    idat = bytearray()
    while pos + 8 <= len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        ctype = data[pos + 4 : pos + 8]
        body = data[pos + 8 : pos + 8 + length]
        if len(body) < length:
            raise WorldError(f"{path}: PNG chunk {ctype!r} truncated")
        pos += 12 + length
        if header is None and ctype != b"IHDR":
            raise WorldError(f"{path}: PNG chunk {ctype!r} before IHDR (IHDR must be first)")
        if ctype == b"IHDR":
            if len(body) != _IHDR_BYTES:
                raise WorldError(f"{path}: PNG IHDR chunk of {len(body)} bytes, expected "
                                 f"{_IHDR_BYTES}")
            header = struct.unpack(">IIBBBBB", body)
        elif ctype == b"PLTE":
            palette = body
        elif ctype == b"IDAT":
            idat += body
        elif ctype == b"IEND":
            break
    if header is None:
        raise WorldError(f"{path}: PNG without IHDR chunk")
    return header, palette, bytes(idat)


def _png_inflate(path: Path, idat: bytes, expected: int) -> bytes:
    """The image data of `expected` bytes, inflated no further than that."""
    inflater = zlib.decompressobj()
    try:
        raw = inflater.decompress(idat, expected)
    except zlib.error as exc:
        raise WorldError(f"{path}: corrupt PNG image data ({exc})") from exc
    if len(raw) < expected:
        raise WorldError(f"{path}: PNG image data truncated ({len(raw)} of {expected} bytes)")
    return raw


def read_png(path: Path) -> npt.NDArray[np.uint8]:
    """(H, W) grey levels 0-255 of a non-interlaced 8/16-bit PNG (grey, RGB, palette, +alpha)."""
    data = inputs.read_bytes(path, MAX_IMAGE_FILE_BYTES, WorldError, "PNG image")
    header, palette, idat = _png_chunks(path, data)
    width, height, depth, color, _comp, _filt, interlace = header
    channels = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}.get(color)
    if channels is None or depth not in (8, 16) or (color == 3 and depth != 8):
        raise WorldError(
            f"{path}: unsupported PNG (colour type {color}, bit depth {depth}); "
            "use 8 or 16-bit grey, RGB or 8-bit palette"
        )
    if interlace:
        raise WorldError(f"{path}: interlaced PNG is not supported")
    bpp = channels * depth // 8
    _check_image_size(path, "PNG", width, height, bpp)
    stride = width * bpp
    raw = _png_inflate(path, idat, height * (stride + 1))
    rows = _png_unfilter(np.frombuffer(raw, dtype=np.uint8), height, stride, bpp, path)
    if depth == 16:
        px = rows.reshape(height, width, channels, 2)[..., 0].astype(np.float64)  # high bytes
    else:
        px = rows.reshape(height, width, channels).astype(np.float64)
    if color == 3:
        if palette is None:
            raise WorldError(f"{path}: palette PNG without PLTE chunk")
        if not palette or len(palette) % 3:
            raise WorldError(f"{path}: PNG palette of {len(palette)} bytes (3 per colour)")
        pal = np.frombuffer(palette, dtype=np.uint8).reshape(-1, 3).astype(np.float64)
        idx = px[..., 0].astype(np.int64)
        if idx.max() >= pal.shape[0]:
            raise WorldError(f"{path}: PNG palette index out of range")
        grey = pal[idx].mean(axis=2)
    elif color in (2, 6):
        grey = px[..., :3].mean(axis=2)
    else:
        grey = px[..., 0]
    return np.clip(np.round(grey), 0, 255).astype(np.uint8)


def _png_unfilter(
    raw: npt.NDArray[np.uint8], height: int, stride: int, bpp: int, path: Path
) -> npt.NDArray[np.uint8]:
    """Undo the per-row PNG filters; returns (height, stride) bytes."""
    out = np.zeros((height, stride), dtype=np.uint8)
    prev = np.zeros(stride, dtype=np.int64)
    for y in range(height):
        base = y * (stride + 1)
        ftype = int(raw[base])
        line = raw[base + 1 : base + 1 + stride].astype(np.int64)
        if ftype == 0:
            cur = line
        elif ftype == 2:  # Up
            cur = (line + prev) & 0xFF
        elif ftype in (1, 3, 4):  # Sub, Average, Paeth depend on the left neighbour: per byte
            cur = np.zeros(stride, dtype=np.int64)
            lv, pv = line.tolist(), prev.tolist()
            cv = [0] * stride
            for i in range(stride):
                left = cv[i - bpp] if i >= bpp else 0
                up = pv[i]
                if ftype == 1:
                    pred = left
                elif ftype == 3:
                    pred = (left + up) >> 1
                else:
                    ul = pv[i - bpp] if i >= bpp else 0
                    p = left + up - ul
                    pa, pb, pc = abs(p - left), abs(p - up), abs(p - ul)
                    pred = left if pa <= pb and pa <= pc else (up if pb <= pc else ul)
                cv[i] = (lv[i] + pred) & 0xFF
            cur = np.array(cv, dtype=np.int64)
        else:
            raise WorldError(f"{path}: bad PNG filter type {ftype} in row {y}")
        out[y] = cur.astype(np.uint8)
        prev = cur
    return out
