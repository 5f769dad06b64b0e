"""`islands measure`: the distinctiveness measure R (or the Fisher score) at points of a world.

  islands measure --world FILE --at X,Y [--at X,Y ...] [--k K] [--c C] [--m M]
                  [--reflect-deg D] [--max-range M] [--angular-res-deg D] [--eps M]
                  [--eps-step M] [--model line|fisher] [--std-ref M]

Prints one JSON object per line per point, in the order given.
--model line (default): {"x", "y", "c_par", "c_perp", "q", "f", "r"} with c_par and c_perp
  UNFILTERED (eqs. 9, 10), q and f from the filtered pair (eqs. 11, 12, 5) and r = R(p, eps)
  (eq. 4; r at p when --eps is 0, the default; with --eps > 0 also "r_point", r at p).
--model fisher: the same keys where meaningful: c_par = lambda_max and c_perp = lambda_min, the
  eigenvalues of the position information (heading marginalized) [1/m^2]; q = lambda_min /
  lambda_max; f = the sigmoid of lambda_min; r = "score" = f (1 + q) / 2; plus "score",
  "min_eig" [1/m^2] and "cond" (null when infinite). --k, --c and --eps do not apply to it;
  --m and --std-ref set its sigmoid.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
from typing import Any

import numpy as np

from island_mapping.cli import CliError
from island_mapping.cli.args import METRES, coordinates
from island_mapping.core.fisher import FisherConfig, FisherError, fisher_measure
from island_mapping.core.fisher import translational_information as _trans_info
from island_mapping.core.measure import MeasureConfig, MeasureError, line_measure


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = __doc__
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    d = MeasureConfig()
    fd = FisherConfig()
    parser.add_argument("--world", required=True,
                        help="world file (YAML/JSON segments, HouseExpo JSON, map image) or a "
                             "built-in name (paper_fig3, paper_fig4, ...)")
    parser.add_argument("--at", action="append", required=True, metavar="X,Y",
                        help="a point in the world frame [m]; repeat for more points")
    parser.add_argument("--model", choices=("line", "fisher"), default="line",
                        help="line: R of the line model (eqs. 4-12); fisher: the Fisher score")
    parser.add_argument("--k", type=float, default=d.k, help=_help(MeasureConfig, "k"))
    parser.add_argument("--c", type=float, default=d.c, help=_help(MeasureConfig, "c"))
    parser.add_argument("--m", type=float, default=None,
                        help=f"{_help(MeasureConfig, 'm')}; for fisher the score's exponent "
                             f"(default {d.m} line, {fd.m} fisher)")
    parser.add_argument("--std-ref", type=float, default=fd.std_ref_m,
                        help=f"fisher only: {_help(FisherConfig, 'std_ref_m')}")
    parser.add_argument("--reflect-deg", type=float, default=d.reflect_deg,
                        help=_help(MeasureConfig, "reflect_deg"))
    parser.add_argument("--max-range", type=float, default=d.max_range_m,
                        help=_help(MeasureConfig, "max_range_m"))
    parser.add_argument("--angular-res-deg", type=float, default=d.angular_res_deg,
                        help=_help(MeasureConfig, "angular_res_deg"))
    parser.add_argument("--eps", type=float, default=d.eps_m, help=_help(MeasureConfig, "eps_m"))
    parser.add_argument("--eps-step", type=float, default=d.eps_step_m,
                        help=_help(MeasureConfig, "eps_step_m"))
    parser.add_argument("--resolution", type=METRES, default=None,
                        help="m/px for image worlds (default 0.1)")


def _help(cls: type, name: str) -> str:
    for f in dataclasses.fields(cls):
        if f.name == name:
            return f"{f.metadata.get('help', name)} (default {f.default})"
    return name


def parse_point(text: str) -> tuple[float, float]:
    """'X,Y' -> (x, y) [m], finite and within MAX_COORD_M; CliError naming the text otherwise."""
    x, y = coordinates(text, "--at", ("X", "Y"))
    return x, y


def load_world_or_fail(spec: str, resolution_m: float | None = None) -> Any:
    """The world of `spec` (file or built-in name), or a CliError with the loader's message."""
    from island_sim.core.world import WorldError
    from island_sim.core.world_loader import load_world

    try:
        world = load_world(spec, resolution_m)
    except WorldError as exc:
        raise CliError(str(exc)) from None
    except OSError as exc:
        raise CliError(f"{spec}: cannot read: {exc}") from None
    if world.segments.shape[0] == 0:
        raise CliError(f"{spec}: the world has no walls")
    return world


def _num(v: float) -> float | None:
    return round(float(v), 6) if math.isfinite(v) else None


def run(args: argparse.Namespace) -> int:
    points = np.array([parse_point(t) for t in args.at], dtype=np.float64)
    world = load_world_or_fail(args.world, args.resolution)
    rows: list[dict[str, Any]] = []
    if args.model == "line":
        try:
            cfg = MeasureConfig(
                k=args.k, c=args.c, m=args.m if args.m is not None else MeasureConfig().m,
                reflect_deg=args.reflect_deg, max_range_m=args.max_range,
                angular_res_deg=args.angular_res_deg, eps_m=args.eps, eps_step_m=args.eps_step,
            )
        except MeasureError as exc:
            raise CliError(str(exc)) from None
        res = line_measure(world, points, cfg)
        for i, (x, y) in enumerate(points):
            row: dict[str, Any] = {
                "x": float(x), "y": float(y), "c_par": _num(res.c_par[i]),
                "c_perp": _num(res.c_perp[i]), "q": _num(res.q[i]), "f": _num(res.f[i]),
                "r": _num(res.r_eps[i]),
            }
            if cfg.eps_m > 0:
                row["r_point"] = _num(res.r[i])
            rows.append(row)
    else:
        if args.eps != 0:
            raise CliError("--eps applies to --model line only")
        try:
            fcfg = FisherConfig(
                m=args.m if args.m is not None else FisherConfig().m, std_ref_m=args.std_ref,
                reflect_deg=args.reflect_deg, max_range_m=args.max_range,
                angular_res_deg=args.angular_res_deg,
            )
        except FisherError as exc:
            raise CliError(str(exc)) from None
        fres = fisher_measure(world, points, fcfg)
        evals = np.linalg.eigvalsh(_trans_info(fres.info))
        for i, (x, y) in enumerate(points):
            lo, hi = float(fres.min_eig[i]), max(0.0, float(evals[i, 1]))
            q = lo / hi if hi > 0 else 0.0
            f = 1.0 / (1.0 + (1.0 / fcfg.std_ref_m**2 / lo) ** fcfg.m) if lo > 0 else 0.0
            rows.append({
                "x": float(x), "y": float(y), "c_par": _num(hi), "c_perp": _num(lo),
                "q": _num(q), "f": _num(f), "r": _num(fres.score[i]),
                "score": _num(fres.score[i]), "min_eig": _num(lo), "cond": _num(fres.cond[i]),
            })
    for row in rows:
        print(json.dumps(row))
    return 0
