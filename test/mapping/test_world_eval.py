"""The map-against-world figures on hand-made maps: coverage, islands per place, false merges,
cycle rank and route lengths."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from island_mapping.core.graph import TopoGraph
from island_mapping.evaluation.world_eval import (
    WorldEvalError,
    compact_events,
    evaluate_map,
    false_merges,
    known_free_of,
    map_cycle_rank,
    revisits_from_events,
)
from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    Exit,
    ExitSide,
    ExitState,
    Island,
    LineModel,
    ModelType,
    Pose2D,
    PrimitiveKind,
    StrategyPrimitive,
)
from island_sim.core.importers import rectangles_to_segments
from island_sim.core.places import WorldPlaceKind, world_places
from island_sim.core.world import World
from island_sim.core.world_loader import load_world

GO = ControlStrategy((StrategyPrimitive(PrimitiveKind.GO, 100),))


def _island(i: int, x: float, y: float, theta: float = 0.0) -> Island:
    return Island(i, LineModel(), ModelType.LINE, 1.0, 0.0, origin_truth=Pose2D(x, y, theta))


def _edge(a: int, b: int, length_m: float = 1.0) -> Edge:
    return Edge(a, b, GO, length_m, length_m)


def _revisit(island: int, truth: tuple[float, float, float],
             in_island: tuple[float, float, float] | None) -> dict[str, object]:
    e: dict[str, object] = {"kind": "island_revisited", "t_s": 1.0, "revisited_island_id": island,
                            "truth_pose": dict(zip("x y theta".split(), truth, strict=True))}
    if in_island is not None:
        e["island_pose"] = dict(zip("x y theta".split(), in_island, strict=True))
    return e


def test_coverage_and_islands_per_place_on_a_t_junction() -> None:
    world = load_world("t_junction")  # places: junction (10, 1), ends (1, 1), (19, 1), (10, 11)
    places = world_places(world)
    graph = TopoGraph.from_parts(
        [_island(0, 10.5, 1.2), _island(1, 2.0, 1.0), _island(2, 2.5, 1.0),
         _island(3, 15.0, 1.0)],
        [_edge(0, 1), _edge(1, 2), _edge(0, 3)])
    ev = evaluate_map(world, places, graph, [])
    assert ev.places == 4 and ev.junctions == 1
    assert sum(ev.covered) == 2 and ev.coverage == pytest.approx(0.5)
    assert ev.junction_coverage == pytest.approx(1.0)
    assert ev.islands_at_places == 3  # island 3 is 4-5 m from every place
    assert ev.islands_per_place == pytest.approx(1.5)  # two islands at the west end
    d = ev.to_dict()
    assert d["islands_off_places"] == 1 and d["covered_junctions"] == 1
    assert d["missed_closures"] == 1  # the west end's second island: a loop not closed
    assert [p["covered"] for p in d["place_list"]].count(True) == 2


def test_a_side_exit_where_the_map_puts_it_makes_a_place_known_not_covered() -> None:
    """One island at the T's west end facing east. Its side exit 8 m along opens at the
    junction (10, 1): the junction is known to the map, not covered. A blocked side exit
    there, or one whose prefix ends 4 m past the junction, makes nothing known."""
    world = load_world("t_junction")  # places: junction (10, 1), ends (1, 1), (19, 1), (10, 11)
    places = world_places(world)

    def side(k: int, go_cm: int, state: ExitState = ExitState.UNEXPLORED) -> Exit:
        return Exit(k, math.pi / 2, 1.0, state, prefix=ControlStrategy.parse(f"Go {go_cm}"),
                    side=ExitSide.LEFT)

    def evaluated(*exits: Exit) -> dict[str, object]:
        isl = Island(0, LineModel(), ModelType.LINE, 1.0, 0.0, origin_truth=Pose2D(2.0, 1.0, 0.0),
                     exits=exits)
        return evaluate_map(world, places, TopoGraph.from_parts([isl], []), []).to_dict()

    d = evaluated(side(0, 800))
    assert (d["covered_places"], d["known_places"]) == (1, 2)
    assert (d["covered_junctions"], d["known_junctions"]) == (0, 1)
    assert [p["known"] for p in d["place_list"]].count(True) == 2
    assert evaluated(side(0, 800, ExitState.BLOCKED))["known_places"] == 1
    assert evaluated(side(0, 1200))["known_places"] == 1


def test_a_place_behind_a_wall_is_not_covered() -> None:
    # two corridors side by side, 0.5 m of wall between them, joined at the east end
    world = World(rectangles_to_segments([(0, 0, 20, 2), (0, 2.5, 20, 4.5), (18, 2, 20, 2.5)],
                                         0.25), start_pose=Pose2D(5, 1, 0))
    places = world_places(world)
    west = [p for p in places.places if p.kind is WorldPlaceKind.END and p.x_m < 3]
    assert len(west) == 2
    graph = TopoGraph.from_parts([_island(0, 1.2, 1.6)], [])
    ev = evaluate_map(world, places, graph, [])
    covered = {round(p.y_m): c for p, c in zip(places.places, ev.covered, strict=True)
               if p in west}
    assert covered == {1: True, 4: False}  # the north one is 2 m away, through the wall


def test_a_recognition_that_moves_the_origin_more_than_3_m_is_a_false_merge() -> None:
    origins = {0: Pose2D(10.5, 1.2, 0.0)}
    events = [
        # 2 m ahead of the origin, turned left: the origin it implies is the true one
        _revisit(0, (12.5, 1.2, math.pi / 2), (2.0, 0.0, math.pi / 2)),
        # recognised at the corridor's west end, 8.5 m away
        _revisit(0, (2.0, 1.0, 0.0), (0.3, 0.0, 0.0)),
        {"kind": "island_accepted", "t_s": 0.5},
    ]
    found = false_merges(origins, revisits_from_events(events), 3.0)
    assert len(found) == 1
    assert found[0].island_id == 0 and found[0].error_m == pytest.approx(8.8, abs=0.01)
    # without the pose in the island the robot's own position is what counts
    assert false_merges(origins, revisits_from_events([_revisit(0, (12.0, 1.2, 0.0), None)]),
                        3.0) == []


def test_map_cycle_rank_counts_distinct_undirected_edges() -> None:
    islands = [_island(i, float(i), 0.0) for i in range(4)]
    chain = TopoGraph.from_parts(islands, [_edge(0, 1), _edge(1, 0), _edge(1, 2)])
    assert map_cycle_rank(chain) == 0  # 0->1 and 1->0 are one edge
    loop = TopoGraph.from_parts(islands, [_edge(0, 1), _edge(1, 0), _edge(1, 2), _edge(2, 0)])
    assert map_cycle_rank(loop) == 1  # island 3 alone is a component, not a loop


def test_a_duplicates_out_and_back_is_a_cycle_of_the_map_not_a_loop_of_the_world() -> None:
    """On the T (no loop): islands 1 and 2 both at the west end, each linked to the
    junction's island 0 and to each other (paper_fig4 seed 3 counted 4 cycles against the
    world's 3, three of them through two islands on one place). The map has cycle rank 1;
    with the islands of one place as one node, 0."""
    world = load_world("t_junction")
    places = world_places(world)
    graph = TopoGraph.from_parts(
        [_island(0, 10.5, 1.2), _island(1, 2.0, 1.0), _island(2, 2.5, 1.0),
         _island(3, 10.0, 10.5)],
        [_edge(0, 1), _edge(2, 0), _edge(1, 2), _edge(0, 3)])
    ev = evaluate_map(world, places, graph, [])
    assert (ev.map_cycle_rank, ev.map_place_cycle_rank, ev.world_cycle_rank) == (1, 0, 0)
    d = ev.to_dict()
    assert (d["map_cycle_rank"], d["map_place_cycle_rank"]) == (1, 0)
    loop = TopoGraph.from_parts(
        [_island(0, 10.5, 1.2), _island(1, 2.0, 1.0), _island(3, 10.0, 10.5)],
        [_edge(0, 1), _edge(1, 3), _edge(3, 0)])  # three places in a loop: counted by both
    ev = evaluate_map(world, places, loop, [])
    assert (ev.map_cycle_rank, ev.map_place_cycle_rank) == (1, 1)


def test_route_length_ratio_against_the_true_shortest_path() -> None:
    world = load_world("corridor")
    graph = TopoGraph.from_parts([_island(0, 2.0, 1.0), _island(1, 15.0, 1.0, math.pi)],
                                 [_edge(0, 1, 14.3)])
    ev = evaluate_map(world, world_places(world), graph, [], [(0, 1, True), (1, 0, False)])
    assert [r.map_length_m for r in ev.routes] == [14.3, 14.3]  # backwards too
    assert ev.routes[0].true_length_m == pytest.approx(13.0, abs=0.1)
    assert ev.route_length_ratio == pytest.approx(1.1, abs=0.01)
    assert ev.route_success_rate == pytest.approx(0.5)
    # two islands at one place: a route between them has no ratio (it would divide by ~0)
    near = TopoGraph.from_parts([_island(0, 2.0, 1.0), _island(1, 2.3, 1.0), _island(2, 9, 1)],
                                [_edge(0, 2, 7.5), _edge(2, 1, 7.0)])
    ev = evaluate_map(world, world_places(world), near, [], [(0, 1, None), (0, 2, None)])
    assert math.isnan(ev.routes[0].ratio) and ev.routes[0].map_length_m == 14.5
    assert ev.route_length_ratio == pytest.approx(7.5 / 7.0, abs=0.01)
    assert ev.to_dict()["routes_without_ratio"] == 1


def test_maps_and_events_that_cannot_be_evaluated_are_clear_errors() -> None:
    world = load_world("corridor")
    places = world_places(world)
    no_truth = TopoGraph.from_parts([Island(0, LineModel(), ModelType.LINE, 1.0, 0.0)], [])
    with pytest.raises(WorldEvalError, match="origin_truth"):
        evaluate_map(world, places, no_truth, [])
    graph = TopoGraph.from_parts([_island(0, 2.0, 1.0)], [])
    with pytest.raises(WorldEvalError, match="truth_pose"):
        evaluate_map(world, places, graph, [{"kind": "island_revisited",
                                             "revisited_island_id": 0}])
    with pytest.raises(WorldEvalError, match="island 5"):
        evaluate_map(world, places, graph, [_revisit(5, (2.0, 1.0, 0.0), None)])
    with pytest.raises(WorldEvalError, match="island 1"):
        evaluate_map(world, places, graph, [], [(0, 1, True)])


def test_compact_events_keep_ids_not_models() -> None:
    island = {"id": 3, "model": {"segments": [[0, 0, 1, 1]]}}
    out = compact_events([{"kind": "island_accepted", "island": island, "legs_m": [[0, 1]],
                           "truth_pose": {"x": 1, "y": 2, "theta": 0}},
                          {"kind": "island_revisited", "edge": {"source": 1, "target": 3,
                                                                "length_m": 4.0, "strategy": "x"}}])
    assert out[0] == {"kind": "island_accepted", "island_id": 3,
                      "truth_pose": {"x": 1, "y": 2, "theta": 0}}
    assert out[1]["edge"] == {"source": 1, "target": 3, "length_m": 4.0}


def test_known_free_pixels_of_an_image_world_and_its_map_yaml(tmp_path: Path) -> None:
    img = np.full((10, 20), 255, dtype=np.uint8)  # row 0 at the top
    img[:, 10:] = 205  # the east half unknown (grey)
    (tmp_path / "m.pgm").write_bytes(b"P5\n20 10\n255\n" + img.tobytes())
    allowed = known_free_of(tmp_path / "m.pgm", 0.5)
    assert allowed is not None
    assert allowed(np.array([[2.0, 2.0], [8.0, 2.0], [12.0, 2.0]])).tolist() == [
        True, False, False]  # 10 px of 0.5 m are known free: x < 5 m
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.5\norigin: [-5.0, 0.0, 0]\n")
    shifted = known_free_of(tmp_path / "m.yaml")
    assert shifted is not None
    assert shifted(np.array([[-3.0, 2.0], [2.0, 2.0]])).tolist() == [True, False]
    assert known_free_of("paper_fig4") is None
