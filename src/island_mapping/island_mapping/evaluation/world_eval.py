"""A map measured against the world it was built in (issue 16's yardstick).

Inputs: the world's ground-truth places (`island_sim.core.places`), the map (islands with
their true origins, `Island.origin_truth`, and edges), the builder's revisit events with the
robot's true pose at each, and the island pairs whose routes were followed. Figures:

- **coverage**: a place is covered when an island's true origin lies within 2.5 m of it with
  no wall between them; overall and over junctions;
- **places the map knows** (beside coverage, not instead of it): a place is known when it is
  covered, or when a side exit of the map (not blocked) opens within 2.5 m of it, with no wall
  between, where the map puts the opening: its island's true origin composed with the exit's
  prefix driven ideally (`openings.exit_pose`), so the odometry's error along the prefix
  counts. Islands stand only where eq. 3 and R allow; a junction beside a corridor, which R
  does not tell from the corridor with this sonar, is in the map as a side exit (a strategy
  prefix and a turn, the paper's way of encoding a route through an unmapped junction);
- **islands per place**: each island belongs to its nearest such place (if any); islands at
  places / covered places (1.0: no place has a duplicate); islands at no place are counted;
  each duplicate is a **missed loop closure** (`missed_closures`);
- **false merges**: an island recognised from where it is not. A revisit event says where the
  robot was in the island's frame (`island_pose`); composed with the robot's true pose it says
  where the island's origin truly was *according to that recognition*. More than 3 m from the
  island's own true origin is a false merge (one island standing for two places);
- **cycle rank** of the map (undirected, distinct edges: E - V + components) against the
  world's (holes of its reachable free space), and the same with the islands at one place as
  one node (`map_place_cycle_rank`: the rank with the duplicates merged; neither counts the
  world's loops the map closes);
- **routes**: success of the followed routes (from the route evaluation), and the length of
  each planned route by the map (sum of its edges' length_m) against the shortest path between
  the two islands' true origins through the free space (no ratio for two islands at one place,
  less than 2.5 m apart: it would divide by almost nothing).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import networkx as nx
import numpy as np
from island_msgs_py.errors import InputError
from island_msgs_py.json_io import GraphFormatError, pose_from_dict
from island_msgs_py.types import ExitState, Pose2D
from island_sim.core.freespace import AllowedFn, FreeSpaceError, known_free_allowed
from island_sim.core.images import read_pgm, read_png
from island_sim.core.importers import ImageImportConfig
from island_sim.core.places import WorldPlaceKind, WorldPlaces
from island_sim.core.world import World, read_structured

from island_mapping.core.explore.openings import exit_pose
from island_mapping.core.graph import GraphError, TopoGraph
from island_mapping.evaluation.routes import with_reverse_edges

ROUNDING = 3
"""Decimals of the figures in the JSON form."""


class WorldEvalError(InputError):
    """The map or its run record cannot be evaluated (names what is missing or wrong)."""


@dataclass(frozen=True)
class WorldEvalConfig:
    cover_radius_m: float = field(
        default=2.5,
        metadata={"help": "a place is covered by an island whose true origin is this close "
                          "with no wall between [m]"},
    )
    false_merge_m: float = field(
        default=3.0,
        metadata={"help": "a recognition that puts the island's origin farther than this from "
                          "its true origin is a false merge [m]"},
    )
    min_route_m: float = field(
        default=2.5,
        metadata={"help": "routes between true origins closer than this (two islands at one "
                          "place) have no length ratio: it would divide by almost nothing [m]"},
    )
    path_snap_m: float = field(
        default=0.5,
        metadata={"help": "an island origin closer to a wall than the robot's clearance is "
                          "moved to free space within this distance for true path lengths [m]"},
    )


@dataclass(frozen=True)
class Revisit:
    """A recognition of island `island_id`: the robot's true pose and its pose in the island's
    frame as the builder localized it [m, rad]."""

    island_id: int
    t_s: float
    truth: Pose2D
    in_island: Pose2D | None


@dataclass(frozen=True)
class FalseMerge:
    island_id: int
    t_s: float
    error_m: float  # distance between the recognised origin and the island's true origin


@dataclass(frozen=True)
class RouteLength:
    source: int
    target: int
    success: bool | None  # None: the route was not followed
    map_length_m: float  # sum of the planned route's edge lengths
    true_length_m: float  # shortest path between the true origins through free space
    min_true_m: float = 0.0  # shorter true paths have no ratio

    @property
    def ratio(self) -> float:
        """map / true length; NaN when the true path is shorter than min_true_m (or none)."""
        ok = self.true_length_m > 0 and self.true_length_m >= self.min_true_m
        return self.map_length_m / self.true_length_m if ok else math.nan


@dataclass(frozen=True)
class MapEvaluation:
    places: int
    junctions: int
    covered: tuple[bool, ...]  # per place, in WorldPlaces order
    islands: int
    island_place: dict[int, int | None]  # island id -> index of its place (None: at no place)
    false_merges: tuple[FalseMerge, ...]
    revisits: int
    map_cycle_rank: int
    map_place_cycle_rank: int  # the islands on one place counted as one node
    world_cycle_rank: int
    routes: tuple[RouteLength, ...]
    place_xy: tuple[tuple[str, float, float], ...]  # per place: kind, x [m], y [m]
    known: tuple[bool, ...]  # per place: covered, or a side exit opens there

    @property
    def junction_flags(self) -> tuple[bool, ...]:
        return tuple(k == WorldPlaceKind.JUNCTION for k, _x, _y in self.place_xy)

    @property
    def coverage(self) -> float:
        return sum(self.covered) / self.places if self.places else math.nan

    @property
    def junction_coverage(self) -> float:
        hits = [c for c, j in zip(self.covered, self.junction_flags, strict=True) if j]
        return sum(hits) / len(hits) if hits else math.nan

    @property
    def islands_at_places(self) -> int:
        return sum(p is not None for p in self.island_place.values())

    @property
    def islands_per_place(self) -> float:
        used = {p for p in self.island_place.values() if p is not None}
        return self.islands_at_places / len(used) if used else math.nan

    @property
    def missed_closures(self) -> int:
        """Islands built at a place that already had one (the robot did not recognise it):
        islands at places minus places with an island."""
        used = {p for p in self.island_place.values() if p is not None}
        return self.islands_at_places - len(used)

    @property
    def route_success_rate(self) -> float:
        done = [r.success for r in self.routes if r.success is not None]
        return sum(done) / len(done) if done else math.nan

    @property
    def route_length_ratio(self) -> float:
        """Mean over the routes (with a ratio) of map length / true shortest path."""
        ratios = [r.ratio for r in self.routes if math.isfinite(r.ratio)]
        return float(np.mean(ratios)) if ratios else math.nan

    @property
    def route_length_ratio_total(self) -> float:
        """Summed map length / summed true length over the routes with a ratio."""
        rs = [r for r in self.routes if math.isfinite(r.ratio)]
        true = sum(r.true_length_m for r in rs)
        return sum(r.map_length_m for r in rs) / true if rs and true > 0 else math.nan

    def to_dict(self) -> dict[str, Any]:
        """The JSON form (NaN -> None)."""

        def num(v: float) -> float | None:
            return round(v, ROUNDING) if math.isfinite(v) else None

        ratios = [r.ratio for r in self.routes if math.isfinite(r.ratio)]
        return {
            "places": self.places,
            "junctions": self.junctions,
            "covered_places": sum(self.covered),
            "covered_junctions": sum(c and j for c, j in zip(self.covered, self.junction_flags,
                                                             strict=True)),
            "coverage": num(self.coverage),
            "known_places": sum(self.known),
            "known_junctions": sum(k and j for k, j in zip(self.known, self.junction_flags,
                                                           strict=True)),
            "junction_coverage": num(self.junction_coverage),
            "islands": self.islands,
            "islands_at_places": self.islands_at_places,
            "islands_off_places": self.islands - self.islands_at_places,
            "islands_per_place": num(self.islands_per_place),
            "revisits": self.revisits,
            "false_merges": len(self.false_merges),
            "missed_closures": self.missed_closures,
            "false_merge_events": [asdict(f) for f in self.false_merges],
            "map_cycle_rank": self.map_cycle_rank,
            "map_place_cycle_rank": self.map_place_cycle_rank,
            "world_cycle_rank": self.world_cycle_rank,
            "routes": len(self.routes),
            "route_success_rate": num(self.route_success_rate),
            "route_length_ratio_mean": num(self.route_length_ratio),
            "route_length_ratio_max": num(max(ratios)) if ratios else None,
            "route_length_ratio_total": num(self.route_length_ratio_total),
            "routes_without_ratio": len(self.routes) - len(ratios),
            "per_route": [
                {"source": r.source, "target": r.target, "success": r.success,
                 "map_length_m": num(r.map_length_m), "true_length_m": num(r.true_length_m),
                 "ratio": num(r.ratio)}
                for r in self.routes
            ],
            "place_list": [
                {"kind": kind, "x": round(x, 2), "y": round(y, 2), "covered": cov, "known": kn}
                for (kind, x, y), cov, kn in zip(self.place_xy, self.covered, self.known,
                                                 strict=True)
            ],
            "island_place": {str(k): v for k, v in sorted(self.island_place.items())},
        }


# ----------------------------------------------------------------------------- pieces


def _in_sight(world: World, a: tuple[float, float], b: tuple[float, float]) -> bool:
    d = math.hypot(b[0] - a[0], b[1] - a[1])
    if d == 0.0:
        return True
    hit = world.raycast(np.array([a]), np.array([math.atan2(b[1] - a[1], b[0] - a[0])]), d)
    return not np.isfinite(hit.distance_m[0])


def island_places(world: World, places: WorldPlaces, origins: Mapping[int, Pose2D],
                  radius_m: float) -> dict[int, int | None]:
    """Each island's place: the nearest place within `radius_m` [m] of its true origin with no
    wall between them (index into places.places), or None."""
    xy = places.positions_m()
    out: dict[int, int | None] = {}
    for i, o in origins.items():
        d = np.hypot(xy[:, 0] - o.x, xy[:, 1] - o.y)
        out[i] = None
        for k in np.argsort(d, kind="stable").tolist():
            if d[k] > radius_m:
                break
            if _in_sight(world, (o.x, o.y), (float(xy[k, 0]), float(xy[k, 1]))):
                out[i] = int(k)
                break
    return out


def covered_places(world: World, places: WorldPlaces, origins: Iterable[Pose2D],
                   radius_m: float) -> tuple[bool, ...]:
    """Per place: an island origin lies within `radius_m` [m] with no wall between."""
    pts = [(o.x, o.y) for o in origins]
    out = []
    for p in places.places:
        out.append(any(math.hypot(x - p.x_m, y - p.y_m) <= radius_m
                       and _in_sight(world, (p.x_m, p.y_m), (x, y)) for x, y in pts))
    return tuple(out)


def side_exit_openings(graph: TopoGraph) -> list[Pose2D]:
    """Where the map puts each side exit's opening that is not blocked, in the world: its
    island's true origin composed with the prefix driven ideally (islands without a true
    origin are skipped)."""
    out = []
    for i in graph.islands():
        if i.origin_truth is None:
            continue
        for e in i.exits:
            if e.prefix is not None and e.side is not None and e.state is not ExitState.BLOCKED:
                out.append(i.origin_truth.compose(exit_pose(e.prefix, e.side)))
    return out


def revisits_from_events(events: Iterable[Mapping[str, Any]]) -> list[Revisit]:
    """The island_revisited events that carry the robot's true pose (`truth_pose`)."""
    out = []
    for k, e in enumerate(events):
        if e.get("kind") != "island_revisited":
            continue
        if e.get("revisited_island_id") is None or e.get("truth_pose") is None:
            raise WorldEvalError(f"builder event {k} (island_revisited) lacks "
                                 "revisited_island_id or truth_pose")
        pose = e.get("island_pose")
        try:
            out.append(Revisit(int(e["revisited_island_id"]), float(e.get("t_s", 0.0)),
                               pose_from_dict(e["truth_pose"], f"event {k} truth_pose"),
                               pose_from_dict(pose, f"event {k} island_pose") if pose else None))
        except (GraphFormatError, TypeError, ValueError) as exc:
            raise WorldEvalError(f"builder event {k} (island_revisited): {exc}") from None
    return out


