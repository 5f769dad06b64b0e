"""What both diagnoses share: a world, a seed and simulated seconds, explored by exits."""

from __future__ import annotations

import argparse

import numpy as np
from island_mapping.evaluation.explore_exits import ExitsRun, explore_by_exits
from island_mapping.evaluation.navigate import SimSetup
from island_sim.core.world_loader import load_world


def parse(doc: str | None) -> argparse.Namespace:
    """world, seed and sim_seconds from the command line."""
    p = argparse.ArgumentParser(description=doc)
    p.add_argument("world")
    p.add_argument("seed", type=int)
    p.add_argument("sim_seconds", type=float)
    return p.parse_args()


def explore(a: argparse.Namespace) -> ExitsRun:
    """Explore a.world by its exits for a.sim_seconds with seed a.seed."""
    return explore_by_exits(SimSetup(world=load_world(a.world, None)), a.sim_seconds,
                            rng=np.random.default_rng(a.seed))
