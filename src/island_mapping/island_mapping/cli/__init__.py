"""`islands`: the project's command-line tool. Each subcommand lives in its own module.

Exit codes: 0 success, 2 bad input (a clear message on stderr naming what was wrong), 1 other
failures.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence

# (subcommand, module under island_mapping.cli, one-line help). Each module defines
# `add_arguments(parser)` and `run(args) -> int`.
SUBCOMMANDS: tuple[tuple[str, str, str], ...] = (
    ("scan", "scan", "simulate one sonar scan at a pose and print JSON"),
    ("world", "world", "check a world file and print its segment count and bounds"),
    ("measure", "measure", "distinctiveness measure R (or the Fisher score) at points"),
    ("fig3", "fig3", "R map, localization-confidence map and residual plot (paper Figs. 2, 3)"),
    ("explore", "explore", "explore a world, build islands and the topological map (main job)"),
    ("evaluate", "evaluate", "measure an explored map against the world's places (issue 16)"),
    ("graph", "graph", "inspect, convert and plan on saved island graphs"),
    ("bag", "bag", "MCAP run recordings: info, echo, play, recover, import"),
    ("topic", "topic", "live topics without ros2cli: list, echo"),
    ("eval-relations", "eval_relations", "score island localization on Kuemmerle relations"),
    ("sonar-ring", "sonar_ring", "score the real 24-sonar ring readings with line models and R"),
    ("replay", "replay", "rebuild the island graph from a recorded run"),
)

EXIT_BAD_INPUT = 2


class CliError(Exception):
    """Bad input for a subcommand: printed as `islands <cmd>: error: <message>`, exit code 2."""


def _ensure_ros_env() -> None:
    """DDS discovery stays on this machine unless the user set otherwise; find message files."""
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)
    os.environ.setdefault("MPLBACKEND", "Agg")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="islands", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, module, help_text in SUBCOMMANDS:
        try:
            mod = importlib.import_module(f"island_mapping.cli.{module}")
        except ModuleNotFoundError as exc:
            if exc.name != f"island_mapping.cli.{module}":
                raise
            continue  # subcommand not shipped in this build
        p = sub.add_parser(name, help=help_text, description=help_text)
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run, _name=name)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    _ensure_ros_env()
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args._run(args))
    except CliError as exc:
        print(f"islands {args._name}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