def false_merges(origins: Mapping[int, Pose2D], revisits: Iterable[Revisit],
                 threshold_m: float) -> list[FalseMerge]:
    """Recognitions that put an island's origin more than `threshold_m` [m] from where it is
    (without `in_island`: the robot itself that far from the origin)."""
    out = []
    for r in revisits:
        if r.island_id not in origins:
            raise WorldEvalError(f"revisit of island {r.island_id}, which has no true origin "
                                 "in the map")
        implied = r.truth.compose(r.in_island.inverse()) if r.in_island else r.truth
        o = origins[r.island_id]
        err = math.hypot(implied.x - o.x, implied.y - o.y)
        if err > threshold_m:
            out.append(FalseMerge(r.island_id, r.t_s, round(err, ROUNDING)))
    return out


def map_cycle_rank(graph: TopoGraph, node: Callable[[int], Hashable] = lambda i: i) -> int:
    """Independent cycles of the map as an undirected graph on distinct edges, each island
    counted as the node `node(island id)` (default: itself; edges within one node dropped)."""
    nodes = {i: node(i) for i in graph.island_ids()}
    g: nx.Graph[Hashable] = nx.Graph()
    g.add_nodes_from(nodes.values())
    g.add_edges_from((a, b) for e in graph.iter_edges()
                     if (a := nodes[e.source]) != (b := nodes[e.target]))
    return g.number_of_edges() - g.number_of_nodes() + nx.number_connected_components(g)


