"""The ground-truth places of a world, and which of them a map covers (`places.png`)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from island_msgs_py.types import FloatArray, Pose2D
from island_sim.core.places import WorldPlaceKind, WorldPlaces

from island_mapping.viz import draw_walls, pyplot, save_figure

DPI = 130
FREE_COLOUR = "#d9ead3"
SKELETON_COLOUR = "tab:blue"
PLACE_COLOUR = {WorldPlaceKind.JUNCTION: "tab:red", WorldPlaceKind.END: "tab:purple"}
COVERED_COLOUR = "tab:green"
MISSED_COLOUR = "tab:red"
MARKER = {WorldPlaceKind.JUNCTION: "s", WorldPlaceKind.END: "o"}
FIGURE_WIDTH_IN = 10.0


def places_figure(
    segments: FloatArray,
    places: WorldPlaces,
    path: str | Path,
    title: str = "",
    covered: Sequence[bool] | None = None,
    islands_xy_m: FloatArray | None = None,
    start: Pose2D | None = None,
) -> Path:
    """Walls, the reachable free space, its pruned skeleton and the places (squares:
    junctions, circles: ends). With `covered` (one flag per place) a place is green when an
    island covers it and red when missed; `islands_xy_m` (K, 2) marks island origins [m]."""
    plt = pyplot()
    r = places.space.raster
    h, w = r.shape
    x0, y0 = r.origin_m
    extent = (x0, x0 + w * r.resolution_m, y0, y0 + h * r.resolution_m)
    aspect = (extent[3] - extent[2]) / max(extent[1] - extent[0], 1e-9)
    fig, ax = plt.subplots(figsize=(FIGURE_WIDTH_IN, max(3.0, FIGURE_WIDTH_IN * aspect)))
    rgba = np.zeros((h, w, 4))
    rgba[places.space.reachable] = (0.85, 0.92, 0.83, 1.0)
    ax.imshow(rgba, origin="lower", extent=extent, interpolation="nearest")
    ii, jj = np.nonzero(places.skeleton)
    sk = r.centres_m(ii, jj)
    ax.plot(sk[:, 0], sk[:, 1], ",", color=SKELETON_COLOUR, alpha=0.6)
    draw_walls(ax, segments, linewidth=0.8)
    _draw_places(ax, places, covered)
    if islands_xy_m is not None and len(islands_xy_m):
        xy = np.asarray(islands_xy_m, dtype=np.float64).reshape(-1, 2)
        ax.plot(xy[:, 0], xy[:, 1], "x", color="black", markersize=6, label="island origins")
    if start is not None:
        ax.plot(start.x, start.y, "*", color="orange", markersize=14, label="start")
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, framealpha=0.8)
    n_j = len(places.junctions)
    head = (f"{len(places.places)} places ({n_j} junctions, {len(places.places) - n_j} ends), "
            f"cycle rank {places.cycle_rank}")
    ax.set_title(f"{title}\n{head}" if title else head, fontsize=9)
    return save_figure(fig, path, dpi=DPI)


def _draw_places(ax: Any, places: WorldPlaces, covered: Sequence[bool] | None) -> None:
    labelled: set[str] = set()
    for k, p in enumerate(places.places):
        if covered is None:
            colour = PLACE_COLOUR[p.kind]
            label = p.kind.value
        else:
            colour = COVERED_COLOUR if covered[k] else MISSED_COLOUR
            label = f"{p.kind.value}, {'covered' if covered[k] else 'missed'}"
        ax.plot(p.x_m, p.y_m, MARKER[p.kind], color=colour, markersize=7,
                markeredgecolor="black", markeredgewidth=0.5,
                label=None if label in labelled else label)
        labelled.add(label)
