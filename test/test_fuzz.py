"""Property-based fuzzing (hypothesis) of every loader and message conversion, on a small fixed
budget: hostile mutations of valid inputs are loaded or refused with an InputError, never
another exception (issue 17).

A mutated input starts from a valid file or message text and takes a few edits of the kinds
that broke the loaders before (issue 17): a number replaced by thousands of digits, 1e308, NaN
or a value past an id limit; deep nesting; a YAML alias bomb or a Python tag; bytes that are not
UTF-8; truncation; flipped and deleted bytes.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import shutil
import struct
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from geometry_msgs.msg import PoseWithCovarianceStamped, TwistStamped
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from island_mapping.bag.reader import open_bag
from island_mapping.bag.writer import BagWriter
from island_mapping.cli.params import parse_assignments
from island_mapping.core.graph import GraphStore, TopoGraph
from island_mapping.logs.carmen import carmen_log, parse_carmen, pose_track
from island_mapping.logs.relations import parse_relations
from island_mapping.logs.uci_sonar import parse_sonar_ring
from island_msgs_py.conversions import (
    check_stamp,
    command_to_twist_stamped,
    odometry_to_pose,
    parameter_to_item,
    pose_with_covariance_stamped_to_pose2d,
    scan_to_arrays,
    string_msg_to_graph,
    time_to_ns,
    twist_stamped_to_command,
)
from island_msgs_py.errors import InputError
from island_msgs_py.inputs import load_json
from island_msgs_py.json_io import island_to_dict
from island_msgs_py.limits import MAX_EVENT_JSON_BYTES
from island_msgs_py.types import ControlStrategy
from island_sim.core.generate import parse_spec
from island_sim.core.hall_follower import parse_script
from island_sim.core.world import save_world
from island_sim.core.world_loader import load_world
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import Parameter, ParameterType
from sensor_msgs.msg import LaserScan
from std_msgs.msg import String

from island_msgs_py import json_io

FUZZ_EXAMPLES = int(os.environ.get("ISLANDS_FUZZ_EXAMPLES", "25"))
"""Examples per fuzz test: a small fixed budget in CI (raise it to search longer)."""

FUZZ = settings(max_examples=FUZZ_EXAMPLES, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                       HealthCheck.function_scoped_fixture])
"""Deterministic (derandomized: the same cases in every run) and within the budget."""

HOSTILE_TOKENS: tuple[bytes, ...] = (
    b"9" * 5000, b"-" + b"9" * 400, b"1e308", b"-1e308", b"1e400", b"nan", b"NaN", b"inf",
    b"-inf", b"-1", b"0", b"2147483648", b"9223372036854775808", b"18446744073709551616",
    b"[" * 3000, b"{\"a\":" * 3000, b"- " * 3000, b"true", b"null", b"\"\"", b"[]", b"{}",
    b"&a [*a, *a, *a, *a, *a, *a, *a, *a, *a, *a]", b"!!python/object/apply:os.system ['true']",
    b"\xff\xfe\x80", b"\x00", b"\r\n", b"\"" + b"x" * 5000 + b"\"", b"/etc/passwd", b"..",
)
_NUMBER = re.compile(rb"-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")


@st.composite
def mutated(draw: st.DrawFn, seed: bytes, max_edits: int = 3) -> bytes:
    """`seed` after 1..max_edits hostile edits."""
    data = bytearray(seed)
    for _ in range(draw(st.integers(1, max_edits))):
        op = draw(st.sampled_from(("number", "number", "insert", "flip", "truncate", "delete")))
        pos = draw(st.integers(0, max(0, len(data) - 1)))
        if op == "number":
            numbers = list(_NUMBER.finditer(bytes(data)))
            if numbers:
                m = numbers[draw(st.integers(0, len(numbers) - 1))]
                data[m.start():m.end()] = draw(st.sampled_from(HOSTILE_TOKENS))
                continue
            op = "insert"
        if op == "insert":
            data[pos:pos] = draw(st.sampled_from(HOSTILE_TOKENS))
        elif op == "flip" and data:
            data[pos] ^= 1 << draw(st.integers(0, 7))
        elif op == "truncate":
            del data[pos:]
        elif op == "delete":
            del data[pos:pos + draw(st.integers(1, 64))]
    return bytes(data)


def mutated_text(seed: str, max_edits: int = 3) -> st.SearchStrategy[str]:
    """Text mutations of `seed` (undecodable bytes replaced), for parsers that take lines."""
    return mutated(seed.encode(), max_edits).map(lambda b: b.decode("utf-8", "replace"))


# ============================================================================= loaders
# Each loader meets mutated versions of a valid file: it returns, or raises an InputError (its
# package's own type), never another exception.

EXAMPLE_GRAPH = Path(__file__).resolve().parents[1] / "bags" / "example_graph.json"


def _png(width: int, height: int, pixels: bytes) -> bytes:
    """A minimal 8-bit greyscale PNG (filter 0 on every row)."""
    def chunk(kind: bytes, body: bytes) -> bytes:
        return (struct.pack(">I", len(body)) + kind + body
                + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF))
    rows = b"".join(b"\x00" + pixels[y * width:(y + 1) * width] for y in range(height))
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(rows))
            + chunk(b"IEND", b""))


def _room(size: int) -> bytes:
    """Pixels of a free room (255) walled by occupied pixels (0)."""
    return bytes(255 if 0 < x < size - 1 and 0 < y < size - 1 else 0
                 for y in range(size) for x in range(size))


@pytest.fixture(scope="module")
def seeds(tmp_path_factory: pytest.TempPathFactory) -> dict[str, bytes]:
    """Valid files of every format a loader reads, made by the project's own writers."""
    d = tmp_path_factory.mktemp("seeds")
    world = load_world("t_junction")
    out = {s: save_world(world, d / f"w{s}").read_bytes() for s in (".yaml", ".json")}
    out[".pgm"] = b"P5\n12 12\n255\n" + _room(12)
    out[".png"] = _png(12, 12, _room(12))
    out["map.yaml"] = b"image: m.pgm\nresolution: 0.1\norigin: [0.0, 0.0, 0.0]\n"
    graph = TopoGraph.load_json(EXAMPLE_GRAPH)
    for suffix, path in graph.save_all(d / "g").items():
        out[f"graph.{suffix}"] = Path(path).read_bytes()
    with BagWriter(d / "bag") as w:
        for k in range(5):
            w.write("/cmd_vel", command_to_twist_stamped(0.1 * k, 0.0, k * 10**8))
    out["mcap"] = next((d / "bag").glob("*.mcap")).read_bytes()
    return out


