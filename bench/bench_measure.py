"""Benchmark: R map points per second, vectorized measure vs a per-point per-ray Python loop.

  python bench/bench_measure.py [--world paper_fig3] [--resolution 0.1] [--baseline-points 40]

Both run in this one process on the same points: the baseline (bench/baseline_measure.py) on a
seeded sample of the map's inside points, the vectorized `line_measure` on the same sample and
on the whole map at --resolution (inside the walls). Prints points/s of both, the speed-up ratio,
the largest |r| difference on the sample (goal: >= 20x, <= 0.02), and the full map's time.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from baseline_measure import baseline_r
from island_mapping.core.measure import (
    MeasureConfig,
    grid_points,
    inside_outline,
    line_measure,
    measure_map,
)
from island_sim.core.world_loader import load_world


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", default="paper_fig3")
    ap.add_argument("--resolution", type=float, default=0.1)
    ap.add_argument("--baseline-points", type=int, default=40)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    cfg = MeasureConfig()
    world = load_world(args.world)
    _, _, pts = grid_points(world.bounds, args.resolution)
    inside = pts[inside_outline(world, pts)]
    rng = np.random.default_rng(args.seed)
    sample = inside[rng.choice(inside.shape[0], size=min(args.baseline_points, inside.shape[0]),
                               replace=False)]

    t0 = time.perf_counter()
    base = np.array([baseline_r(world.segments, float(x), float(y), cfg) for x, y in sample])
    t_base = time.perf_counter() - t0

    t0 = time.perf_counter()
    vec_sample = line_measure(world, sample, cfg).r
    t_vec_sample = time.perf_counter() - t0

    t0 = time.perf_counter()
    xs, ys, grid = measure_map(world, world.bounds, args.resolution, cfg, only_inside=True)
    t_map = time.perf_counter() - t0
    n_map = int(np.isfinite(grid).sum())

    base_pps = sample.shape[0] / t_base
    vec_pps = n_map / t_map
    result = {
        "world": world.name,
        "segments": int(world.segments.shape[0]),
        "rays_per_point": cfg.n_rays,
        "baseline_points": int(sample.shape[0]),
        "baseline_points_per_s": round(base_pps, 1),
        "vectorized_points_per_s_map": round(vec_pps, 1),
        "vectorized_points_per_s_sample": round(sample.shape[0] / t_vec_sample, 1),
        "speedup": round(vec_pps / base_pps, 1),
        "max_abs_r_diff": float(np.max(np.abs(base - vec_sample))),
        "map_resolution_m": args.resolution,
        "map_inside_points": n_map,
        "map_grid": [int(ys.shape[0]), int(xs.shape[0])],
        "map_seconds": round(t_map, 2),
    }
    print(json.dumps(result, indent=1))
    ok = result["speedup"] >= 20 and result["max_abs_r_diff"] <= 0.02
    print(f"speed-up {result['speedup']}x (goal >= 20x), max |r diff| "
          f"{result['max_abs_r_diff']:.2e} (goal <= 0.02): {'OK' if ok else 'MISSED'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
