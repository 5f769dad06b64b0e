"""The ONE place converting shared map types <-> ROS 2 messages (standard types only).

- Pose2D <-> geometry_msgs Pose / PoseStamped / PoseWithCovarianceStamped (yaw as a quaternion
  about z; the 3x3 (x, y, theta) covariance sits at rows/cols 0, 1, 5 of the 6x6 one).
- The graph -> visualization_msgs/MarkerArray: per island a LINE_LIST of its model and a TEXT
  label, per exit a short ARROW from the island origin coloured by the exit's state, per edge an
  ARROW from source to target with its control strategy as TEXT. Islands
  share no metric frame, so a *display layout* (a Pose2D per island, e.g. from
  `TopoGraph.display_layout()`, or the simulator's truth when known) places them for viewing
  only. By default everything is drawn in one display frame (RViz fixed frame
  `islands_layout`), each island's model placed by its layout pose; with
  `in_island_frames=True` each island's model and label are stamped in its own frame
  `island_<id>` with an identity pose (for setups that provide TF for those frames).
- The graph <-> std_msgs/String holding the versioned JSON document (island_msgs_py.json_io).
- Islands/edges/exit updates <-> rcl_interfaces/Parameter items of the graph server's
  `/topo_graph/add` (a SetParameters request: name `island`, `edge` or `exit`, a JSON string
  value).
- A planned route -> nav_msgs/Path of the island origins (identity pose in each island frame).
- Sensor and drive messages <-> arrays, for every node that reads or drives a robot:
  builtin_interfaces/Time <-> integer nanoseconds (exact stamp pairing), sensor_msgs/LaserScan
  <-> (ranges, bearings), nav_msgs/Odometry <-> (Pose2D, 3x3 covariance, stamp),
  geometry_msgs/Twist(Stamped) <-> (v, w[, stamp]). A malformed message raises
  ConversionError naming the field.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence

import numpy as np
import numpy.typing as npt
from builtin_interfaces.msg import Time
from geometry_msgs.msg import (
    Point,
    Pose,
    PoseStamped,
    PoseWithCovariance,
    PoseWithCovarianceStamped,
    Quaternion,
    Twist,
    TwistStamped,
)
from nav_msgs.msg import Odometry, Path
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from sensor_msgs.msg import LaserScan
from std_msgs.msg import ColorRGBA, Header, String
from visualization_msgs.msg import Marker, MarkerArray

from island_msgs_py import json_io
from island_msgs_py.errors import InputError
from island_msgs_py.limits import MAX_SCAN_RANGES, MAX_STAMP_AHEAD_S
from island_msgs_py.types import (
    Edge,
    ExitState,
    ExitUpdate,
    FloatArray,
    Island,
    IslandTypeError,
    NewExit,
    Pose2D,
)

DISPLAY_FRAME = "islands_layout"  # display-only frame of the marker layout
ISLAND_PARAM = "island"
EDGE_PARAM = "edge"
EXIT_PARAM = "exit"
NEW_EXIT_PARAM = "new_exit"
ITEM_PARAMS = (ISLAND_PARAM, EDGE_PARAM, EXIT_PARAM, NEW_EXIT_PARAM)
NS_PER_S = 1_000_000_000
_COV_INDEX = (0, 1, 5)  # x, y, yaw rows/cols of ROS's 6x6 pose covariance
_COV_ROWS, _COV_COLS = np.ix_(_COV_INDEX, _COV_INDEX)
# Evenly spaced bearings may differ from a perfect grid by this much (float32 fields) [rad].
_ANGLE_GRID_TOL_RAD = 1e-4
_LINE_WIDTH_M = 0.08
_TEXT_HEIGHT_M = 0.5
_GRID_SPACING_M = 15.0  # fallback layout spacing when nothing better is known
_MODEL_COLOUR = ColorRGBA(r=0.1, g=0.45, b=0.9, a=1.0)
_EDGE_COLOUR = ColorRGBA(r=0.9, g=0.5, b=0.1, a=0.9)
_TEXT_COLOUR = ColorRGBA(r=0.1, g=0.1, b=0.1, a=1.0)
EXIT_ARROW_M = 1.0  # length of an exit's arrow from the island origin [m]
EXIT_COLOURS = {  # an exit's arrow by its state: still to explore, done, not worth it
    ExitState.UNEXPLORED: ColorRGBA(r=0.95, g=0.75, b=0.0, a=1.0),
    ExitState.EXPLORED: ColorRGBA(r=0.15, g=0.7, b=0.2, a=1.0),
    ExitState.BLOCKED: ColorRGBA(r=0.85, g=0.1, b=0.1, a=1.0),
}


class ConversionError(InputError):
    """A message (or value for one) is malformed; the message says which field and why."""


# ----------------------------------------------------------------------------- poses


def yaw_to_quaternion(theta_rad: float) -> Quaternion:
    """A rotation of theta [rad] about z."""
    return Quaternion(x=0.0, y=0.0, z=math.sin(theta_rad / 2.0), w=math.cos(theta_rad / 2.0))


def quaternion_to_yaw(q: Quaternion) -> float:
    """Yaw [rad] in (-pi, pi] of a quaternion (normalized first; roll/pitch are ignored)."""
    return quaternion_components_to_yaw(q.x, q.y, q.z, q.w)


def quaternion_components_to_yaw(qx: float, qy: float, qz: float, qw: float) -> float:
    """quaternion_to_yaw of the components (x, y, z, w) [-]."""
    if not (math.isfinite(qx) and math.isfinite(qy) and math.isfinite(qz)
            and math.isfinite(qw)):
        raise IslandTypeError(
            f"quaternion has a NaN or infinite component: {(qx, qy, qz, qw)}")
    norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    if norm < 1e-9:
        raise IslandTypeError("quaternion has zero length")
    x, y, z, w = qx / norm, qy / norm, qz / norm, qw / norm
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return math.pi if yaw == -math.pi else yaw


def pose2d_to_pose(p: Pose2D) -> Pose:
    return Pose(position=Point(x=float(p.x), y=float(p.y), z=0.0),
                orientation=yaw_to_quaternion(p.theta))


def pose_to_pose2d(msg: Pose) -> Pose2D:
    """x, y [m] and yaw [rad]; raises IslandTypeError on NaN or a zero quaternion."""
    return Pose2D(float(msg.position.x), float(msg.position.y), quaternion_to_yaw(msg.orientation))


def pose2d_to_pose_stamped(p: Pose2D, frame_id: str, stamp: Time | None = None) -> PoseStamped:
    header = Header(frame_id=frame_id, stamp=stamp or Time())
    return PoseStamped(header=header, pose=pose2d_to_pose(p))


def pose2d_to_pose_with_covariance_stamped(
    p: Pose2D, frame_id: str, cov_xyt: np.ndarray | None = None, stamp: Time | None = None
) -> PoseWithCovarianceStamped:
    """`cov_xyt`: 3x3 covariance of (x [m], y [m], theta [rad]); unknown entries are 0."""
    cov6 = np.zeros((6, 6))
    if cov_xyt is not None:
        c = np.asarray(cov_xyt, dtype=np.float64)
        if c.shape != (3, 3) or not np.all(np.isfinite(c)):
            raise IslandTypeError(f"covariance: expected a finite 3x3 array, got shape {c.shape}")
        cov6[np.ix_(_COV_INDEX, _COV_INDEX)] = c
    return PoseWithCovarianceStamped(
        header=Header(frame_id=frame_id, stamp=stamp or Time()),
        pose=PoseWithCovariance(pose=pose2d_to_pose(p), covariance=cov6.reshape(-1).tolist()),
    )


def pose_with_covariance_stamped_to_pose2d(
    msg: PoseWithCovarianceStamped,
) -> tuple[Pose2D, np.ndarray, str]:
    """(pose, 3x3 covariance of x, y, theta, frame id)."""
    cov6 = np.asarray(msg.pose.covariance, dtype=np.float64).reshape(6, 6)
    return pose_to_pose2d(msg.pose.pose), cov6[np.ix_(_COV_INDEX, _COV_INDEX)].copy(), \
        msg.header.frame_id


# ----------------------------------------------------------------------------- graph as JSON


def graph_to_string_msg(islands: Iterable[Island], edges: Iterable[Edge]) -> String:
    return String(data=json_io.graph_to_json(islands, edges))


def string_msg_to_graph(msg: String) -> tuple[list[Island], list[Edge]]:
    """Validated islands and edges; raises json_io.GraphFormatError naming the bad field."""
    return json_io.graph_from_json(msg.data)


def island_to_parameter(island: Island) -> Parameter:
    return Parameter(name=ISLAND_PARAM, value=ParameterValue(
        type=ParameterType.PARAMETER_STRING, string_value=json_io.island_to_json(island)))


def edge_to_parameter(edge: Edge) -> Parameter:
    return Parameter(name=EDGE_PARAM, value=ParameterValue(
        type=ParameterType.PARAMETER_STRING, string_value=json_io.edge_to_json(edge)))


def exit_update_to_parameter(update: ExitUpdate) -> Parameter:
    return Parameter(name=EXIT_PARAM, value=ParameterValue(
        type=ParameterType.PARAMETER_STRING, string_value=json_io.exit_update_to_json(update)))


def new_exit_to_parameter(item: NewExit) -> Parameter:
    return Parameter(name=NEW_EXIT_PARAM, value=ParameterValue(
        type=ParameterType.PARAMETER_STRING, string_value=json_io.new_exit_to_json(item)))


def parameter_to_item(param: Parameter, path: str = "parameter"
                      ) -> Island | Edge | ExitUpdate | NewExit:
    """Decode one `/topo_graph/add` item; raises json_io.GraphFormatError when malformed."""
    if param.name not in ITEM_PARAMS:
        raise json_io.GraphFormatError(
            f"{path}.name", f"expected {ISLAND_PARAM!r}, {EDGE_PARAM!r}, {EXIT_PARAM!r} or "
            f"{NEW_EXIT_PARAM!r}, got {param.name[:40]!r}")
    if param.value.type != ParameterType.PARAMETER_STRING:
        raise json_io.GraphFormatError(
            f"{path}.value", f"expected a string (type {ParameterType.PARAMETER_STRING}) holding "
            f"JSON, got parameter type {param.value.type}")
    if param.name == ISLAND_PARAM:
        return json_io.island_from_json(param.value.string_value, param.name)
    if param.name == EXIT_PARAM:
        return json_io.exit_update_from_json(param.value.string_value, param.name)
    if param.name == NEW_EXIT_PARAM:
        return json_io.new_exit_from_json(param.value.string_value, param.name)
    return json_io.edge_from_json(param.value.string_value, param.name)


# ----------------------------------------------------------------------------- routes


def route_to_path(route: Sequence[Island], stamp: Time | None = None) -> Path:
    """The island origins in route order: identity pose stamped in each island's own frame."""
    st = stamp or Time()
    origin = Pose2D(0.0, 0.0, 0.0)
    poses = [pose2d_to_pose_stamped(origin, i.frame_id, st) for i in route]
    frame = route[0].frame_id if route else ""
    return Path(header=Header(frame_id=frame, stamp=st), poses=poses)


