"""`islands eval-relations`: islands built offline on a CARMEN log, scored on relations and a
reference trajectory.

  islands eval-relations --log LOG [--relations FILE] [--reference FILE] --out DIR
                         [--beams 180|24|16] [--localize-beams 24|16] [--place-recognition]
                         [--no-loop-closure] [--scan-lines FLASER|ROBOTLASER1|RLASER|SONAR]
                         [--fov-deg D --angle-min-deg A] [--time-offset-s S]
                         [--seed N] [--bridge-s S] [--max-scans N]

The scan geometry is read from the log (PARAM lines, ROBOTLASER1 fields, SONAR transducer poses,
the FLASER format's standard beam counts); what the log does not say is an error asking for
--fov-deg (and --angle-min-deg). A sonar ring is built with sonar settings. The relations'
time offset is found from the log unless --time-offset-s gives it. Writes DIR/metrics.json
(island_mapping.logs.report: relations covered inside islands, strict and bridged, with the
reference trajectory on the same relations; agreement with the reference inside islands;
islands per place) and DIR/islands.png (each island's line model in its own frame, like the
paper's Fig. 5b, titled with the log's name, the title also in the PNG's metadata), and prints
the headline figures. The pipeline is deterministic; --seed is recorded only.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from pathlib import Path
from typing import Any

from island_mapping.bag.carmen import MAX_LOG_TIME_S
from island_mapping.cli import CliError
from island_mapping.cli.args import (
    COUNT,
    SECONDS,
    SEED,
    check_output_dir,
    number,
)
from island_mapping.core.builder.passive import IslandRun
from island_mapping.logs import islands as offline

# Default bridging limit: about half the Intel log's median scan interval (3.35 s), so every
# relation time can reach the nearer of its two neighbouring scans [s].
DEFAULT_BRIDGE_S = 1.7
# Progress goes to stderr every this many scans (a full Intel run takes a few minutes).
PROGRESS_EVERY_SCANS = 100


def add_geometry_arguments(parser: argparse.ArgumentParser) -> None:
    """--fov-deg, --angle-min-deg: the scan geometry when the data does not give it."""
    parser.add_argument("--fov-deg", type=number(0.0, 360.0, exclusive_minimum=True), default=None,
                        help="scan geometry when the log does not give it: the angle from the "
                             "first to the last beam [deg]")
    parser.add_argument("--angle-min-deg", type=number(-360.0, 360.0), default=None,
                        help="with --fov-deg: the first beam's angle, CCW from the robot's x "
                             "axis [deg] (default: the scan is centred)")


SCAN_LINES = ("FLASER", "ROBOTLASER1", "RLASER", "SONAR")
"""The CARMEN line types a log's scans may be (logs.carmen_lines.SCAN_KINDS)."""


def add_scan_lines_argument(parser: argparse.ArgumentParser) -> None:
    """--scan-lines: which sensor's lines of a CARMEN log are the scans."""
    parser.add_argument("--scan-lines", default=None, choices=SCAN_LINES,
                        help="the CARMEN lines that are the scans (default: FLASER, else "
                             "ROBOTLASER1, else RLASER, else SONAR: the first the log has); "
                             "SONAR builds islands from a sonar ring beside a laser")


def add_loop_closure_argument(parser: Any) -> None:
    """--no-loop-closure on `parser` (a parser or an argument group): the passive mode without
    live exploration's loop closure."""
    parser.add_argument("--no-loop-closure", action="store_true",
                        help="do not recognize known islands before an attempt with live "
                             "exploration's revisit search and gate (the figures before it)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--log", required=True,
                        help="CARMEN log (FLASER/RLASER/ROBOTLASER1 and ODOM), e.g. intel.gfs.log")
    parser.add_argument("--relations", default=None,
                        help="Kuemmerle relations file (t1 t2 x y z roll pitch yaw)")
    parser.add_argument("--reference", default=None,
                        help="reference trajectory (`t x y theta` or TUM lines; default: the "
                             "log's own scan poses)")
    parser.add_argument("--time-offset-s", type=number(-MAX_LOG_TIME_S, MAX_LOG_TIME_S),
                        default=None,
                        help="relation time = log time + this [s] (default: found from the log)")
    parser.add_argument("--out", required=True, help="output directory")
    add_geometry_arguments(parser)
    add_scan_lines_argument(parser)
    parser.add_argument("--beams", type=int, default=180, choices=offline.SUPPORTED_BEAMS,
                        help="180 = the laser; 24 or 16 = sonar-like mode (beams kept per scan)")
    parser.add_argument("--localize-beams", type=int, default=0,
                        choices=(0, *offline.SUPPORTED_BEAMS),
                        help="beams used to localize scans in the islands (0 = --beams): "
                             "--beams 180 --localize-beams 24 localizes sonar-like scans in "
                             "laser-built islands")
    parser.add_argument("--place-recognition", action="store_true",
                        help="a lost robot first searches every island's model for its scan "
                             "(re-enters islands on revisits; slower)")
    add_loop_closure_argument(parser)
    parser.add_argument("--seed", type=SEED, default=0,
                        help="recorded only: the pipeline has no random step")
    parser.add_argument("--bridge-s", type=SECONDS, default=DEFAULT_BRIDGE_S,
                        help="bridged scoring: a relation time at most this far from a localized "
                             "scan takes its fix plus raw odometry [s] (0 = off)")
    parser.add_argument("--max-scans", type=COUNT, default=None,
                        help="use only the first N scans (quick runs)")


