"""`islands fig3`: R map, localization-confidence map and residual plot (paper Figs. 3a, 3c, 2).

  islands fig3 --world FILE --out DIR [--resolution M] [--seed N] [--trials N]
               [--map-resolution M] [--params METRICS_JSON] [--no-fit]

Writes into DIR:
- r_map.png: R (eps = 0) of the world's walls on a --map-resolution grid inside the walls;
- fisher_map.png: the Fisher score on the same grid;
- confidence_map.png: localization confidence (simulated sonar, 10-15 cm offsets, --trials per
  point) on the --resolution grid;
- residual.png: points whose |normalized measure - confidence| exceeds a value (Fig. 2), both
  models; scatter_line.png, scatter_fisher.png;
- metrics.json: for "line" and "fisher": frac_residual_gt_0_4, spearman, auc, params (the
  parameters used), and "fitted" (parameters fit on THIS world and their metrics); the
  confidence summary and how both maps were normalized.
--params takes a metrics.json of another world and uses its fitted parameters (to report on a
world the parameters were not tuned on). A progress bar goes to stderr.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace
from typing import Any

from island_msgs_py.inputs import read_json

from island_mapping.cli import CliError
from island_mapping.cli.args import METRES, POSITIVE_COUNT, SEED, check_output_dir
from island_mapping.cli.measure import load_world_or_fail
from island_mapping.cli.progress import ProgressBar
from island_mapping.core.fisher import FisherConfig, FisherError
from island_mapping.core.measure import MeasureConfig, MeasureError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = __doc__
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.add_argument("--world", required=True, help="world file or built-in name")
    parser.add_argument("--out", required=True, help="output directory")
    parser.add_argument("--resolution", type=METRES, default=0.5,
                        help="grid of the confidence map and of the comparison [m]")
    parser.add_argument("--map-resolution", type=METRES, default=0.25,
                        help="grid of the R and Fisher map pictures [m]")
    parser.add_argument("--seed", type=SEED, default=0, help="seed of the simulated trials")
    parser.add_argument("--trials", type=POSITIVE_COUNT, default=3,
                        help="localization trials per point")
    parser.add_argument("--params", default=None,
                        help="metrics.json of another run: use its fitted parameters")
    parser.add_argument("--no-fit", action="store_true",
                        help="skip fitting c, m, k (and the Fisher score) on this world")


def _configs_from(path: str) -> tuple[MeasureConfig, FisherConfig]:
    data = read_json(path, CliError, what="--params metrics.json")
    try:
        lp = data["line"]["fitted"]["params"]
        fp = data["fisher"]["fitted"]["params"]
        line = replace(MeasureConfig(), k=float(lp["k"]), c=float(lp["c"]), m=float(lp["m"]))
        fisher = replace(FisherConfig(), std_ref_m=float(fp["std_ref_m"]), m=float(fp["m"]))
    except (ValueError, KeyError, TypeError, OverflowError) as exc:
        raise CliError(
            f"--params {path}: not a fig3 metrics.json with line/fisher fitted params ({exc})"
        ) from None
    except (MeasureError, FisherError) as exc:
        raise CliError(f"--params {path}: {exc}") from None
    return line, fisher


def run(args: argparse.Namespace) -> int:
    from island_msgs_py.json_io import atomic_write_text

    from island_mapping.core.fisher import fisher_measure
    from island_mapping.core.measure import grid_points, inside_outline, line_measure
    from island_mapping.evaluation.validation import (
        ValidationConfig,
        ValidationError,
        normalize,
        residuals,
        run_validation,
    )
    from island_mapping.viz.fig3 import plot_map, plot_residuals, plot_scatter

    for name in ("resolution", "map_resolution"):
        v = getattr(args, name)
        if not (math.isfinite(v) and v > 0):
            raise CliError(f"--{name.replace('_', '-')}: expected a number > 0, got {v}")
    if args.trials < 1:
        raise CliError(f"--trials: expected >= 1, got {args.trials}")
    out = check_output_dir(args.out)
    world = load_world_or_fail(args.world)
    line_cfg, fisher_cfg = (
        _configs_from(args.params) if args.params else (MeasureConfig(), FisherConfig())
    )
    vcfg = ValidationConfig(resolution_m=args.resolution, trials=args.trials, seed=args.seed)
    try:
        report = run_validation(world, vcfg, line_cfg, fisher_cfg, fit=not args.no_fit,
                                progress=ProgressBar("confidence map"))
    except ValidationError as exc:
        raise CliError(str(exc)) from None
    metrics: dict[str, Any] = dict(report.metrics)
    metrics["params_source"] = args.params or "defaults"

    # Dense pictures of both measures (inside the walls only).
    xs, ys, pts = grid_points(world.bounds, args.map_resolution)
    inside = inside_outline(world, pts)
    r_grid = _grid_values(pts, inside, lambda p: line_measure(world, p, line_cfg).r, ProgressBar(
        "R map"))
    f_grid = _grid_values(pts, inside, lambda p: fisher_measure(world, p, fisher_cfg).score,
                          ProgressBar("Fisher map"))
    shape = (ys.shape[0], xs.shape[0])
    out.mkdir(parents=True, exist_ok=True)
    segs = world.segments
    plot_map(xs, ys, r_grid.reshape(shape), segs, out / "r_map.png",
             f"distinctiveness measure R, {world.name}", "R (eps = 0)", vmax=1.0)
    plot_map(xs, ys, f_grid.reshape(shape), segs, out / "fisher_map.png",
             f"Fisher score, {world.name}", "score", vmax=1.0)
    plot_map(report.xs, report.ys, report.confidence_map, segs, out / "confidence_map.png",
             f"localization confidence, {world.name}", "confidence (c - error) / c", vmax=1.0)
    conf = report.confidence
    plot_residuals(
        {"line R": residuals(report.r_values, conf),
         "Fisher": residuals(report.fisher_values, conf)},
        out / "residual.png", f"residuals, {world.name} ({conf.points.shape[0]} points)",
    )
    plot_scatter(normalize(report.r_values), conf.confidence, out / "scatter_line.png",
                 f"R vs confidence, {world.name}")
    plot_scatter(normalize(report.fisher_values), conf.confidence, out / "scatter_fisher.png",
                 f"Fisher score vs confidence, {world.name}")
    atomic_write_text(out / "metrics.json", json.dumps(metrics, indent=1) + "\n")
    summary = {m: {k: metrics[m][k] for k in ("frac_residual_gt_0_4", "spearman", "auc")}
               for m in ("line", "fisher")}
    print(json.dumps({"world": world.name, "n_points": metrics["n_points"], **summary}))
    return 0


def _grid_values(pts: Any, inside: Any, fn: Any, progress: ProgressBar,
                 chunk: int = 2000) -> Any:
    import numpy as np

    values = np.full(pts.shape[0], np.nan)
    idx = np.flatnonzero(inside)
    for s in range(0, idx.size, chunk):
        sel = idx[s : s + chunk]
        values[sel] = fn(pts[sel])
        progress(min(s + chunk, idx.size), idx.size)
    if idx.size == 0:
        progress(0, 0)
    return values
