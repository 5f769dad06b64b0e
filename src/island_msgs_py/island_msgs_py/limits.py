"""Bounds of the shared map types: what the graph, its files, its store and its messages accept.

Each bound says what is accepted and why it is there; a value outside one is an error of the
package's own type (IslandTypeError, GraphFormatError, GraphError) naming the field and the
bound. None is near what a run produces (islands are numbered from 0, models are metres across,
a building is hundreds of metres); they exist so one hostile value cannot break what comes
after it (a marker, a plan, a restart on the store).
"""

from __future__ import annotations

MAX_ISLAND_ID = 2**31 - 1
"""Largest island id: it is a visualization_msgs Marker id (int32) and part of the frame id
`island_<id>`; the store keeps it in a SQLite INTEGER."""

MAX_EXIT_INDEX = 2**31 - 1
"""Largest exit index (an int32 like an island id)."""

MAX_COORD_M = 1.0e6
"""Largest |coordinate| [m] of a segment end or an origin: 1000 km, far beyond any building,
and small enough that squares and sums of coordinates stay finite in every computation."""

MAX_LENGTH_M = 1.0e6
"""Largest edge weight, length, expected error or exit width [m]."""

MAX_GO_CM = 100_000_000
"""Largest `Go` step [cm] of a control strategy (MAX_LENGTH_M in centimetres)."""

MAX_STRATEGY_STEPS = 1000
"""Most primitives in one control strategy (a long edge drives a few dozen)."""

MAX_SEGMENTS_PER_ISLAND = 10_000
"""Most line segments in one island's model (a sonar star gives tens, a laser island hundreds)."""

MAX_EXITS_PER_ISLAND = 64
"""Most exits of one island (a junction has a handful)."""

MAX_JSON_DEPTH = 32
"""Deepest nesting of arrays and objects in any JSON the map reads (a graph document nests 6
deep, GeoJSON 7): deeper input is refused before parsing, never a RecursionError."""

MAX_JSON_INT_DIGITS = 20
"""Most digits of an integer literal in JSON (int64 has 19): longer ones are refused while
parsing, before Python's int conversion limit or a float overflow can raise."""

MAX_GRAPH_FILE_BYTES = 256 * 1024 * 1024
"""Largest graph file read (JSON, GeoJSON, GraphML) [bytes]; a 100,000-island map with 20
segments per island is about 150 MB as JSON."""

MAX_ITEM_JSON_BYTES = 4 * 1024 * 1024
"""Largest JSON text of one island, edge or exit item (a 10,000-segment model is ~0.8 MB)."""

MAX_FRAME_ID_CHARS = 256
"""Longest frame id of an island (`island_<id>` is at most 17 characters)."""
