"""The graph package's exceptions (all ValueErrors, so callers that catch bad input catch them)."""

from __future__ import annotations

from island_msgs_py.errors import InputError


class GraphError(InputError):
    """A request on the map was rejected (the message names the island/edge and the problem)."""


class NoRouteError(GraphError):
    """Both islands exist but no directed path joins them."""