def map_place_cycle_rank(graph: TopoGraph, island_place: Mapping[int, int | None]) -> int:
    """`map_cycle_rank` with the islands at one world place (`island_places`) as one node:
    an edge out to a duplicate and one back from it make a cycle of the map, not a loop of
    the world, and an edge within one place is no edge."""
    def node(i: int) -> tuple[str, int]:
        p = island_place.get(i)
        return ("island", i) if p is None else ("place", p)

    return map_cycle_rank(graph, node)


def route_lengths(graph: TopoGraph, places: WorldPlaces, origins: Mapping[int, Pose2D],
                  pairs: Sequence[tuple[int, int, bool | None]],
                  snap_m: float, min_route_m: float = 0.0) -> list[RouteLength]:
    """Map length of the planned route (edges usable backwards, as routes are followed) and
    the true shortest path between the islands' true origins, per (source, target, success);
    a ratio only for true paths of at least `min_route_m` [m]."""
    g2 = with_reverse_edges(graph)
    out = []
    for a, b, ok in pairs:
        for i in (a, b):
            if i not in origins:
                raise WorldEvalError(f"route {a}->{b}: island {i} has no true origin in the map")
        try:
            route = g2.plan_route(a, b)
        except GraphError as exc:
            raise WorldEvalError(f"route {a}->{b}: {exc}") from None
        try:
            true_m, _path = places.space.shortest_path_m(
                (origins[a].x, origins[a].y), (origins[b].x, origins[b].y), snap_m)
        except FreeSpaceError:
            true_m = math.nan  # an origin off the reachable free space: no ratio
        out.append(RouteLength(a, b, ok, float(sum(e.length_m for e in route.edges)), true_m,
                               min_route_m))
    return out


