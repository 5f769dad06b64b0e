"""`islands`: the project's command-line tool. Each subcommand lives in its own module.

Exit codes: 0 success, 2 bad input (one line on stderr naming the file or option, the field and
the limit), 1 other failures; an internal error (a bug) is one line saying so and where its
traceback was written, never a traceback on the terminal.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import tempfile
import time
import traceback
from collections.abc import Sequence
from pathlib import Path
from typing import NoReturn

from island_msgs_py.errors import InputError
from island_msgs_py.inputs import one_line

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
EXIT_FAILED = 1
EXIT_INTERRUPTED = 130
LOG_DIR_ENV = "ISLANDS_LOG_DIR"
"""Where internal-error logs go (default: $ROS_LOG_DIR, else $ROS_HOME/log, else ~/.ros/log)."""


class CliError(InputError):
    """Bad input for a subcommand: printed as `islands <cmd>: error: <message>`, exit code 2."""


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors: `islands <cmd>: error: <what>; see islands <cmd> -h`."""

    def error(self, message: str) -> NoReturn:
        print(f"{self.prog}: error: {one_line(message)} (see `{self.prog} -h`)", file=sys.stderr)
        sys.exit(EXIT_BAD_INPUT)


def log_dir() -> Path:
    """The directory of internal-error logs (see LOG_DIR_ENV)."""
    for env in (LOG_DIR_ENV, "ROS_LOG_DIR"):
        if os.environ.get(env):
            return Path(os.environ[env]).expanduser()
    if os.environ.get("ROS_HOME"):
        return Path(os.environ["ROS_HOME"]).expanduser() / "log"
    return Path.home() / ".ros" / "log"


def write_crash_log(name: str, argv: Sequence[str]) -> Path | None:
    """The current exception's traceback in a new file of log_dir() (or the temp directory);
    its path, or None when no file could be written."""
    stamp = time.strftime("%Y%m%d-%H%M%S")
    text = f"islands {name}: {' '.join(argv)}\n{traceback.format_exc()}"
    for directory in (log_dir(), Path(tempfile.gettempdir())):
        try:
            directory.mkdir(parents=True, exist_ok=True)
            path = directory / f"islands-{name}-{stamp}-{os.getpid()}.log"
            path.write_text(text, encoding="utf-8")
            return path
        except OSError:
            continue
    return None


def _ensure_ros_env() -> None:
    """DDS discovery stays on this machine unless the user set otherwise; find message files."""
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)
    os.environ.setdefault("MPLBACKEND", "Agg")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="islands", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND",
                                parser_class=_Parser)
    for name, module, help_text in SUBCOMMANDS:
        try:
            mod = importlib.import_module(f"island_mapping.cli.{module}")
        except ModuleNotFoundError as exc:
            if exc.name != f"island_mapping.cli.{module}":
                raise
            continue  # subcommand not shipped in this build
        p = sub.add_parser(name, help=help_text, description=help_text)
        mod.add_arguments(p)
        p.set_defaults(run_command=mod.run)  # the subcommand's name is in `command`
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    _ensure_ros_env()
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # -h, or a bad option (already printed on one line)
        return exc.code if isinstance(exc.code, int) else EXIT_BAD_INPUT
    name = args.command
    try:
        return int(args.run_command(args))
    except InputError as exc:  # CliError and every package's bad-input error
        print(f"islands {name}: error: {one_line(str(exc))}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except OSError as exc:  # a file named on the command line or in an input file
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"islands {name}: error: {one_line(where + (exc.strerror or str(exc)))}",
              file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED
    except Exception as exc:  # a bug: one line, the traceback in a log file
        log = write_crash_log(name, sys.argv[1:] if argv is None else list(argv))
        where = f"traceback in {log}" if log is not None else "no log could be written"
        print(f"islands {name}: internal error (a bug, please report it): "
              f"{type(exc).__name__}: {one_line(str(exc), 200)}; {where}", file=sys.stderr)
        return EXIT_FAILED


if __name__ == "__main__":
    sys.exit(main())
