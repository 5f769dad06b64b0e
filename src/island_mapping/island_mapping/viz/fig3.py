"""Figures of the measure validation, like the paper's Figs. 3a (R map), 3c (localization
confidence) and 2 (residual plot). Matplotlib with the Agg backend; files written atomically."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import numpy.typing as npt
from island_msgs_py.types import FloatArray

from island_mapping.viz import draw_walls, pyplot, save_figure


def plot_map(
    xs: FloatArray,
    ys: FloatArray,
    grid: FloatArray,
    segments: FloatArray,
    path: str | os.PathLike[str],
    title: str,
    label: str,
    vmin: float = 0.0,
    vmax: float | None = None,
) -> Path:
    """A (ny, nx) map on cell centres xs, ys [m] with the walls on top, axes in metres."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.0, 6.0))
    dx = float(xs[1] - xs[0]) if xs.shape[0] > 1 else 1.0
    dy = float(ys[1] - ys[0]) if ys.shape[0] > 1 else 1.0
    extent = (xs[0] - dx / 2, xs[-1] + dx / 2, ys[0] - dy / 2, ys[-1] + dy / 2)
    masked = np.ma.masked_invalid(grid)
    top = vmax if vmax is not None else (float(np.nanmax(grid)) if np.any(np.isfinite(grid))
                                         else 1.0)
    im = ax.imshow(masked, origin="lower", extent=extent, cmap="viridis", vmin=vmin,
                   vmax=max(top, vmin + 1e-9), interpolation="nearest")
    draw_walls(ax, segments)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")
    ax.set_title(title)
    fig.colorbar(im, ax=ax, label=label, shrink=0.85)
    fig.tight_layout()
    return save_figure(fig, path, dpi=110)


def plot_residuals(
    residuals: dict[str, npt.ArrayLike],
    path: str | os.PathLike[str],
    title: str,
    threshold: float = 0.4,
) -> Path:
    """Paper Fig. 2: number of points whose |residual| exceeds a value, against the value."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    levels = np.linspace(0.0, 1.0, 101)
    for name, res in residuals.items():
        a = np.abs(np.asarray(res, dtype=np.float64))
        counts = (a[None, :] > levels[:, None]).sum(axis=1)
        frac = float(np.mean(a > threshold)) if a.size else float("nan")
        ax.plot(levels, counts, label=f"{name} ({100 * frac:.1f}% > {threshold})")
    ax.axvline(threshold, color="grey", linestyle="--", linewidth=1)
    ax.set_xlabel("residual |normalized measure - confidence|")
    ax.set_ylabel("points with a larger residual")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    return save_figure(fig, path, dpi=110)


def plot_scatter(
    measure: npt.ArrayLike, confidence: npt.ArrayLike, path: str | os.PathLike[str], title: str
) -> Path:
    """Normalized measure against localization confidence, one dot a grid point."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(5.0, 5.0))
    ax.scatter(np.asarray(measure), np.asarray(confidence), s=6, alpha=0.5)
    ax.plot([0, 1], [0, 1], color="grey", linewidth=1)
    ax.set_xlabel("normalized measure")
    ax.set_ylabel("localization confidence")
    ax.set_xlim(-0.02, 1.02)
    ax.set_ylim(-0.02, 1.02)
    ax.set_title(title)
    fig.tight_layout()
    return save_figure(fig, path, dpi=110)
