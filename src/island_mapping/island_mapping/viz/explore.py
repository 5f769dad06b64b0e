"""Figures of an exploration run, like the paper's Fig. 4a (path and attempts) and Fig. 4b
(the topological-metric map: each island's line model in its own frame, laid out for clarity).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from island_msgs_py.types import FloatArray

from island_mapping.core.graph import TopoGraph
from island_mapping.viz import draw_walls, pyplot, save_figure

WALL_COLOUR = "0.55"
ACCEPTED_COLOUR = "tab:green"
DISMISSED_COLOUR = "tab:orange"
FAILED_COLOUR = "tab:red"
REVISITED_COLOUR = "tab:purple"
DPI = 130
LAYOUT_GAP_M = 2.0
"""Space between two islands' drawings in the topology figure [m]."""


def _save(fig: Any, path: Path) -> Path:
    return save_figure(fig, path, dpi=DPI)


def _attempt_windows(events: Sequence[dict[str, Any]]) -> list[tuple[float, float, str]]:
    """(t_start, t_end, outcome) of each star attempt or revisit docking, until the robot was
    handed back: 'accepted', 'dismissed' or 'revisited'."""
    out: list[tuple[float, float, str]] = []
    start: float | None = None
    outcome = ""
    for e in events:
        kind = e.get("kind")
        t = float(e.get("t_s", 0.0))
        if kind == "attempt_started":
            start, outcome = t, ""
        elif kind == "island_accepted":
            outcome = "accepted"
        elif kind == "attempt_dismissed":
            outcome = "dismissed"
        elif kind == "island_revisited":
            start = t if start is None else start
            outcome = "revisited"
        elif kind == "handed_back" and start is not None:
            out.append((start, t, outcome or "dismissed"))
            start = None
        if kind == "attempt_failed_at_once":
            start = None
    return out


def exploration_figure(
    segments: FloatArray,
    truth_path: FloatArray,
    events: Sequence[dict[str, Any]],
    path: Path,
    title: str = "",
) -> Path:
    """Fig. 4a: world walls, the true path, dots where an attempt failed at once, full stars
    (green) where an island was built, partial stars (orange) where an attempt was dismissed.
    `truth_path` rows are (t [s], x [m], y [m], theta [rad])."""
    fig, ax = pyplot().subplots(figsize=(10, 7))
    draw_walls(ax, segments, color=WALL_COLOUR, linewidth=1.0)
    if truth_path.shape[0]:
        ax.plot(truth_path[:, 1], truth_path[:, 2], color="tab:blue", lw=0.6, alpha=0.6,
                label="path (ground truth)")
    t = truth_path[:, 0] if truth_path.shape[0] else np.zeros(0)
    for t0, t1, outcome in _attempt_windows(events):
        sel = (t >= t0) & (t <= t1)
        colour = {"accepted": ACCEPTED_COLOUR, "revisited": REVISITED_COLOUR}.get(
            outcome, DISMISSED_COLOUR)
        ax.plot(truth_path[sel, 1], truth_path[sel, 2], color=colour, lw=1.6)
    failed = [e["truth_pose"] for e in events
              if e.get("kind") == "attempt_failed_at_once" and "truth_pose" in e]
    if failed:
        ax.scatter([p["x"] for p in failed], [p["y"] for p in failed], s=28, color=FAILED_COLOUR,
                   zorder=5, label="attempt failed at once")
    for e in events:
        if e.get("kind") == "island_accepted" and e.get("island", {}).get("origin_truth"):
            o = e["island"]["origin_truth"]
            ax.scatter([o["x"]], [o["y"]], s=60, marker="*", color="k", zorder=6)
            ax.annotate(str(e["island"]["id"]), (o["x"], o["y"]), xytext=(4, 4),
                        textcoords="offset points", fontsize=8)
    ax.plot([], [], color=ACCEPTED_COLOUR, lw=1.6, label="full star: island built")
    ax.plot([], [], color=DISMISSED_COLOUR, lw=1.6, label="partial star: dismissed")
    revisits = [e["truth_pose"] for e in events
                if e.get("kind") == "island_revisited" and "truth_pose" in e]
    if revisits:
        ax.scatter([p["x"] for p in revisits], [p["y"] for p in revisits], s=70, marker="s",
                   facecolors="none", edgecolors=REVISITED_COLOUR, zorder=6,
                   label="known island recognised (revisit)")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title or "Exploration path and island attempts (cf. paper Fig. 4a)")
    ax.legend(loc="upper right", fontsize=7, framealpha=0.85)
    return _save(fig, path)


def _grid_layout(ids: Sequence[int], cell_m: float) -> dict[int, tuple[float, float]]:
    """Display positions on a grid, islands in id order row by row (the exploration order).
    There is no global frame: the layout only keeps the drawings apart."""
    cols = max(1, math.ceil(math.sqrt(len(ids))))
    return {i: ((k % cols) * cell_m, -(k // cols) * cell_m) for k, i in enumerate(sorted(ids))}


def topology_figure(graph: TopoGraph, path: Path, title: str = "") -> Path:
    """Fig. 4b: every island's line model drawn in its own frame (x axis = the island's heading
    0) on a display grid, with the links numbered as in strategies.txt."""
    extent = max([float(np.abs(i.model.segments).max()) if len(i.model) else 1.0
                  for i in graph.islands()] or [1.0])
    pos = _grid_layout(graph.island_ids(), cell_m=2.0 * extent + LAYOUT_GAP_M)
    cols = max(1, math.ceil(math.sqrt(max(1, len(pos)))))
    fig, ax = pyplot().subplots(figsize=(min(4.0 * cols, 20.0), min(4.0 * cols, 20.0)))
    for k, e in enumerate(graph.edges()):
        if e.source in pos and e.target in pos:
            (x0, y0), (x1, y1) = pos[e.source], pos[e.target]
            ax.annotate("", xy=(x1, y1), xytext=(x0, y0),
                        arrowprops={"arrowstyle": "->", "color": "tab:blue", "lw": 0.8,
                                    "alpha": 0.6, "connectionstyle": "arc3,rad=0.15"})
            ax.text((x0 + x1) / 2, (y0 + y1) / 2, f"L{k}", fontsize=8, color="tab:blue")
    for isl in graph.islands():
        x, y = pos[isl.id]
        for x1, y1, x2, y2 in isl.model.segments:
            ax.plot([x + x1, x + x2], [y + y1, y + y2], color="k", lw=1.0)
        ax.scatter([x], [y], s=25, color="tab:red", zorder=5)
        ax.arrow(x, y, 0.8, 0.0, width=0.05, color="tab:red", length_includes_head=True)
        ax.annotate(f"{isl.id} ({isl.model_type.value}, {isl.r:.2f})", (x, y), xytext=(4, -10),
                    textcoords="offset points", fontsize=7)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_xlabel("each island in its own frame (red arrow: its x axis, 1 m); laid out on a grid "
                  "for clarity, no global frame; links L<k> as in strategies.txt")
    ax.set_title(title or "Topological-metric map: islands of reliability (cf. paper Fig. 4b)")
    return _save(fig, path)


def strategies_table(graph: TopoGraph) -> str:
    """Table 1 of the paper: one line per link with its control strategy."""
    lines = ["Link\tFrom\tTo\tLength [m]\tWeight\tControl Strategies"]
    for k, e in enumerate(graph.edges()):
        lines.append(
            f"{k}\t{e.source}\t{e.target}\t{e.length_m:.2f}\t{e.weight:.2f}\t{e.strategy}"
        )
    return "\n".join(lines) + "\n"