def evaluate_map(world: World, places: WorldPlaces, graph: TopoGraph,
                 events: Iterable[Mapping[str, Any]],
                 route_pairs: Sequence[tuple[int, int, bool | None]] = (),
                 cfg: WorldEvalConfig | None = None) -> MapEvaluation:
    """Every figure of the module docstring for `graph` built in `world`.

    WorldEvalError when the map has no island with a true origin, or an event or route names
    an island the map does not have."""
    c = cfg if cfg is not None else WorldEvalConfig()
    origins = {i.id: i.origin_truth for i in graph.islands() if i.origin_truth is not None}
    if len(graph) and not origins:
        raise WorldEvalError("the map's islands have no true origins (origin_truth): it was "
                             "not built in simulation")
    revisits = revisits_from_events(events)
    covered = covered_places(world, places, origins.values(), c.cover_radius_m)
    by_exits = covered_places(world, places, side_exit_openings(graph), c.cover_radius_m)
    at_place = island_places(world, places, origins, c.cover_radius_m)
    return MapEvaluation(
        places=len(places.places),
        junctions=len(places.junctions),
        covered=covered,
        islands=len(graph),
        island_place=at_place,
        false_merges=tuple(false_merges(origins, revisits, c.false_merge_m)),
        revisits=len(revisits),
        map_cycle_rank=map_cycle_rank(graph),
        map_place_cycle_rank=map_place_cycle_rank(graph, at_place),
        world_cycle_rank=places.cycle_rank,
        routes=tuple(route_lengths(graph, places, origins, route_pairs, c.path_snap_m,
                                   c.min_route_m)),
        place_xy=tuple((p.kind.value, p.x_m, p.y_m) for p in places.places),
        known=tuple(a or b for a, b in zip(covered, by_exits, strict=True)),
    )


