"""nav_msgs/Odometry (read and written) and sensor_msgs/LaserScan (read) as CDR bytes, with
`struct` alone (no ROS).

Why: in a lockstep run (`islands explore`) the simulator publishes /odom and /ground_truth at
every physics step and eight subscriptions read them. rclpy turns each delivery into a tree of
nine Python message objects (every field checked by its generated `__init__`), about 65 us a
delivery against about 11 us for the raw bytes (`bench/bench_deliveries.py`), and the nodes
read only the stamp, x, y, the yaw and nine covariance entries. These functions read exactly
those from the serialized message and write the whole message the simulator publishes, with the
same values rclpy's own (de)serialization gives (tests compare them field by field). The
scan, 10 times a simulated second to four nodes, is read the same way for the same reason.

Only plain CDR (XCDR1, little or big endian: encapsulation 0x0000 / 0x0001), which rmw
implementations use for ROS 2 messages, is read here; other encapsulations raise
`CdrUnsupportedError` so the caller can fall back to rclpy's deserialization. Offsets are aligned
relative to the end of the 4-byte encapsulation header, as CDR requires.
"""

from __future__ import annotations

import math
import struct
from functools import lru_cache
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from island_msgs_py.errors import InputError

NS_PER_S = 1_000_000_000
ENCAPSULATION_LE = b"\x00\x01\x00\x00"
"""CDR, little endian, no options: what this module writes."""
_HEADER_BYTES = 4  # encapsulation kind (2 bytes) and options (2 bytes)
_KINDS = {b"\x00\x00": ">", b"\x00\x01": "<"}  # plain CDR, big / little endian
_ODOM_DOUBLES = 3 + 4 + 36 + 6 + 36  # position, orientation, covariance, twist, covariance
_COV_FIRST = 7  # index of pose.covariance[0] among the doubles
_TWIST_FIRST = _COV_FIRST + 36  # index of twist.twist.linear.x among the doubles
_COV_3X3 = (0, 1, 5, 6, 7, 11, 30, 31, 35)  # x, y, yaw rows/cols of the row-major 6x6
_MAX_STAMP_NS = (1 << 31) * NS_PER_S  # builtin_interfaces/Time.sec is an int32
_MAX_STRING_BYTES = 1 << 16  # a frame id longer than this is not a frame id [bytes]


class CdrError(InputError):
    """The bytes are not a well-formed message of the expected type (the text says why)."""


class CdrUnsupportedError(CdrError):
    """An encapsulation other than plain CDR: read it with rclpy instead."""


class OdometryFields(NamedTuple):
    """What the nodes read of an Odometry message: the header stamp [ns], the pose's x, y [m],
    its quaternion (x, y, z, w), the (x, y, yaw) rows/cols of its 6x6 covariance, row-major
    [m^2, m rad, rad^2], and the twist's linear.x [m/s] and angular.z [rad/s]."""

    stamp_ns: int
    x: float
    y: float
    quaternion: tuple[float, float, float, float]
    cov3x3: tuple[float, ...]
    v: float
    w: float


def _doubles_read(order: str) -> struct.Struct:
    """The pose and twist doubles of an Odometry that the nodes read (x, y, the quaternion, the
    3x3 covariance, linear.x, angular.z), the others skipped as pad bytes: one unpack call."""
    wanted = {0, 1, 3, 4, 5, 6, *(_COV_FIRST + i for i in _COV_3X3), _TWIST_FIRST,
              _TWIST_FIRST + 5}
    return struct.Struct(order + "".join("d" if i in wanted else "8x"
                                         for i in range(_ODOM_DOUBLES)))


_READ = {order: _doubles_read(order) for order in ("<", ">")}
_WRITE = struct.Struct(f"<{_ODOM_DOUBLES}d")


def _align(offset: int, size: int) -> int:
    return (offset + size - 1) // size * size


