"""Where one island's origin lies in another's frame, as measured by odometry along edges.

A link a -> b is island b's origin in island a's frame, measured on one stretch of odometry
from a's origin, with its position and heading sigmas. `LinkGraph.chain` composes links (either
direction) into b's origin in a's frame along the chain with the smallest position sigma.

The chain's cost is not a sum of fixed edge weights: a link's heading error turns every later
link, so a step adds the heading sigma accumulated so far times its length. The links' errors
are independent (each is measured on its own stretch of odometry), so sigmas add in quadrature:
a chain's sigma is the root of the sum of its squared terms, not their sum. That is why this is
a small Dijkstra of its own rather than networkx's, whose weights cannot depend on the path.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

from island_msgs_py.types import Pose2D


@dataclass(frozen=True)
class Link:
    """b's origin in a's frame [m, rad], with position [m] and heading [rad] sigmas."""

    pose: Pose2D
    sigma_m: float
    sigma_rad: float


class LinkGraph:
    """Links between island origins (see the module docstring)."""

    def __init__(self) -> None:
        self._links: dict[tuple[int, int], Link] = {}

    def __len__(self) -> int:
        return len(self._links)

    def add(self, a: int, b: int, link: Link) -> None:
        """Keep `link` for a -> b unless one with a smaller position sigma is known."""
        old = self._links.get((a, b))
        if old is None or link.sigma_m < old.sigma_m:
            self._links[a, b] = link

    def get(self, a: int, b: int) -> Link | None:
        """The link a -> b as measured (not reversed), or None."""
        return self._links.get((a, b))

    def chain(self, src: int, dst: int) -> Link | None:
        """Island dst's origin in island src's frame through the links (either direction),
        the chain with the smallest position sigma; None when none joins them. A link's
        heading error turns every later link: sigma grows by the heading sigma so far times
        each later link's length (first order); independent terms add in quadrature."""
        best = {src: 0.0}
        heap: list[tuple[float, int, int, Pose2D, float]] = [(0.0, 0, src, Pose2D(0, 0, 0), 0.0)]
        tie = 1
        while heap:
            sig, _, node, pose, sig_th = heapq.heappop(heap)
            if node == dst:
                return Link(pose, sig, sig_th)
            if sig > best.get(node, math.inf):
                continue
            for (a, b), link in self._links.items():
                if node not in (a, b):
                    continue
                nxt, step = (b, link.pose) if a == node else (a, link.pose.inverse())
                ns = math.sqrt(sig ** 2 + link.sigma_m ** 2
                               + (sig_th * math.hypot(step.x, step.y)) ** 2)
                if ns < best.get(nxt, math.inf):
                    best[nxt] = ns
                    entry = (ns, tie, nxt, pose.compose(step), math.hypot(sig_th, link.sigma_rad))
                    heapq.heappush(heap, entry)
                    tie += 1
        return None