def _world_case(tmp: Path, seed: bytes, suffix: str) -> Path:
    path = tmp / f"world{suffix}"
    path.write_bytes(seed)
    return path


@pytest.mark.parametrize("suffix", [".yaml", ".json", ".pgm", ".png"])
def test_fuzz_world_files(seeds: dict[str, bytes], tmp_path: Path, suffix: str) -> None:
    @FUZZ
    @given(data=mutated(seeds[suffix]))
    def case(data: bytes) -> None:
        path = _world_case(tmp_path, data, suffix)
        with contextlib.suppress(InputError):
            load_world(path, 0.1 if suffix in (".pgm", ".png") else None)

    case()


def test_fuzz_map_yaml(seeds: dict[str, bytes], tmp_path: Path) -> None:
    (tmp_path / "m.pgm").write_bytes(seeds[".pgm"])

    @FUZZ
    @given(data=mutated(seeds["map.yaml"]))
    def case(data: bytes) -> None:
        path = _world_case(tmp_path, data, ".yaml")
        with contextlib.suppress(InputError):
            load_world(path)

    case()


@pytest.mark.parametrize("suffix", ["json", "geojson", "graphml"])
def test_fuzz_graph_files(seeds: dict[str, bytes], tmp_path: Path, suffix: str) -> None:
    @FUZZ
    @given(data=mutated(seeds[f"graph.{suffix}"]))
    def case(data: bytes) -> None:
        path = tmp_path / f"graph.{suffix}"
        path.write_bytes(data)
        with contextlib.suppress(InputError):
            TopoGraph.load_any(path)

    case()


def test_fuzz_graph_store(tmp_path: Path) -> None:
    """A store whose database was damaged is refused (GraphStoreError), or reads as it was
    written: never a smaller graph and never another exception."""
    source = tmp_path / "source"
    graph = TopoGraph.load_json(EXAMPLE_GRAPH)
    store = GraphStore(source)
    for island in graph.islands():
        store.put_island(island)
    for edge in graph.edges():
        store.put_edge(edge)
    store.close()
    files = {p.name: p.read_bytes() for p in source.iterdir() if p.is_file()}
    db = next(name for name in files if name.endswith(".sqlite3"))
    counter = iter(range(10**6))

    @FUZZ
    @given(data=mutated(files[db], max_edits=2))
    def case(data: bytes) -> None:
        target = tmp_path / f"s{next(counter)}"
        target.mkdir()
        for name, content in files.items():
            (target / name).write_bytes(data if name == db else content)
        try:
            opened = GraphStore(target, read_only=True)
        except InputError:
            return
        try:
            assert len(opened.graph) == len(graph)
            assert opened.graph.num_edges == graph.num_edges
        finally:
            opened.close()
            shutil.rmtree(target)

    case()


