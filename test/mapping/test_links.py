"""The chain of links between two islands: its pose, and sigmas that add in quadrature."""

from __future__ import annotations

import math

import pytest
from island_mapping.core.builder.links import Link, LinkGraph
from island_msgs_py.types import Pose2D


def _line(n: int, sigma_m: float, sigma_rad: float, length_m: float = 5.0) -> LinkGraph:
    g = LinkGraph()
    for i in range(n):
        g.add(i, i + 1, Link(Pose2D(length_m, 0.0, 0.0), sigma_m, sigma_rad))
    return g


def test_chain_composes_links_either_way() -> None:
    g = LinkGraph()
    g.add(0, 1, Link(Pose2D(2.0, 0.0, math.pi / 2), 0.1, 0.01))
    g.add(2, 1, Link(Pose2D(0.0, -3.0, 0.0), 0.1, 0.01))  # driven from 2 to 1: reversed
    c = g.chain(0, 2)
    assert c is not None
    assert (c.pose.x, c.pose.y) == pytest.approx((-1.0, 0.0), abs=1e-9)
    assert g.chain(0, 7) is None


def test_independent_link_errors_add_in_quadrature() -> None:
    c = _line(4, 1.0, 0.0).chain(0, 4)
    assert c is not None
    assert c.sigma_m == pytest.approx(2.0)  # sqrt(4) x 1 m, not 4 m


def test_a_heading_error_turns_every_later_link() -> None:
    c = _line(2, 0.0, 0.1, length_m=10.0).chain(0, 2)
    assert c is not None
    # the first link's 0.1 rad turns the second's 10 m: 1 m; heading sigmas in quadrature
    assert c.sigma_m == pytest.approx(1.0)
    assert c.sigma_rad == pytest.approx(0.1 * math.sqrt(2.0))


def test_the_chain_with_the_smaller_sigma_wins() -> None:
    g = _line(3, 1.0, 0.0)
    g.add(0, 3, Link(Pose2D(15.2, 0.0, 0.0), 0.5, 0.0))
    c = g.chain(0, 3)
    assert c is not None
    assert c.pose.x == pytest.approx(15.2)
    assert c.sigma_m == pytest.approx(0.5)
