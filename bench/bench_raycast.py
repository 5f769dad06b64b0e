"""Ray casts per second: spatial index vs brute force, side by side, in paper_fig4 and Willow.

  python bench/bench_raycast.py [--poses N] [--willow PATH]

Workloads (the same rays for both casters, checked to give identical hits):
- sonar: one 16-transducer x 5-ray scan per pose, max range 6.5 m, one call per scan (how the
  sonar node uses it), over N random poses in free space;
- batch: all those rays in a single call, with the sonar's 6.5 m limit (how the measure maps and
  the validation use it) and with unlimited range.
The index is warmed by a first pass; its cold (first-use) time is printed too.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
from island_msgs_py.raycast import raycast
from island_msgs_py.types import Pose2D
from island_sim.core.sonar import SonarConfig, SonarModel
from island_sim.core.world import World
from island_sim.core.world_loader import load_world
from island_sim.core.worlds_builtin import BUILTIN_FREE_RECTS

DEFAULT_WILLOW = Path(__file__).resolve().parents[2] / "shared/data/floorplans/willow-full.pgm"


def _fig4_poses(n: int, rng: np.random.Generator) -> np.ndarray:
    rects = np.array(BUILTIN_FREE_RECTS["paper_fig4"](), dtype=np.float64)
    area = (rects[:, 2] - rects[:, 0]) * (rects[:, 3] - rects[:, 1])
    k = rng.choice(rects.shape[0], n, p=area / area.sum())
    r = rects[k]
    x = rng.uniform(r[:, 0] + 0.3, np.maximum(r[:, 2] - 0.3, r[:, 0] + 0.31))
    y = rng.uniform(r[:, 1] + 0.3, np.maximum(r[:, 3] - 0.3, r[:, 1] + 0.31))
    return np.stack([x, y, rng.uniform(-math.pi, math.pi, n)], axis=1)


def _enclosed_poses(world: World, n: int, rng: np.random.Generator) -> np.ndarray:
    """Random poses whose 8 axis rays all hit a wall at >= 0.4 m (inside the building)."""
    x0, y0, x1, y1 = world.bounds
    out: list[np.ndarray] = []
    dirs = np.linspace(0, 2 * math.pi, 8, endpoint=False)
    while sum(len(o) for o in out) < n:
        pts = np.stack([rng.uniform(x0, x1, 4 * n), rng.uniform(y0, y1, 4 * n)], axis=1)
        d = world.raycast(np.repeat(pts, 8, axis=0), np.tile(dirs, pts.shape[0])).distance_m
        ok = np.all(np.isfinite(d.reshape(-1, 8)) & (d.reshape(-1, 8) >= 0.4), axis=1)
        out.append(pts[ok])
    pts = np.vstack(out)[:n]
    return np.hstack([pts, rng.uniform(-math.pi, math.pi, (n, 1))])


def _scan_rays(model: SonarModel, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    c = model.config
    axis = pose[2] + model.angles_rad
    k = model.ray_offsets_rad.size
    rr = c.ring_radius_m
    o = np.stack([pose[0] + rr * np.cos(axis), pose[1] + rr * np.sin(axis)], axis=1)
    ang = (axis[:, None] + model.ray_offsets_rad[None, :]).ravel()
    return np.repeat(o, k, axis=0), ang


def bench(world: World, poses: np.ndarray) -> None:
    model = SonarModel(SonarConfig())
    rays = [_scan_rays(model, p) for p in poses]
    n_rays = sum(a.size for _, a in rays)
    fresh = World(world.segments, name=world.name)  # a cold index

    t = time.perf_counter()
    for o, a in rays:
        fresh.raycast(o, a, 6.5)
    cold = time.perf_counter() - t
    t = time.perf_counter()
    fast = [fresh.raycast(o, a, 6.5).distance_m for o, a in rays]
    warm = time.perf_counter() - t
    t = time.perf_counter()
    slow = [raycast(world.segments, o, a, 6.5).distance_m for o, a in rays]
    brute = time.perf_counter() - t
    assert all(np.array_equal(f, s) for f, s in zip(fast, slow, strict=True))

    allo = np.vstack([o for o, _ in rays])
    alla = np.concatenate([a for _, a in rays])
    batch: dict[float, tuple[float, float]] = {}
    for max_range in (6.5, np.inf):
        t = time.perf_counter()
        fb = fresh.raycast(allo, alla, max_range)
        batch_fast = time.perf_counter() - t
        t = time.perf_counter()
        sb = raycast(world.segments, allo, alla, max_range)
        batch_brute = time.perf_counter() - t
        assert np.array_equal(fb.distance_m, sb.distance_m)
        assert np.array_equal(fb.segment, sb.segment)
        batch[max_range] = (batch_fast, batch_brute)

    t = time.perf_counter()
    for p in poses:
        model.scan(fresh, Pose2D.from_array(p))
    scans = time.perf_counter() - t

    print(f"{world.name}: {world.segments.shape[0]} segments, {len(poses)} poses, {n_rays} rays")
    print(
        f"  per scan,  6.5 m    : index {n_rays / warm:10.0f} rays/s (cold {n_rays / cold:.0f}) "
        f"| brute {n_rays / brute:10.0f} rays/s | speed-up x{brute / warm:.1f}"
    )
    for max_range, (bf, bb) in batch.items():
        label = f"{max_range:.1f} m" if np.isfinite(max_range) else "unlimited"
        print(
            f"  one batch, {label:9s}: index {n_rays / bf:10.0f} rays/s "
            f"| brute {n_rays / bb:10.0f} rays/s | speed-up x{bb / bf:.1f}"
        )
    print(f"  SonarModel.scan: {len(poses) / scans:.0f} scans/s (16 transducers x 5 rays)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=300)
    parser.add_argument("--willow", type=Path, default=DEFAULT_WILLOW)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    fig4 = load_world("paper_fig4")
    bench(fig4, _fig4_poses(args.poses, rng))
    if args.willow.is_file():
        willow = load_world(args.willow)
        bench(willow, _enclosed_poses(willow, args.poses, rng))
    else:
        print(f"(Willow map not found at {args.willow}: skipped)")


if __name__ == "__main__":
    main()
