"""The builder hooks an explorer installs (`core.builder.hooks.BuilderHooks`): managed mode,
exits found from the star's evidence, and the loop-closure gate on recognitions."""

from __future__ import annotations

import math
from collections.abc import Callable

from island_msgs_py.types import Exit, FloatArray, Island

from island_mapping.core.builder.hooks import BuilderHooks
from island_mapping.core.builder.recognition import PoseSnapshot, Recognition
from island_mapping.core.explore.config import ExplorerConfig
from island_mapping.core.explore.exits import ExitEvidence, find_exits
from island_mapping.core.graph import TopoGraph


def explorer_hooks(cfg: ExplorerConfig, graph: Callable[[], TopoGraph]) -> BuilderHooks:
    """Managed mode with `find_exits` (cfg.exit) and a revisit gate: a recognised island is
    docked onto only from its place (within revisit_near_m of its origin); `graph` returns
    the latest map."""

    def exits(segments: FloatArray, points: FloatArray, driven: FloatArray,
              arrival_rad: float | None) -> tuple[Exit, ...]:
        return find_exits(ExitEvidence(segments, points, driven, arrival_rad), cfg.exit)

    def near(rec: Recognition, snap: PoseSnapshot, island: Island, star: bool) -> bool:
        del snap, island, star
        return math.hypot(rec.pose.x, rec.pose.y) <= cfg.revisit_near_m

    del graph
    return BuilderHooks(managed=True, find_exits=exits, accept_revisit=near,
                        arrival_match_deg=cfg.exit.arrival_match_deg)
