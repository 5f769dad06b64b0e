"""Exits in the ROS forms: the `exit` item of /topo_graph/add, and the exit arrows in markers."""

from __future__ import annotations

import math

import pytest
from island_msgs_py.json_io import GraphFormatError
from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    Exit,
    ExitState,
    ExitUpdate,
    Island,
    LineModel,
    ModelType,
    Pose2D,
)
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rclpy.serialization import deserialize_message, serialize_message
from visualization_msgs.msg import Marker, MarkerArray

from island_msgs_py import conversions as cv


def test_exit_item_round_trip_and_errors() -> None:
    updates = (ExitUpdate(3, 1, ExitState.EXPLORED, (3, 5)), ExitUpdate(0, 2, ExitState.BLOCKED))
    for update in updates:
        p = deserialize_message(serialize_message(cv.exit_update_to_parameter(update)), Parameter)
        assert p.name == "exit" and cv.parameter_to_item(p) == update
    bad = Parameter(name="exit", value=ParameterValue(
        type=ParameterType.PARAMETER_STRING, string_value='{"island": 3, "exit": 1}'))
    with pytest.raises(GraphFormatError, match=r"^exit\.state: missing"):
        cv.parameter_to_item(bad)
    wrong = Parameter(name="exits", value=ParameterValue(type=ParameterType.PARAMETER_STRING))
    with pytest.raises(GraphFormatError, match="expected 'island', 'edge', 'exit' or 'new_exit'"):
        cv.parameter_to_item(wrong)


def test_markers_draw_one_arrow_per_exit_coloured_by_state() -> None:
    a = Island(0, LineModel(), ModelType.LINE, 0.5, 0.0, exits=(
        Exit(0, 0.0, 1.0, ExitState.EXPLORED, (0, 4)), Exit(1, math.pi / 2, 1.0),
        Exit(5, -math.pi / 2, 0.8, ExitState.BLOCKED)))
    b = Island(4, LineModel(), ModelType.LINE, 0.5, 0.0, exits=(Exit(0, math.pi, 1.0),))
    layout = {0: Pose2D(0.0, 0.0, 0.0), 4: Pose2D(10.0, 0.0, math.pi / 2)}
    edges = [Edge(0, 4, ControlStrategy.parse("Go 1000"), 10.0, source_exit=0, target_exit=0)]
    arr = deserialize_message(serialize_message(
        cv.graph_to_marker_array([a, b], edges, layout)), MarkerArray)
    arrows = [m for m in arr.markers if m.ns == "exits"]
    assert [m.type for m in arrows] == [Marker.ARROW] * 4
    assert sorted(m.id for m in arrows) == [0, 1, 2, 3]  # unique ids in the namespace
    colours = [(m.color.r, m.color.g, m.color.b) for m in arrows]
    want = [cv.EXIT_COLOURS[s] for s in
            (ExitState.EXPLORED, ExitState.UNEXPLORED, ExitState.BLOCKED, ExitState.UNEXPLORED)]
    assert colours == [pytest.approx((c.r, c.g, c.b)) for c in want]
    north = arrows[1]  # island 0's exit 1: from its origin, along +y of its frame
    assert (north.points[0].x, north.points[0].y) == (0.0, 0.0)
    assert (north.points[1].x, north.points[1].y) == pytest.approx((0.0, cv.EXIT_ARROW_M))
    b_exit = arrows[3]  # placed by island 4's layout pose (turned by pi/2)
    assert cv.pose_to_pose2d(b_exit.pose).theta == pytest.approx(math.pi / 2)
    assert b_exit.pose.position.x == 10.0
    in_frames = cv.graph_to_marker_array([a, b], edges, layout, in_island_frames=True)
    assert {m.header.frame_id for m in in_frames.markers if m.ns == "exits"} == \
        {"island_0", "island_4"}
