"""Figures of the real-data runs: islands like the paper's Fig. 5b, and R on the sonar ring."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from island_mapping.core.builder.passive import PassiveIsland
from island_mapping.core.sonar_ring import RingScores, SonarReadings
from island_mapping.viz import pyplot, save_figure

# Islands per row of the Fig. 5b-like layout, and the gap between their boxes [m].
_MAX_COLUMNS = 10
_GAP_M = 2.0


def island_layout(islands: Sequence[PassiveIsland]) -> list[tuple[float, float]]:
    """Offsets [m] that place each island's model (in its own frame) in a grid, for clarity
    only (no global frame exists): cells as large as most of the models (the 90th percentile
    of endpoint distances from the origins; a few far segments may reach a neighbour's cell)
    plus a gap."""
    if not islands:
        return []
    coords = [np.abs(i.island.model.segments).ravel() for i in islands if len(i.island.model)]
    half = max(1.0, float(np.percentile(np.concatenate(coords), 90))) if coords else 1.0
    cell = 2.0 * half + _GAP_M
    cols = min(_MAX_COLUMNS, max(1, math.ceil(math.sqrt(len(islands)))))
    return [(cell * (k % cols), -cell * (k // cols)) for k in range(len(islands))]


def plot_islands(
    islands: Sequence[PassiveIsland], path: str | os.PathLike[str], title: str = ""
) -> Path:
    """Each island's line model drawn in its own frame, a dot at its origin, laid out in a grid
    (like the paper's Fig. 5b); the island id and its best normalized measure label each."""
    plt = pyplot()
    offsets = island_layout(islands)
    fig, ax = plt.subplots(figsize=(10, 10))
    colours = {"line": "tab:blue", "fisher": "tab:green"}
    for isl, (ox, oy) in zip(islands, offsets, strict=True):
        seg = isl.island.model.segments
        colour = colours.get(isl.island.model_type.value, "tab:blue")
        for x1, y1, x2, y2 in seg:
            ax.plot([x1 + ox, x2 + ox], [y1 + oy, y2 + oy], color=colour, lw=1.0)
        ax.plot([ox], [oy], "o", color="tab:red", ms=4)
        ax.plot([ox, ox + 1.0], [oy, oy], color="tab:red", lw=1.5)  # the frame's x axis, 1 m
        ax.annotate(f"{isl.island.id}", (ox, oy), textcoords="offset points", xytext=(4, 4),
                    fontsize=7)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m] (each island in its own frame, offsets for clarity)")
    ax.set_ylabel("y [m]")
    text = title or f"{len(islands)} islands (blue: line model R, green: Fisher)"
    ax.set_title(text)
    fig.tight_layout()
    out = save_figure(fig, path, title=text)
    return out


def plot_ring_scores(
    readings: SonarReadings, scores: RingScores, path: str | os.PathLike[str]
) -> Path:
    """Box plot of R per motion label and R over the reading index coloured by label."""
    plt = pyplot()
    labels = np.asarray(readings.labels)
    names = sorted(set(readings.labels))
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(11, 8))
    ax1.boxplot([scores.r[labels == n] for n in names], tick_labels=names)
    ax1.set_ylabel("R at the robot [-]")
    ax1.set_title("Line-model measure R of single 24-sonar readings per recorded motion")
    cmap = plt.get_cmap("tab10")
    idx = np.arange(labels.size)
    for k, n in enumerate(names):
        sel = labels == n
        ax2.scatter(idx[sel], scores.r[sel], s=3, color=cmap(k % 10), label=n)
    ax2.set_xlabel("reading index (9 Hz)")
    ax2.set_ylabel("R [-]")
    ax2.legend(markerscale=4, fontsize=8, loc="lower right")
    fig.tight_layout()
    out = save_figure(fig, path)
    return out