def path_to_island_frames(path: Path) -> list[str]:
    return [p.header.frame_id for p in path.poses]


# ----------------------------------------------------------------------------- markers


def grid_layout(islands: Sequence[Island], spacing_m: float = _GRID_SPACING_M) -> dict[int, Pose2D]:
    """Fallback display layout: the truth when every island has it, else a square grid."""
    if islands and all(i.origin_truth is not None for i in islands):
        return {i.id: i.origin_truth for i in islands if i.origin_truth is not None}
    side = max(1, math.ceil(math.sqrt(len(islands))))
    return {isl.id: Pose2D((k % side) * spacing_m, (k // side) * spacing_m, 0.0)
            for k, isl in enumerate(sorted(islands, key=lambda i: i.id))}


def _marker(header: Header, ns: str, mid: int, mtype: int, pose: Pose2D) -> Marker:
    m = Marker(header=header, ns=ns, id=mid, type=mtype, action=Marker.ADD)
    m.pose = pose2d_to_pose(pose)
    return m


def _island_markers(
    i: Island, header: Header, pose: Pose2D
) -> list[Marker]:
    """The model (LINE_LIST) and the label (TEXT) of one island."""
    m = _marker(header, "island_models", i.id, Marker.LINE_LIST, pose)
    m.scale.x = _LINE_WIDTH_M
    m.color = _MODEL_COLOUR
    ends = i.model.segments.reshape(-1, 2)
    m.points = [Point(x=float(x), y=float(y), z=0.0) for x, y in ends]
    t = _marker(header, "island_labels", i.id, Marker.TEXT_VIEW_FACING, pose)
    t.pose.position.z = 0.5
    t.scale.z = _TEXT_HEIGHT_M
    t.color = _TEXT_COLOUR
    t.text = f"{i.frame_id} ({i.model_type.value}, R={i.r:.2f})"
    return [m, t]


def _exit_markers(i: Island, header: Header, pose: Pose2D, first_id: int) -> list[Marker]:
    """Per exit an ARROW of EXIT_ARROW_M from the island origin along its heading, coloured by
    its state (ids first_id, first_id + 1, ...; namespace `exits`)."""
    out = []
    for k, e in enumerate(i.exits):
        m = _marker(header, "exits", first_id + k, Marker.ARROW, pose)
        tip = (EXIT_ARROW_M * math.cos(e.heading_rad), EXIT_ARROW_M * math.sin(e.heading_rad))
        m.points = [Point(x=0.0, y=0.0, z=0.05), Point(x=tip[0], y=tip[1], z=0.05)]
        m.scale.x, m.scale.y, m.scale.z = 0.06, 0.18, 0.25  # shaft, head diameter, head length
        m.color = EXIT_COLOURS[e.state]
        out.append(m)
    return out


def _edge_markers(k: int, e: Edge, a: Pose2D, b: Pose2D, display: Header) -> list[Marker]:
    """The ARROW source -> target and its strategy (TEXT) of edge number k."""
    m = Marker(header=display, ns="edges", id=k, type=Marker.ARROW, action=Marker.ADD)
    m.pose.orientation.w = 1.0
    m.points = [Point(x=a.x, y=a.y, z=0.0), Point(x=b.x, y=b.y, z=0.0)]
    m.scale.x, m.scale.y, m.scale.z = 0.1, 0.3, 0.4  # shaft, head diameter, head length [m]
    m.color = _EDGE_COLOUR
    t = Marker(header=display, ns="edge_labels", id=k, type=Marker.TEXT_VIEW_FACING,
               action=Marker.ADD)
    t.pose = pose2d_to_pose(Pose2D((a.x + b.x) / 2, (a.y + b.y) / 2, 0.0))
    t.pose.position.z = 0.3
    t.scale.z = _TEXT_HEIGHT_M * 0.8
    t.color = _EDGE_COLOUR
    t.text = f"{e.source}->{e.target}: {e.strategy}" if e.strategy.steps else \
        f"{e.source}->{e.target}"
    return [m, t]


def graph_to_marker_array(
    islands: Iterable[Island],
    edges: Iterable[Edge],
    layout: Mapping[int, Pose2D] | None = None,
    display_frame: str = DISPLAY_FRAME,
    in_island_frames: bool = False,
    stamp: Time | None = None,
) -> MarkerArray:
    """Markers for viewers; the first one is DELETEALL so removed islands disappear.

    Namespaces: `island_models` (LINE_LIST, id = island id), `island_labels` (TEXT),
    `exits` (ARROW from the island origin along the exit's heading, coloured by its state:
    EXIT_COLOURS), `edges` (ARROW source -> target in the display frame), `edge_labels`
    (TEXT: strategy).
    """
    isl = sorted(islands, key=lambda i: i.id)
    lay = dict(layout) if layout is not None else grid_layout(isl)
    missing = [i.id for i in isl if i.id not in lay]
    if missing:
        raise IslandTypeError(f"display layout has no pose for islands {missing[:5]}")
    st = stamp or Time()
    display = Header(frame_id=display_frame, stamp=st)
    out = [Marker(header=display, ns="", id=0, action=Marker.DELETEALL)]
    identity = Pose2D(0.0, 0.0, 0.0)
    exit_markers: list[Marker] = []
    for i in isl:
        if in_island_frames:
            header, pose = Header(frame_id=i.frame_id, stamp=st), identity
        else:
            header, pose = display, lay[i.id]
        out += _island_markers(i, header, pose)
        exit_markers += _exit_markers(i, header, pose, len(exit_markers))
    out += exit_markers
    for k, e in enumerate(sorted(edges, key=lambda e: (e.source, e.target))):
        if e.source not in lay or e.target not in lay:
            raise IslandTypeError(f"edge {e.source}->{e.target}: island missing from the layout")
        out += _edge_markers(k, e, lay[e.source], lay[e.target], display)
    return MarkerArray(markers=out)


def marker_array_to_models(msg: MarkerArray) -> dict[int, np.ndarray]:
    """Island id -> (N, 4) model segments [m] in the island frame, read back from the markers."""
    out: dict[int, np.ndarray] = {}
    for m in msg.markers:
        if m.ns == "island_models" and m.type == Marker.LINE_LIST and m.action == Marker.ADD:
            pts = np.array([[p.x, p.y] for p in m.points], dtype=np.float64).reshape(-1, 4)
            out[int(m.id)] = pts
    return out


# ----------------------------------------------------------------------------- time


def ns_to_time(t_ns: int) -> Time:
    """builtin_interfaces/Time of `t_ns` nanoseconds (>= 0)."""
    if t_ns < 0:
        raise ConversionError(f"stamp must be >= 0 ns, got {t_ns}")
    return Time(sec=int(t_ns // NS_PER_S), nanosec=int(t_ns % NS_PER_S))


def time_to_ns(t: Time) -> int:
    """Nanoseconds of a builtin_interfaces/Time."""
    return int(t.sec) * NS_PER_S + int(t.nanosec)


def check_stamp(t_ns: int, now_ns: int, topic: str,
                max_ahead_s: float = MAX_STAMP_AHEAD_S) -> None:
    """Refuse (ConversionError naming `topic`) a stamp more than `max_ahead_s` ahead of the
    receiving node's clock `now_ns`: one message stamped 2^31 - 1 s would make every later one
    look old. A clock that has not started (`now_ns` <= 0: sim time before its first /clock)
    cannot judge and takes any stamp."""
    if now_ns > 0 and t_ns - now_ns > max_ahead_s * NS_PER_S:
        raise ConversionError(
            f"{topic}: header.stamp {t_ns / NS_PER_S:.9g} s is {(t_ns - now_ns) / NS_PER_S:.6g} s "
            f"ahead of the node's clock (the limit is {max_ahead_s:g} s)")


# ----------------------------------------------------------------------------- LaserScan


def arrays_to_scan(
    ranges_m: npt.ArrayLike,
    angles_rad: npt.ArrayLike,
    range_limits_m: tuple[float, float],
    t_ns: int,
    frame_id: str = "base_link",
    scan_time_s: float = 0.0,
) -> LaserScan:
    """LaserScan of ranges (N,) [m] at evenly spaced bearings (N,) [rad]; inf = no echo."""
    r, (angle_min, angle_max, inc) = scan_grid(ranges_m, angles_rad)
    lo, hi = range_limits_m
    msg = LaserScan()
    msg.header.stamp = ns_to_time(t_ns)
    msg.header.frame_id = frame_id
    msg.angle_min = angle_min
    msg.angle_max = angle_max
    msg.angle_increment = inc
    msg.time_increment = 0.0
    msg.scan_time = float(scan_time_s)
    msg.range_min = float(lo)
    msg.range_max = float(hi)
    msg.ranges = r.tolist()
    return msg


def scan_grid(ranges_m: npt.ArrayLike, angles_rad: npt.ArrayLike
              ) -> tuple[FloatArray, tuple[float, float, float]]:
    """The ranges (N,) [m] of a LaserScan (inf where not finite) and its (angle_min,
    angle_max, angle_increment) [rad]; ConversionError unless the bearings are evenly spaced."""
    r = np.asarray(ranges_m, dtype=np.float64).reshape(-1)
    a = np.asarray(angles_rad, dtype=np.float64).reshape(-1)
    if r.shape != a.shape or r.size == 0:
        raise ConversionError(f"scan: {r.size} ranges but {a.size} angles (need N >= 1 of each)")
    inc = float(a[1] - a[0]) if a.size > 1 else 0.0
    if a.size > 1 and not np.allclose(np.diff(a), inc, atol=_ANGLE_GRID_TOL_RAD):
        raise ConversionError("scan: bearings must be evenly spaced for a LaserScan")
    return np.where(np.isfinite(r), r, np.inf), (float(a[0]), float(a[-1]), inc)


def scan_to_arrays(msg: LaserScan, max_ranges: int = MAX_SCAN_RANGES
                   ) -> tuple[FloatArray, FloatArray]:
    """(ranges (N,) [m], bearings (N,) [rad]); NaN and out-of-limit readings become inf. A scan
    of more than `max_ranges` ranges is refused before any work on it."""
    check_scan_count(len(msg.ranges), max_ranges)
    return scan_arrays(np.asarray(msg.ranges, dtype=np.float64), msg.angle_min,
                        msg.angle_increment, msg.range_min, msg.range_max)


def check_scan_count(n: int, max_ranges: int) -> None:
    """ConversionError for a scan of more than `max_ranges` ranges (before any work on it)."""
    if n > max_ranges:
        raise ConversionError(
            f"scan: ranges has {n} values (the limit is {max_ranges}, more than any sensor of "
            "the project produces)")


def scan_arrays(r: FloatArray, angle_min: float, angle_increment: float, range_min: float,
                 range_max: float) -> tuple[FloatArray, FloatArray]:
    """scan_to_arrays of a LaserScan's fields: ranges (N,) [m] as float64, the angles [rad] and
    limits [m] as rclpy gives them."""
    if r.size == 0:
        raise ConversionError("scan: no ranges")
    if not (math.isfinite(angle_min) and math.isfinite(angle_increment)):
        raise ConversionError(
            f"scan: angle_min/angle_increment must be finite, got {angle_min}, "
            f"{angle_increment}"
        )
    a = angle_min + angle_increment * np.arange(r.size, dtype=np.float64)
    ok = np.isfinite(r) & (r >= range_min) & (r <= range_max)
    return np.where(ok, r, np.inf), a


# ----------------------------------------------------------------------------- Odometry


def pose_to_odometry(
    pose: Pose2D,
    cov: npt.ArrayLike | None,
    t_ns: int,
    frame_id: str,
    child_frame_id: str = "base_link",
    twist: tuple[float, float] = (0.0, 0.0),
) -> Odometry:
    """Odometry with the pose, its 3x3 (x, y, theta) covariance in the 6x6, and (v, w) twist."""
    return fill_odometry(Odometry(), pose, cov, t_ns, frame_id, child_frame_id, twist)


def fill_odometry(
    msg: Odometry,
    pose: Pose2D,
    cov: npt.ArrayLike | None,
    t_ns: int,
    frame_id: str,
    child_frame_id: str = "base_link",
    twist: tuple[float, float] = (0.0, 0.0),
) -> Odometry:
    """Overwrite `msg` in place (publishers reuse one message: building one costs ~0.2 ms)."""
    msg.header.stamp.sec = int(t_ns // NS_PER_S)
    msg.header.stamp.nanosec = int(t_ns % NS_PER_S)
    msg.header.frame_id = frame_id
    msg.child_frame_id = child_frame_id
    position = msg.pose.pose.position
    position.x = pose.x
    position.y = pose.y
    q = msg.pose.pose.orientation
    q.z = math.sin(pose.theta / 2.0)
    q.w = math.cos(pose.theta / 2.0)
    full = np.zeros((6, 6), dtype=np.float64)
    if cov is not None:
        c = np.asarray(cov, dtype=np.float64)
        if c.shape != (3, 3) or not np.all(np.isfinite(c)):
            raise ConversionError(f"odometry covariance must be a finite 3x3, got {c.shape}")
        full[_COV_ROWS, _COV_COLS] = c
    msg.pose.covariance = full.reshape(-1)
    msg.twist.twist.linear.x = float(twist[0])
    msg.twist.twist.angular.z = float(twist[1])
    return msg


def odometry_to_pose(msg: Odometry) -> tuple[Pose2D, FloatArray, int]:
    """(pose, 3x3 covariance, stamp [ns]) of an Odometry message; ConversionError if malformed."""
    p = msg.pose.pose.position
    try:
        theta = quaternion_to_yaw(msg.pose.pose.orientation)
        pose = Pose2D(float(p.x), float(p.y), theta)
    except IslandTypeError as exc:
        raise ConversionError(f"odometry pose: {exc}") from None
    full = np.asarray(msg.pose.covariance, dtype=np.float64).reshape(6, 6)
    return pose, full[_COV_ROWS, _COV_COLS], time_to_ns(msg.header.stamp)


# ----------------------------------------------------------------------------- Twist


def twist_to_command(msg: Twist) -> tuple[float, float]:
    """(v [m/s], w [rad/s]) of a Twist; ConversionError naming the field if NaN or infinite."""
    v, w = float(msg.linear.x), float(msg.angular.z)
    if not math.isfinite(v):
        raise ConversionError(f"cmd_vel linear.x is not finite ({v})")
    if not math.isfinite(w):
        raise ConversionError(f"cmd_vel angular.z is not finite ({w})")
    return v, w


def command_to_twist(v_mps: float, w_radps: float) -> Twist:
    """Twist with linear.x = v [m/s] and angular.z = w [rad/s]."""
    msg = Twist()
    msg.linear.x = float(v_mps)
    msg.angular.z = float(w_radps)
    return msg


def command_to_twist_stamped(
    v_mps: float, w_radps: float, stamp_ns: int, frame_id: str = "base_link"
) -> TwistStamped:
    """The /cmd_vel message: TwistStamped whose stamp is the sensor stamp [ns] it answers."""
    msg = TwistStamped()
    msg.header.stamp = ns_to_time(stamp_ns)
    msg.header.frame_id = frame_id
    msg.twist = command_to_twist(v_mps, w_radps)
    return msg


def twist_stamped_to_command(msg: TwistStamped) -> tuple[float, float, int]:
    """(v [m/s], w [rad/s], stamp [ns]) of a TwistStamped; ConversionError if not finite."""
    v, w = twist_to_command(msg.twist)
    return v, w, time_to_ns(msg.header.stamp)
