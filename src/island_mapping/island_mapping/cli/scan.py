"""`islands scan`: simulate one sonar-ring scan at a pose and print it as JSON.

  islands scan --world WORLD --pose X,Y,THETA [--ideal] [--seed N] [--resolution M]

WORLD is a built-in name (paper_fig3, paper_fig4, corridor, square_room, t_junction) or a world
file (YAML/JSON segments, HouseExpo JSON, PGM/PNG occupancy image). Prints
{"angles": [...] (rad, robot frame), "ranges": [...] (m from the robot centre, null = no echo),
"pose": [x, y, theta], "world": name}. Without --pose the world's start pose is used; a pose
starting with a minus sign needs the `=` form: --pose=-1.5,2,0.
"""

from __future__ import annotations

import argparse
import json
import math

from island_msgs_py.types import Pose2D

from island_mapping.cli import CliError
from island_mapping.cli.args import METRES, SEED, coordinates


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--world", required=True, help="built-in world name or world file")
    parser.add_argument(
        "--pose",
        default=None,
        help="robot pose X,Y,THETA (m, m, rad; write --pose=-1,2,0 for a negative X); "
        "default: the world's start pose",
    )
    parser.add_argument(
        "--ideal", action="store_true", help="one ray per transducer, no noise, no specular loss"
    )
    parser.add_argument("--seed", type=SEED, default=0, help="seed of the range noise")
    parser.add_argument(
        "--resolution", type=METRES, default=None, help="image worlds: pixel size [m/px]"
    )


def parse_pose(text: str) -> Pose2D:
    """'X,Y,THETA' (m, m, rad) -> Pose2D; CliError naming the problem and the limit."""
    return Pose2D(*coordinates(text, "--pose", ("X", "Y", "THETA")))


def run(args: argparse.Namespace) -> int:
    import numpy as np
    from island_sim.core.sonar import SonarConfig, SonarModel
    from island_sim.core.world import WorldError
    from island_sim.core.world_loader import load_world

    pose = parse_pose(args.pose) if args.pose is not None else None
    if args.resolution is not None and not (math.isfinite(args.resolution) and args.resolution > 0):
        raise CliError(f"--resolution: expected a positive pixel size in m, got {args.resolution}")
    try:
        world = load_world(args.world, resolution_m=args.resolution)
    except WorldError as exc:
        raise CliError(str(exc)) from None
    if pose is None:
        pose = world.start_pose
    model = SonarModel(SonarConfig(ideal=bool(args.ideal)))
    ranges = model.scan(world, pose, np.random.default_rng(args.seed))
    out = {
        "angles": [float(a) for a in model.angles_rad],
        "ranges": [float(r) if math.isfinite(r) else None for r in ranges],
        "pose": [pose.x, pose.y, pose.theta],
        "world": world.name,
    }
    print(json.dumps(out))
    return 0