def _byte_order(data: bytes, what: str) -> str:
    if len(data) < _HEADER_BYTES:
        raise CdrError(f"{what}: {len(data)} bytes cannot hold a CDR header")
    order = _KINDS.get(bytes(data[:2]))
    if order is None:
        raise CdrUnsupportedError(
            f"{what}: encapsulation 0x{bytes(data[:2]).hex()} is not plain CDR")
    return order


def _skip_string(data: bytes, order: str, offset: int, what: str) -> int:
    """The offset (relative to the body) just past the string at `offset`."""
    offset = _align(offset, 4)
    start = _HEADER_BYTES + offset
    if start + 4 > len(data):
        raise CdrError(f"{what}: truncated at a string length ({len(data)} bytes)")
    (n,) = struct.unpack_from(order + "I", data, start)
    if n > _MAX_STRING_BYTES or start + 4 + n > len(data):
        raise CdrError(f"{what}: a string of {n} bytes does not fit in {len(data)} bytes")
    return offset + 4 + n


def read_odometry(data: bytes) -> OdometryFields:
    """The stamp, position, quaternion and 3x3 covariance of a serialized nav_msgs/Odometry;
    CdrError if the bytes are too short for one, CdrUnsupportedError for another encapsulation."""
    order = _byte_order(data, "odometry")
    if len(data) < _HEADER_BYTES + 8:
        raise CdrError(f"odometry: {len(data)} bytes cannot hold a header stamp")
    sec, nanosec = struct.unpack_from(order + "iI", data, _HEADER_BYTES)
    offset = _skip_string(data, order, 8, "odometry header.frame_id")
    offset = _skip_string(data, order, offset, "odometry child_frame_id")
    start = _HEADER_BYTES + _align(offset, 8)
    if start + 8 * _ODOM_DOUBLES > len(data):
        raise CdrError(f"odometry: truncated pose or twist ({len(data)} bytes)")
    v = _READ[order].unpack_from(data, start)  # x, y, quaternion (4), covariance (9), v, w
    return OdometryFields(sec * NS_PER_S + nanosec, v[0], v[1], v[2:6], v[6:15], v[15], v[16])


@lru_cache(maxsize=16)
def _frames_block(frame_id: str, child_frame_id: str) -> tuple[bytes, int]:
    """The two strings of the header as little-endian CDR from body offset 8, padded up to the
    8-byte alignment of the pose; and the body offset where the pose starts."""
    out = bytearray()
    offset = 8
    for text in (frame_id, child_frame_id):
        pad = _align(offset, 4) - offset
        raw = text.encode("utf-8") + b"\x00"
        out += b"\x00" * pad + struct.pack("<I", len(raw)) + raw
        offset += pad + 4 + len(raw)
    pad = _align(offset, 8) - offset
    out += b"\x00" * pad
    return bytes(out), offset + pad