def route_pairs_from_summary(summary: Mapping[str, Any]) -> list[tuple[int, int, bool | None]]:
    """(source, target, success) of the routes an `islands explore` summary.json evaluated."""
    routes = summary.get("routes")
    if not isinstance(routes, Mapping):
        return []
    out: list[tuple[int, int, bool | None]] = []
    for k, r in enumerate(routes.get("per_route", []) or []):
        try:
            out.append((int(r["source"]), int(r["target"]), bool(r["islands_success"])))
        except (KeyError, TypeError, ValueError):
            raise WorldEvalError(f"summary.json routes.per_route[{k}]: needs source, target "
                                 "and islands_success") from None
    return out


def compact_events(events: Iterable[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Builder events as summary.json keeps them: an accepted island by id (not its model), an
    edge by its ends and length; everything else (truth_pose included) as it is."""
    out = []
    for e in events:
        d = {k: v for k, v in e.items() if k not in ("island", "edge", "legs_m")}
        island = e.get("island")
        if isinstance(island, Mapping) and "id" in island:
            d["island_id"] = island["id"]
        edge = e.get("edge")
        if isinstance(edge, Mapping):
            d["edge"] = {k: edge.get(k) for k in ("source", "target", "length_m")}
        out.append(d)
    return out


def known_free_of(spec: str | Path, resolution_m: float | None = None) -> AllowedFn | None:
    """For a world read from an occupancy image (.pgm/.png, or a map YAML naming one), its
    known-free pixels as an `AllowedFn` (the ground truth's free space stays inside what the
    map says is free: not in the unknown beyond its walls); None for other worlds."""
    path = Path(spec)
    suffix = path.suffix.lower()
    if suffix in (".pgm", ".png") and path.exists():
        cfg = ImageImportConfig(resolution_m=resolution_m if resolution_m else 0.1)
        img_path = path
    elif suffix in (".yaml", ".yml") and path.exists():
        data = read_structured(path)
        if "image" not in data:
            return None
        try:
            origin = data.get("origin", [0.0, 0.0, 0.0])
            cfg = ImageImportConfig(
                resolution_m=resolution_m if resolution_m else float(data.get("resolution", 0.1)),
                free_thresh=float(data.get("free_thresh", ImageImportConfig.free_thresh)),
                origin_x_m=float(origin[0]), origin_y_m=float(origin[1]))
        except (TypeError, ValueError, IndexError) as exc:
            raise WorldEvalError(f"{path}: bad resolution/origin/free_thresh: {exc}") from None
        img_path = Path(str(data["image"]))
        img_path = img_path if img_path.is_absolute() else path.parent / img_path
    else:
        return None
    img = read_pgm(img_path) if img_path.suffix.lower() == ".pgm" else read_png(img_path)
    free = (255.0 - img[::-1, :].astype(np.float64)) / 255.0 < cfg.free_thresh
    return known_free_allowed(free, cfg.resolution_m, (cfg.origin_x_m, cfg.origin_y_m))
