"""Matplotlib figures (never imported by core modules)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any


def pyplot() -> Any:
    """matplotlib.pyplot on the non-interactive Agg backend (figures are files here)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def draw_walls(ax: Any, segments: Any, color: str = "black", linewidth: float = 1.2) -> None:
    """Wall segments (N, 4) [m] as lines on `ax`."""
    for x1, y1, x2, y2 in segments:
        ax.plot([x1, x2], [y1, y2], color=color, linewidth=linewidth, solid_capstyle="butt")


def save_figure(fig: Any, path: str | os.PathLike[str], dpi: int = 120,
                title: str | None = None) -> Path:
    """Save a matplotlib figure to `path` atomically (temp file in the same dir + os.replace)
    and close it; `title` is also stored in the file's metadata (a PNG `Title` text chunk),
    where a program can read it back."""
    plt = pyplot()
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=target.suffix, dir=target.parent)
    os.close(fd)
    try:
        meta = {"Title": title} if title and target.suffix.lower() == ".png" else None
        fig.savefig(tmp, dpi=dpi, bbox_inches="tight", metadata=meta)
        os.chmod(tmp, 0o644)
        os.replace(tmp, target)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    finally:
        plt.close(fig)
    return target
