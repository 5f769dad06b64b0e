"""Shared types <-> ROS messages, on messages built in memory (and serialized to CDR and back)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from geometry_msgs.msg import Pose, PoseWithCovarianceStamped, Quaternion
from island_msgs_py.json_io import GraphFormatError
from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    Island,
    IslandTypeError,
    LineModel,
    ModelType,
    Pose2D,
)
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import String
from visualization_msgs.msg import Marker, MarkerArray

from island_msgs_py import conversions as cv


def _graph() -> tuple[list[Island], list[Edge]]:
    rng = np.random.default_rng(2)
    islands = [
        Island(0, LineModel(rng.uniform(-3, 3, (4, 4))), ModelType.LINE, 0.8, 1.0),
        Island(3, LineModel(rng.uniform(-3, 3, (2, 4))), ModelType.FISHER, 0.6, 2.0),
    ]
    edges = [Edge(0, 3, ControlStrategy.parse("Go 125, Rot 270, Go 652"), 8.0, 7.77, 0.2),
             Edge(3, 0, ControlStrategy(()), 1.0)]
    return islands, edges


@pytest.mark.parametrize("theta", [0.0, 0.3, -1.2, math.pi, -math.pi + 1e-9, 3.0])
def test_pose_round_trip(theta: float) -> None:
    p = Pose2D(1.5, -2.25, theta)
    back = cv.pose_to_pose2d(cv.pose2d_to_pose(p))
    assert (back.x, back.y) == (1.5, -2.25)
    assert math.cos(back.theta - theta) == pytest.approx(1.0)
    assert abs(back.theta - p.theta) < 1e-12 or abs(abs(back.theta - p.theta) - 2 * math.pi) < 1e-9


def test_quaternion_yaw_is_normalized_and_checked() -> None:
    q = cv.yaw_to_quaternion(0.7)
    scaled = Quaternion(x=0.0, y=0.0, z=q.z * 3, w=q.w * 3)
    assert cv.quaternion_to_yaw(scaled) == pytest.approx(0.7)
    with pytest.raises(IslandTypeError, match="zero length"):
        cv.quaternion_to_yaw(Quaternion(x=0.0, y=0.0, z=0.0, w=0.0))
    bad = Pose()
    bad.orientation.w = math.nan
    with pytest.raises(IslandTypeError, match="NaN"):
        cv.pose_to_pose2d(bad)


def test_pose_with_covariance_round_trip_through_cdr() -> None:
    cov = np.array([[0.04, 0.01, 0.0], [0.01, 0.09, 0.002], [0.0, 0.002, 0.01]])
    msg = cv.pose2d_to_pose_with_covariance_stamped(Pose2D(1.0, 2.0, 0.5), "island_4", cov)
    msg2 = deserialize_message(serialize_message(msg), PoseWithCovarianceStamped)
    pose, cov_back, frame = cv.pose_with_covariance_stamped_to_pose2d(msg2)
    assert frame == "island_4"
    assert pose.theta == pytest.approx(0.5) and (pose.x, pose.y) == (1.0, 2.0)
    np.testing.assert_array_equal(cov_back, cov)
    six = np.asarray(msg.pose.covariance).reshape(6, 6)
    assert six[5, 5] == 0.01 and six[0, 1] == 0.01 and six[2, 2] == 0.0
    with pytest.raises(IslandTypeError, match="3x3"):
        cv.pose2d_to_pose_with_covariance_stamped(Pose2D(0, 0, 0), "f", np.eye(2))


def test_graph_string_round_trip_through_cdr() -> None:
    islands, edges = _graph()
    msg = deserialize_message(serialize_message(cv.graph_to_string_msg(islands, edges)), String)
    assert cv.string_msg_to_graph(msg) == (islands, edges)
    with pytest.raises(GraphFormatError, match="not valid JSON"):
        cv.string_msg_to_graph(String(data="{"))


def test_add_parameters_round_trip_and_errors() -> None:
    islands, edges = _graph()
    for item in [*islands, *edges]:
        p = cv.island_to_parameter(item) if isinstance(item, Island) else cv.edge_to_parameter(item)
        p = deserialize_message(serialize_message(p), Parameter)
        assert cv.parameter_to_item(p) == item
    wrong = Parameter(name="node", value=ParameterValue(type=ParameterType.PARAMETER_STRING))
    with pytest.raises(GraphFormatError, match=r"parameter\.name: expected 'island', 'edge', "
                                               r"'exit' or 'new_exit', got 'node'"):
        cv.parameter_to_item(wrong)
    num = Parameter(name="edge", value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE))
    with pytest.raises(GraphFormatError, match=r"parameter\.value: expected a string"):
        cv.parameter_to_item(num)


def test_route_to_path() -> None:
    islands, _ = _graph()
    path = cv.route_to_path(islands)
    assert path.header.frame_id == "island_0"
    assert cv.path_to_island_frames(path) == ["island_0", "island_3"]
    for ps in path.poses:
        assert cv.pose_to_pose2d(ps.pose) == Pose2D(0.0, 0.0, 0.0)
    assert cv.route_to_path([]).poses == []


def test_markers_in_display_frame_round_trip_models() -> None:
    islands, edges = _graph()
    layout = {0: Pose2D(0.0, 0.0, 0.0), 3: Pose2D(10.0, 5.0, math.pi / 2)}
    arr = deserialize_message(
        serialize_message(cv.graph_to_marker_array(islands, edges, layout)), MarkerArray)
    assert arr.markers[0].action == Marker.DELETEALL
    models = cv.marker_array_to_models(arr)
    for i in islands:
        np.testing.assert_allclose(models[i.id], i.model.segments, rtol=0, atol=0)
    by_ns: dict[str, list[Marker]] = {}
    for m in arr.markers[1:]:
        by_ns.setdefault(m.ns, []).append(m)
    assert {m.header.frame_id for m in arr.markers} == {"islands_layout"}
    m3 = next(m for m in by_ns["island_models"] if m.id == 3)
    assert cv.pose_to_pose2d(m3.pose).theta == pytest.approx(math.pi / 2)
    assert m3.pose.position.x == 10.0
    labels = {m.text for m in by_ns["edge_labels"]}
    assert "0->3: Go 125, Rot 270, Go 652" in labels and "3->0" in labels
    arrow = next(m for m in by_ns["edges"] if m.points[1].x == 10.0)
    assert (arrow.points[0].x, arrow.points[1].y) == (0.0, 5.0)
    assert any("island_3 (fisher, R=0.60)" == m.text for m in by_ns["island_labels"])


def test_markers_in_island_frames_and_fallback_layout() -> None:
    islands, edges = _graph()
    arr = cv.graph_to_marker_array(islands, edges, in_island_frames=True)
    models = [m for m in arr.markers if m.ns == "island_models"]
    assert [m.header.frame_id for m in models] == ["island_0", "island_3"]
    assert all(cv.pose_to_pose2d(m.pose) == Pose2D(0.0, 0.0, 0.0) for m in models)
    with pytest.raises(IslandTypeError, match="no pose for islands"):
        cv.graph_to_marker_array(islands, edges, {0: Pose2D(0, 0, 0)})
