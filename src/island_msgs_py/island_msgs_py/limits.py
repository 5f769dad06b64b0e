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

# ----------------------------------------------------------------------------- input files

MAX_TEXT_FILE_BYTES = 256 * 1024 * 1024
"""Largest text file read whole (a parameter file, rosbag2's metadata.yaml, a relations file, a
sonar-ring data file, a CARMEN log: the Intel log is 1.7 MB) [bytes]."""

MAX_WORLD_FILE_BYTES = 64 * 1024 * 1024
"""Largest world file (YAML/JSON segments, HouseExpo JSON, map YAML) [bytes]: a 200,000-segment
world is ~17 MB as JSON; parsed, a file of this size holds the most segments a world may have."""

MAX_WORLD_SEGMENTS = 500_000
"""Most wall segments of one world (Willow traced from its image has 3,550)."""

MAX_YAML_DEPTH = MAX_JSON_DEPTH
"""Deepest nesting of YAML mappings and sequences (a world nests 3 deep, rosbag2's metadata 6):
checked on the parser's events before anything is built, never a RecursionError."""

MAX_YAML_ALIAS_NODES = 100_000
"""Most YAML nodes that aliases may stand for in one file, counted expanded (an alias of an alias
counts every node it reaches): a 700-byte "billion laughs" file stands for billions."""

MAX_INT_DIGITS = MAX_JSON_INT_DIGITS
"""Most digits of an integer in any YAML or text input (int64 has 19): longer ones are refused
before Python's int conversion limit (4300 digits) or a float overflow can raise."""

MAX_IMAGE_BYTES = 16 * 1024 * 1024
"""Largest decoded occupancy image, width x height x bytes per pixel [bytes] (an 8-bit grey
4000 x 4000 image: 400 m square at 0.1 m/px; Willow is 540 x 587), checked on the size the
header declares before any pixel is decoded."""

MAX_IMAGE_FILE_BYTES = 128 * 1024 * 1024
"""Largest occupancy image file [bytes] (an ASCII PGM of MAX_IMAGE_PIXELS is ~64 MB)."""

MAX_PATH_CHARS = 4096
"""Longest file path taken from inside a file (a map YAML's `image`) [characters]."""

# ----------------------------------------------------------------------------- messages

MAX_SCAN_RANGES = 4096
"""Most ranges of one LaserScan a node accepts (the sonar ring has 16, the Intel laser 180, a
0.1 deg 360 deg lidar 3600): a longer scan is refused before any work is done on it."""

MAX_STAMP_AHEAD_S = 10.0
"""A message stamped more than this ahead of the receiving node's clock is refused [s]: one
message stamped 2^31 - 1 s would otherwise make every later one look old for good."""

MAX_EVENT_JSON_BYTES = 8 * 1024 * 1024
"""Largest builder event (JSON on /island_builder/events; it carries one island) [bytes]."""

MAX_SEED = 2**63 - 1
"""Largest random seed (a ROS integer parameter is an int64)."""

MAX_DOMAIN_ID = 232
"""Largest ROS_DOMAIN_ID Fast DDS can open on Linux (its port formula overflows beyond)."""