def test_fuzz_bag(seeds: dict[str, bytes], tmp_path: Path) -> None:
    @FUZZ
    @given(data=mutated(seeds["mcap"]))
    def case(data: bytes) -> None:
        path = tmp_path / "bag.mcap"
        path.write_bytes(data)
        with contextlib.suppress(InputError):
            for m in open_bag(path).messages(None):
                m.deserialize()

    case()


LOG_SEEDS = {
    "carmen": (
        "ODOM 0 0 0 0 0 0 0.000246 pippo 0.000246\n"
        "FLASER 180 " + " ".join(["2.5"] * 180) + " 0.1 0.2 0.0 0.1 0.2 0.0 1.0 pippo 1.0\n"
        "ODOM 0.1 0 0.01 0 0 0 1.1 pippo 1.1\n"
        "FLASER 180 " + " ".join(["2.6"] * 180) + " 0.2 0.2 0.0 0.2 0.2 0.0 2.0 pippo 2.0\n"
    ),
    "carmen_rear_sonar": (  # a rear laser mounted off the centre, and a sonar ring
        "PARAM robot_rearlaser_offset 0.2 host 0\n"
        "PARAM robot_rearlaser_angular_offset 0.1 host 0\n"
        "ODOM 0 0 0 0 0 0 0.5 pippo 0.5\n"
        "RLASER 181 " + " ".join(["2.5"] * 181) + " 0.1 0.2 0.0 0.1 0.2 0.0 1.0 pippo 1.0\n"
        "SONAR 0.436 4 1.0 2.0 5.0 0.5 0.2 0 0 0 0.2 1.57 -0.2 0 3.14 0 -0.2 -1.57 1.2 p 1.2\n"
        "ODOM 0.1 0 0.01 0 0 0 1.5 pippo 1.5\n"
        "RLASER 181 " + " ".join(["2.6"] * 181) + " 0.2 0.2 0.0 0.2 0.2 0.0 2.0 pippo 2.0\n"
        "SONAR 0.436 4 1.1 2.1 5.0 0.6 0.2 0 0 0 0.2 1.57 -0.2 0 3.14 0 -0.2 -1.57 2.2 p 2.2\n"
    ),
    "relations": ("976052905.167303 976052911.885496 -0.056990 -0.128430 0.000000 0.000000 "
                  "0.000000 -1.682210\n" * 2),
    "uci": ("0.438,0.498,3.625,3.645,5.000,2.918,5.000,2.351,2.332,2.643,1.698,1.687,1.698,"
            "1.717,1.744,0.593,0.502,0.493,0.504,0.445,0.431,0.444,0.440,0.429,"
            "Slight-Right-Turn\n" * 2),
}


def _parse_log(kind: str, text: str) -> None:
    lines = text.splitlines(keepends=True)
    if kind.startswith("carmen"):
        records = parse_carmen(lines, "fuzz.log")
        for scans in (None, "SONAR"):  # the log's first laser, and its sonar ring
            chosen = records.with_scans(scans)
            carmen_log(chosen)
            pose_track(chosen)
    elif kind == "relations":
        parse_relations(lines, "fuzz.relations")
    else:
        parse_sonar_ring(lines, "fuzz.data")


@pytest.mark.parametrize("kind", sorted(LOG_SEEDS))
def test_fuzz_logs(kind: str) -> None:
    @FUZZ
    @given(text=mutated_text(LOG_SEEDS[kind]))
    def case(text: str) -> None:
        with contextlib.suppress(InputError):
            _parse_log(kind, text)

    case()


def test_fuzz_cli_values() -> None:
    """--builder-param values and world specs typed on the command line."""
    @FUZZ
    @given(text=st.one_of(st.text(max_size=40),
                          mutated_text("gen:office:seed=3,scale=1.0"),
                          mutated_text("builder.e_min_m=0.5")))
    def case(text: str) -> None:
        with contextlib.suppress(InputError):
            parse_assignments([text], "--builder-param")
        with contextlib.suppress(InputError):
            parse_spec(text)

    case()


# ============================================================================= messages
# Each conversion a node applies to a received message meets arbitrary field values (NaN, inf,
# huge, negative) or mutated JSON text: a value, or an InputError, never another exception.

FLOATS = st.floats(allow_nan=True, allow_infinity=True, width=64)
SEC = st.integers(-(2**31), 2**31 - 1)
NANOSEC = st.integers(0, 2**32 - 1)


def _stamp(msg: Any, sec: int, nanosec: int) -> None:
    msg.header.stamp.sec = sec
    msg.header.stamp.nanosec = nanosec