def write_odometry(stamp_ns: int, frame_id: str, child_frame_id: str, x_m: float, y_m: float,
                   theta_rad: float, cov3x3: tuple[float, ...] | None, v_mps: float,
                   w_radps: float) -> bytes:
    """A serialized nav_msgs/Odometry (little-endian CDR) of a planar pose: position (x, y, 0),
    a rotation of theta about z, `cov3x3` (row-major (x, y, yaw) 3x3, or None: zeros) at
    rows/cols 0, 1, 5 of the pose covariance, twist linear.x = v, angular.z = w, zeros
    elsewhere: the message `island_msgs_py.conversions.fill_odometry` fills."""
    if not 0 <= stamp_ns < _MAX_STAMP_NS:
        raise CdrError(f"odometry stamp must be in [0, 2^31) s, got {stamp_ns} ns")
    frames, _ = _frames_block(frame_id, child_frame_id)
    cov = [0.0] * 36
    if cov3x3 is not None:
        if len(cov3x3) != 9:
            raise CdrError(f"odometry covariance must have 9 entries, got {len(cov3x3)}")
        for i, c in zip(_COV_3X3, cov3x3, strict=True):
            cov[i] = float(c)
    half = theta_rad / 2.0
    doubles = (float(x_m), float(y_m), 0.0, 0.0, 0.0, math.sin(half), math.cos(half), *cov,
               float(v_mps), 0.0, 0.0, 0.0, 0.0, float(w_radps), *([0.0] * 36))
    return b"".join((ENCAPSULATION_LE,
                     struct.pack("<iI", stamp_ns // NS_PER_S, stamp_ns % NS_PER_S), frames,
                     _WRITE.pack(*doubles)))


class ScanFields(NamedTuple):
    """What the nodes read of a LaserScan: the header stamp [ns], angle_min and angle_increment
    [rad], range_min and range_max [m] (float32 values, as rclpy gives them) and the ranges [m]
    (float32; `n_ranges` of them, None when more than the caller's limit: not read)."""

    stamp_ns: int
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    n_ranges: int
    ranges: npt.NDArray[np.float32] | None


_FLOAT32 = {"<": np.dtype("<f4"), ">": np.dtype(">f4")}
_SCAN_FLOATS = 7  # angle_min, angle_max, angle_increment, time_increment, scan_time, range_min,
# range_max


def write_scan(stamp_ns: int, frame_id: str, floats: tuple[float, ...],
               ranges: npt.NDArray[np.float64]) -> bytes:
    """A serialized sensor_msgs/LaserScan (little-endian CDR) with the seven float32 fields
    `floats` (angle_min, angle_max, angle_increment, time_increment, scan_time, range_min,
    range_max), `ranges` as float32 and no intensities."""
    if not 0 <= stamp_ns < _MAX_STAMP_NS:
        raise CdrError(f"scan stamp must be in [0, 2^31) s, got {stamp_ns} ns")
    if len(floats) != _SCAN_FLOATS:
        raise CdrError(f"scan: {len(floats)} float fields, expected {_SCAN_FLOATS}")
    raw = frame_id.encode("utf-8") + b"\x00"
    pad = b"\x00" * (_align(12 + len(raw), 4) - 12 - len(raw))  # the floats are 4-aligned
    return b"".join((ENCAPSULATION_LE,
                     struct.pack("<iII", stamp_ns // NS_PER_S, stamp_ns % NS_PER_S, len(raw)),
                     raw, pad, struct.pack(f"<{_SCAN_FLOATS}fI", *floats, ranges.size),
                     ranges.astype("<f4").tobytes(), struct.pack("<I", 0)))


def read_scan(data: bytes, max_ranges: int) -> ScanFields:
    """The stamp, angles, limits and ranges of a serialized sensor_msgs/LaserScan (the ranges
    only if there are at most `max_ranges`); CdrError / CdrUnsupportedError as read_odometry."""
    order = _byte_order(data, "scan")
    if len(data) < _HEADER_BYTES + 8:
        raise CdrError(f"scan: {len(data)} bytes cannot hold a header stamp")
    sec, nanosec = struct.unpack_from(order + "iI", data, _HEADER_BYTES)
    offset = _align(_skip_string(data, order, 8, "scan header.frame_id"), 4)
    start = _HEADER_BYTES + offset
    if start + 4 * (_SCAN_FLOATS + 1) > len(data):
        raise CdrError(f"scan: truncated before the ranges ({len(data)} bytes)")
    f = struct.unpack_from(f"{order}{_SCAN_FLOATS}fI", data, start)
    n, first = f[_SCAN_FLOATS], start + 4 * (_SCAN_FLOATS + 1)
    ranges = None
    if n <= max_ranges:
        end = first + 4 * n
        if end + 4 > len(data):
            raise CdrError(f"scan: {n} ranges do not fit in {len(data)} bytes")
        (k,) = struct.unpack_from(order + "I", data, end)
        if end + 4 + 4 * k > len(data):  # the intensities: the message must be whole
            raise CdrError(f"scan: {k} intensities do not fit in {len(data)} bytes")
        ranges = np.frombuffer(data, dtype=_FLOAT32[order], count=n, offset=first)
    return ScanFields(sec * NS_PER_S + nanosec, f[0], f[2], f[5], f[6], n, ranges)
