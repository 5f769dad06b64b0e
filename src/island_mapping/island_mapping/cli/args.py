"""The validation layer of command-line values: argparse types with the limits they accept,
and the checks of output paths.

An argparse `type=` below refuses a value with a message naming the limit (argparse prints it as
`argument --seed: ...`); the path checks raise CliError naming the option. So a bad value is
one line and exit code 2, never a traceback or an endless run.
"""

from __future__ import annotations

import argparse
import math
import os
from collections.abc import Callable
from pathlib import Path

from island_msgs_py.json_checks import describe
from island_msgs_py.limits import MAX_COORD_M, MAX_DOMAIN_ID, MAX_INT_DIGITS, MAX_SEED

from island_mapping.cli import CliError

MAX_WALL_SECONDS = 7 * 24 * 3600.0
"""Longest wall time any option may ask to wait or run [s] (a week)."""

MAX_COUNT = 10**9
"""Largest count an option takes (messages, routes, trials, readings) [-]."""


def _int(text: str) -> int:
    s = text.strip()
    digits = len(s.lstrip("+-"))
    if digits > MAX_INT_DIGITS:
        raise argparse.ArgumentTypeError(
            f"an integer of {digits} digits (the limit is {MAX_INT_DIGITS})")
    try:
        return int(s, 10)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {describe(text)}") from None


def integer(minimum: int, maximum: int) -> Callable[[str], int]:
    """An argparse type: a decimal integer in [minimum, maximum]."""
    def parse(text: str) -> int:
        value = _int(text)
        if not minimum <= value <= maximum:
            raise argparse.ArgumentTypeError(
                f"expected an integer in [{minimum}, {maximum}], got {value}")
        return value
    parse.__name__ = "integer"  # argparse names the type in its own messages
    return parse


def number(minimum: float = -math.inf, maximum: float = math.inf,
           exclusive_minimum: bool = False) -> Callable[[str], float]:
    """An argparse type: a finite number in [minimum, maximum] (minimum excluded when
    `exclusive_minimum`)."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {describe(text)}") from None
        low_ok = value > minimum if exclusive_minimum else value >= minimum
        if not (math.isfinite(value) and low_ok and value <= maximum):
            low = "(" if exclusive_minimum else "["
            raise argparse.ArgumentTypeError(
                f"expected a finite number in {low}{minimum:g}, {maximum:g}], got {describe(text)}")
        return value
    parse.__name__ = "number"
    return parse


SEED = integer(0, MAX_SEED)
"""A random seed: 0 ... 2^63 - 1 (what a ROS integer parameter holds)."""
DOMAIN_ID = integer(0, MAX_DOMAIN_ID)
"""A ROS_DOMAIN_ID Fast DDS can open: 0 ... 232."""
COUNT = integer(0, MAX_COUNT)
"""A count >= 0."""
POSITIVE_COUNT = integer(1, MAX_COUNT)
"""A count >= 1."""
SECONDS = number(0.0, MAX_WALL_SECONDS)
"""A duration >= 0 [s] (at most a week)."""
POSITIVE_SECONDS = number(0.0, MAX_WALL_SECONDS, exclusive_minimum=True)
"""A duration > 0 [s] (at most a week)."""
METRES = number(0.0, MAX_COORD_M, exclusive_minimum=True)
"""A length > 0 [m] (at most MAX_COORD_M)."""


def coordinates(text: str, option: str, names: tuple[str, ...]) -> tuple[float, ...]:
    """`X,Y[,THETA]` as finite numbers, positions within MAX_COORD_M [m] and angles within
    MAX_COORD_M too (wrapped later); CliError naming `option` otherwise."""
    form = ",".join(names)
    count = {2: "two", 3: "three"}.get(len(names), str(len(names)))
    parts = text.split(",")
    if len(parts) != len(names):
        raise CliError(f"{option}: expected {form} ({count} numbers separated by commas), got "
                       f"{describe(text)}")
    values = []
    for name, part in zip(names, parts, strict=True):
        try:
            v = float(part)
        except ValueError:
            raise CliError(f"{option}: expected {form}, got {describe(text)}: {name} is not a "
                           "number") from None
        if not math.isfinite(v):
            raise CliError(f"{option}: expected {form}, got {describe(text)}: {name} is "
                           f"{describe(v)} (must be finite)")
        if abs(v) > MAX_COORD_M:
            raise CliError(f"{option}: expected {form}, got {describe(text)}: |{name}| must be "
                           f"<= {MAX_COORD_M:g} (the limit)")
        values.append(v)
    return tuple(values)


def check_output_dir(text: str, option: str = "--out") -> Path:
    """The output directory `text`, checked but not created (a run that fails on its input
    leaves nothing behind): an existing directory we can write, or a path whose nearest existing
    ancestor is one; CliError naming `option` otherwise."""
    path = Path(text).expanduser()
    probe = path
    try:
        while not probe.exists() and probe != probe.parent:
            probe = probe.parent
        if not probe.is_dir():
            what = ("exists and is not a directory" if probe == path
                    else f"{probe} is not a directory")
            raise CliError(f"{option} {describe(text)}: {what}")
    except OSError as exc:
        raise CliError(f"{option} {describe(text)}: {exc.strerror or exc}") from None
    if not os.access(probe, os.W_OK | os.X_OK):
        raise CliError(f"{option} {describe(text)}: {probe} is not writable")
    return path


def output_dir(text: str, option: str = "--out") -> Path:
    """Create the output directory `text` (and its parents); CliError naming `option` when it
    is a file or cannot be created."""
    path = Path(text).expanduser()
    try:
        if path.exists() and not path.is_dir():
            raise CliError(f"{option} {describe(text)}: exists and is not a directory")
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CliError(f"{option} {describe(text)}: cannot create the directory: "
                       f"{exc.strerror or exc}") from None
    if not os.access(path, os.W_OK | os.X_OK):
        raise CliError(f"{option} {describe(text)}: the directory is not writable")
    return path


def new_output_dir(text: str, option: str = "--out") -> Path:
    """A directory that must not exist yet, whose parent can be created; CliError naming
    `option` otherwise (the directory itself is made by whoever writes it)."""
    path = Path(text).expanduser()
    try:
        if path.exists():
            raise CliError(f"{option} {describe(text)}: exists (choose a new directory)")
        output_dir(str(path.parent) if str(path.parent) else ".", option)
    except OSError as exc:
        raise CliError(f"{option} {describe(text)}: {exc.strerror or exc}") from None
    return path


def output_file(text: str, option: str) -> Path:
    """A file to write: not a directory, its directory created; CliError naming `option`."""
    path = Path(text).expanduser()
    try:
        if path.is_dir():
            raise CliError(f"{option} {describe(text)}: is a directory, expected a file name")
    except OSError as exc:
        raise CliError(f"{option} {describe(text)}: {exc.strerror or exc}") from None
    output_dir(str(path.parent) if str(path.parent) else ".", option)
    return path