def test_fuzz_laser_scan() -> None:
    @FUZZ
    @given(ranges=st.lists(FLOATS.map(lambda v: float(np.float32(v)) if abs(v) < 3e38 else v)
                           .filter(lambda v: not math.isfinite(v) or abs(v) < 3e38),
                           max_size=64),
           angles=st.tuples(FLOATS, FLOATS, FLOATS, FLOATS), sec=SEC, nanosec=NANOSEC)
    def case(ranges: list[float], angles: tuple[float, ...], sec: int, nanosec: int) -> None:
        msg = LaserScan()
        msg.angle_min, msg.angle_increment, msg.range_min, msg.range_max = (
            float(np.float32(a)) if math.isfinite(a) and abs(a) < 3e38 else float(a)
            for a in angles)
        msg.ranges = ranges
        _stamp(msg, sec, nanosec)
        with contextlib.suppress(InputError):
            r, a = scan_to_arrays(msg)
            assert r.shape == a.shape == (len(ranges),)
            check_stamp(time_to_ns(msg.header.stamp), 10**9, "/sonar/scan")

    case()


def test_fuzz_odometry_and_pose_messages() -> None:
    @FUZZ
    @given(values=st.lists(FLOATS, min_size=7, max_size=7),
           cov=st.lists(FLOATS, min_size=36, max_size=36), sec=SEC, nanosec=NANOSEC,
           frame=st.text(max_size=300))
    def case(values: list[float], cov: list[float], sec: int, nanosec: int, frame: str) -> None:
        odom = Odometry()
        p, q = odom.pose.pose.position, odom.pose.pose.orientation
        p.x, p.y, p.z, q.x, q.y, q.z, q.w = values
        odom.pose.covariance = cov
        _stamp(odom, sec, nanosec)
        with contextlib.suppress(InputError):
            pose, _, t_ns = odometry_to_pose(odom)
            assert math.isfinite(pose.x) and math.isfinite(pose.theta)
            check_stamp(t_ns, 10**9, "/odom")
        fix = PoseWithCovarianceStamped()
        fix.pose.pose.position, fix.pose.pose.orientation = p, q
        fix.pose.covariance = cov
        fix.header.frame_id = frame
        with contextlib.suppress(InputError):
            pose_with_covariance_stamped_to_pose2d(fix)

    case()


def test_fuzz_twist_messages() -> None:
    @FUZZ
    @given(v=FLOATS, w=FLOATS, sec=SEC, nanosec=NANOSEC)
    def case(v: float, w: float, sec: int, nanosec: int) -> None:
        msg = TwistStamped()
        msg.twist.linear.x, msg.twist.angular.z = v, w
        _stamp(msg, sec, nanosec)
        with contextlib.suppress(InputError):
            got_v, got_w, t_ns = twist_stamped_to_command(msg)
            assert math.isfinite(got_v) and math.isfinite(got_w)
            check_stamp(t_ns, 10**9, "/cmd_vel")

    case()


def _example_graph_text() -> str:
    return TopoGraph.load_json(EXAMPLE_GRAPH).to_json()


def _one_island_text() -> str:
    return json.dumps(island_to_dict(TopoGraph.load_json(EXAMPLE_GRAPH).islands()[0]))


def _event_text() -> str:
    return json.dumps({"kind": "island_accepted", "island": json.loads(_one_island_text()),
                       "anchor_odom": {"x": 1.0, "y": 2.0, "theta": 0.5}})


def _decode_event(text: str) -> None:
    """What island_localizer_node does with /island_builder/events."""
    d = load_json(text, "/island_builder/events", max_bytes=MAX_EVENT_JSON_BYTES)
    if isinstance(d, dict) and d.get("kind") == "island_accepted":
        json_io.island_from_dict(d.get("island"), "event.island")
        json_io.pose_from_dict(d.get("anchor_odom"), "event.anchor_odom")


def test_fuzz_json_messages() -> None:
    """/topo_graph/graph, /topo_graph/add items and /island_builder/events."""
    @FUZZ
    @given(graph=mutated_text(_example_graph_text()), item=mutated_text(_one_island_text()),
           name=st.sampled_from(["island", "edge", "exit", "other"]),
           event=mutated_text(_event_text()))
    def case(graph: str, item: str, name: str, event: str) -> None:
        with contextlib.suppress(InputError):
            string_msg_to_graph(String(data=graph))
        param = Parameter(name=name)
        param.value.type = ParameterType.PARAMETER_STRING
        param.value.string_value = item
        with contextlib.suppress(InputError):
            parameter_to_item(param)
        with contextlib.suppress(InputError):
            _decode_event(event)

    case()


def test_fuzz_strategy_and_script_text() -> None:
    """/hall_follower/strategy (latched) and the follower's turn script."""
    @FUZZ
    @given(text=st.one_of(st.text(max_size=80), mutated_text("Go 125, Rot 270, Go 652"),
                          mutated_text("left, straight, right, back")))
    def case(text: str) -> None:
        with contextlib.suppress(InputError):
            ControlStrategy.parse(text)
        with contextlib.suppress(InputError):
            parse_script(text)

    case()
