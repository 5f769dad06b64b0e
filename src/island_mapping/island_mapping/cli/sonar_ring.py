"""`islands sonar-ring`: line models and R on the real 24-sonar ring (UCI wall-following data).

  islands sonar-ring --data sensor_readings_24.data --out DIR [--limit N]

Per reading: the ring's echoes as points (sensor 1 ahead, numbered clockwise, 15 deg apart;
readings of 5.0 m are no echo), a line model fitted to that single reading, and at the robot the
distinctiveness measure R and the Fisher score. Writes DIR/metrics.json (per motion label:
count, mean/median R and Fisher score) and DIR/sonar_ring.png (box plot of R per label, R over
time coloured by label). A malformed line is an error naming its line number.
"""

from __future__ import annotations

import argparse
import json

from island_mapping.cli import CliError
from island_mapping.cli.args import POSITIVE_COUNT, check_output_dir
from island_mapping.core import sonar_ring as rd


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--data", required=True, help="UCI sensor_readings_24.data")
    parser.add_argument("--out", required=True, help="output directory")
    parser.add_argument("--limit", type=POSITIVE_COUNT, default=None,
                        help="score only the first N readings")


def run(args: argparse.Namespace) -> int:
    from island_msgs_py.json_io import atomic_write_text

    from island_mapping.logs.errors import LogFormatError
    from island_mapping.logs.uci_sonar import read_sonar_ring
    from island_mapping.viz.realdata import plot_ring_scores

    if args.limit is not None and args.limit < 1:
        raise CliError(f"--limit: expected at least 1 reading, got {args.limit}")
    out = check_output_dir(args.out)
    try:
        readings = read_sonar_ring(args.data, args.limit)
    except LogFormatError as exc:
        raise CliError(str(exc)) from None
    if readings.ranges_m.shape[0] == 0:
        raise CliError(f"{args.data}: no readings")
    cfg = rd.SonarRingConfig()
    scores = rd.score_ring_readings(readings, cfg)
    ring = rd.ring_metrics(readings, scores)
    metrics = {
        **ring,
        "geometry": {
            "sensors": rd.RING_SENSORS,
            "sensor_1_deg": 0.0,
            "step_deg": -rd.RING_STEP_DEG,
            "ring_radius_m": cfg.ring_radius_m,
            "no_echo_m": cfg.max_range_m,
        },
    }
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "metrics.json", json.dumps(metrics, indent=1) + "\n")
    plot_ring_scores(readings, scores, out / "sonar_ring.png")
    print(json.dumps({k: v["median_r"] for k, v in ring["per_label"].items()}))
    return 0