def progress(scan: int, scans: int, islands: int) -> None:
    if scan % PROGRESS_EVERY_SCANS == 0:
        print(f"islands: scan {scan}/{scans}, {islands} islands", file=sys.stderr, flush=True)


def offline_config(args: argparse.Namespace) -> offline.OfflineConfig:
    """The passive builder's configuration of --beams, --localize-beams, --place-recognition,
    --no-loop-closure."""
    base = offline.sonar_like_config(args.beams)
    return dataclasses.replace(
        base, localize_beams=args.localize_beams, loop_closure=not args.no_loop_closure,
        islands=dataclasses.replace(base.islands, place_recognition=args.place_recognition))


def geometry_override(args: argparse.Namespace) -> Any:
    from island_mapping.logs.geometry import GeometryOverride, ScanGeometryError

    if args.angle_min_deg is not None and args.fov_deg is None:
        raise CliError("--angle-min-deg needs --fov-deg")
    try:
        return GeometryOverride(args.fov_deg, args.angle_min_deg)
    except ScanGeometryError as exc:
        raise CliError(str(exc)) from None


def scoring(args: argparse.Namespace) -> Any:
    """The relations and reference of --relations, --reference, --time-offset-s, --bridge-s."""
    from island_mapping.logs.errors import LogFormatError
    from island_mapping.logs.reference import read_reference
    from island_mapping.logs.relations import read_relations
    from island_mapping.logs.report import Scoring

    if not (math.isfinite(args.bridge_s) and args.bridge_s >= 0):
        raise CliError(f"--bridge-s: expected a number >= 0, got {args.bridge_s}")
    if args.time_offset_s is not None and not math.isfinite(args.time_offset_s):
        raise CliError(f"--time-offset-s: expected a number, got {args.time_offset_s}")
    try:
        relations = read_relations(args.relations) if args.relations else None
        reference = read_reference(args.reference) if args.reference else None
    except LogFormatError as exc:
        raise CliError(str(exc)) from None
    if relations is not None and len(relations) == 0:
        raise CliError(f"{args.relations}: no relations")
    return Scoring(relations, args.time_offset_s, args.bridge_s, reference)


def evaluate(args: argparse.Namespace) -> dict[str, Any]:
    """Run the evaluation and return metrics (no files written; the run under "_run")."""
    from island_mapping.core.relations import RelationsError
    from island_mapping.logs.errors import LogFormatError
    from island_mapping.logs.report import evaluate_log, from_carmen

    if args.max_scans is not None and args.max_scans < 2:
        raise CliError(f"--max-scans: need at least 2 scans, got {args.max_scans}")
    score = scoring(args)
    try:
        log = from_carmen(args.log, geometry_override(args), args.scan_lines)
        metrics, run = evaluate_log(log, offline_config(args), score, args.max_scans, progress)
    except (LogFormatError, RelationsError, offline.OfflineError) as exc:
        raise CliError(str(exc)) from None
    metrics["seed"] = args.seed
    metrics["_run"] = run
    return metrics


def write_outputs(out: Path, metrics: dict[str, Any], args: argparse.Namespace) -> None:
    """metrics.json, islands.png titled with the log's name, and the headline on stdout."""
    from island_msgs_py.json_io import atomic_write_text

    from island_mapping.logs.report import headline
    from island_mapping.viz.realdata import plot_islands

    island_run: IslandRun = metrics.pop("_run")
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "metrics.json", json.dumps(metrics, indent=1) + "\n")
    plot_islands(island_run.islands, out / "islands.png",
                 f"{len(island_run.islands)} islands on {metrics['log']} ({metrics['mode']})")
    for line in headline(metrics):
        print(line)
    print(json.dumps(summary_line(metrics)))


def summary_line(metrics: dict[str, Any]) -> dict[str, Any]:
    """The last console line, one JSON object: the headline (bridged) figures first, then the
    strict ones, islands and islands per place (null where not computed)."""
    bridged = metrics.get("bridged", {})
    places = metrics.get("places", {})
    return {
        "log": metrics.get("log"), "island_count": metrics.get("island_count"),
        "bridged_covered_relations": bridged.get("covered_relations"),
        "bridged_mean_trans_err_m": bridged.get("mean_trans_err_m"),
        "bridged_mean_rot_err_deg": bridged.get("mean_rot_err_deg"),
        "reference_same_bridged_mean_trans_err_m":
            bridged.get("gmapping_same_relations", {}).get("mean_trans_err_m"),
        **{k: metrics.get(k) for k in ("covered_relations", "mean_trans_err_m",
                                       "median_trans_err_m", "mean_rot_err_deg")},
        "islands_per_place": places.get("islands_per_place"),
    }


def run(args: argparse.Namespace) -> int:
    out = check_output_dir(args.out)
    write_outputs(out, evaluate(args), args)
    return 0
