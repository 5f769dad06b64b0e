"""`islands replay BAG --passive`: islands from any recording with LaserScan and Odometry,
built by the builder's passive mode, with the outputs of `islands eval-relations`.

  islands replay BAG --passive --out DIR [--scan-topic T] [--odom-topic T]
                 [--reference-topic T] [--relations FILE] [--reference FILE]
                 [--time-offset-s S]
                 [--beams 180|24|16] [--place-recognition] [--no-loop-closure]
                 [--fov-deg D --angle-min-deg A]

BAG is a rosbag2 directory or .mcap (a recorded real run, `islands bag import-carmen`'s output).
The scans' geometry is the LaserScan's own (beams >= 5 deg apart: a sonar ring, built with
sonar settings); the reference trajectory is --reference, else --reference-topic, else the
recording's /gmapping_pose or /ground_truth if it has one. Writes DIR/metrics.json and
DIR/islands.png and prints the headline figures (island_mapping.logs.report).
"""

from __future__ import annotations

import argparse

from island_mapping.cli import CliError
from island_mapping.cli import eval_relations as ev


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The passive replay's options (added to `islands replay`)."""
    g = parser.add_argument_group("passive mode (--passive): islands from any recording")
    g.add_argument("--passive", action="store_true",
                   help="build islands from the recording's LaserScan and Odometry with the "
                        "builder's passive mode (not a replay of a recorded explore run)")
    g.add_argument("--scan-topic", default=None, help="LaserScan topic (default: the only one)")
    g.add_argument("--odom-topic", default=None, help="Odometry topic (default: /odom)")
    g.add_argument("--reference-topic", default=None,
                   help="Odometry topic of a reference trajectory, taken at each scan by stamp "
                        "(default: /gmapping_pose, else /ground_truth, if recorded)")
    g.add_argument("--relations", default=None, help="Kuemmerle relations file")
    g.add_argument("--time-offset-s", type=float, default=None,
                   help="relation time = scan time + this [s] (default: found)")
    g.add_argument("--beams", type=int, default=180, choices=ev.offline.SUPPORTED_BEAMS,
                   help="180 = the laser (every beam); 24 or 16 = sonar-like mode")
    g.add_argument("--place-recognition", action="store_true",
                   help="a lost robot searches every island's model for its scan")
    ev.add_loop_closure_argument(g)
    g.add_argument("--bridge-s", type=float, default=ev.DEFAULT_BRIDGE_S,
                   help="bridged scoring limit [s]")
    ev.add_geometry_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from island_mapping.bag.scanlog import read_scan_log
    from island_mapping.core.relations import RelationsError
    from island_mapping.logs.errors import LogFormatError
    from island_mapping.logs.report import evaluate_log

    args.localize_beams, args.max_scans, args.seed = 0, None, 0
    score = ev.scoring(args)
    out = Path(args.out)
    try:
        log, counts = read_scan_log(args.bag, scan_topic=args.scan_topic,
                                    odom_topic=args.odom_topic,
                                    reference_topic=args.reference_topic,
                                    override=ev.geometry_override(args))
        metrics, run_ = evaluate_log(log, ev.offline_config(args), score, None, ev.progress)
    except (LogFormatError, RelationsError, ev.offline.OfflineError) as exc:
        raise CliError(str(exc)) from None
    metrics["skipped"] = counts
    metrics["_run"] = run_
    ev.write_outputs(out, metrics, args)
    return 0
