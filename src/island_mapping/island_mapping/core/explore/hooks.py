"""The builder hooks an explorer installs (`core.builder.hooks.BuilderHooks`): managed mode,
exits found from the star's evidence, and the loop-closure gate on recognitions."""

from __future__ import annotations

from collections.abc import Callable

from island_msgs_py.types import Exit, FloatArray

from island_mapping.core.builder.hooks import BuilderHooks
from island_mapping.core.explore.config import ExplorerConfig
from island_mapping.core.explore.exits import ExitEvidence, find_exits
from island_mapping.core.graph import TopoGraph


def explorer_hooks(cfg: ExplorerConfig, graph: Callable[[], TopoGraph]) -> BuilderHooks:
    """Managed mode with `find_exits` (cfg.exit); `graph` returns the latest map."""

    def exits(segments: FloatArray, points: FloatArray, driven: FloatArray,
              arrival_rad: float | None) -> tuple[Exit, ...]:
        return find_exits(ExitEvidence(segments, points, driven, arrival_rad), cfg.exit)

    del graph
    return BuilderHooks(managed=True, find_exits=exits,
                        arrival_match_deg=cfg.exit.arrival_match_deg)
