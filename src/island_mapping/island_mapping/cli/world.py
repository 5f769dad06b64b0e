"""`islands world`: check a world (file or built-in name) and print its summary as JSON.

  islands world WORLD [--resolution M] [--save OUT.yaml]

Prints {"name", "segments" (count), "bounds" [xmin, ymin, xmax, ymax] (m), "size" [w, h] (m),
"start_pose" [x, y, theta]}. --save writes the world as a segment YAML/JSON file (e.g. to
freeze an imported floor plan). A malformed world is an error naming the file and the problem
(exit code 2).
"""

from __future__ import annotations

import argparse
import json
import math

from island_mapping.cli import CliError
from island_mapping.cli.args import METRES, output_file


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("world", help="world file (YAML/JSON/HouseExpo/PGM/PNG) or built-in name")
    parser.add_argument(
        "--resolution", type=METRES, default=None, help="image worlds: pixel size [m/px]"
    )
    parser.add_argument("--save", default=None, help="also write the world as YAML (or .json)")


def run(args: argparse.Namespace) -> int:
    from island_sim.core.world import WorldError, save_world
    from island_sim.core.world_loader import load_world

    if args.resolution is not None and not (math.isfinite(args.resolution) and args.resolution > 0):
        raise CliError(f"--resolution: expected a positive pixel size in m, got {args.resolution}")
    try:
        world = load_world(args.world, resolution_m=args.resolution)
    except WorldError as exc:
        raise CliError(str(exc)) from None
    x0, y0, x1, y1 = world.bounds
    sp = world.start_pose
    summary = {
        "name": world.name,
        "segments": int(world.segments.shape[0]),
        "bounds": [x0, y0, x1, y1],
        "size": [x1 - x0, y1 - y0],
        "start_pose": [sp.x, sp.y, sp.theta],
    }
    if args.save:
        target = output_file(args.save, "--save")
        try:
            summary["saved"] = str(save_world(world, target))
        except OSError as exc:
            raise CliError(f"--save {args.save}: cannot write ({exc})") from None
    print(json.dumps(summary))
    return 0
