"""Readers of recorded real-robot data files (pure: numpy only, no rclpy).

Public API, by module (import the submodule; this package imports nothing):

- `carmen`: the one CARMEN log parser (`parse_carmen`, `read_carmen_records` -> `CarmenRecords`;
  the views `carmen_log` -> `CarmenLog` and `pose_track` -> core.relations.PoseTrack; FLASER
  geometry `flaser_angles`, `sonar_like_indices`; `CarmenFormatError`);
- `relations`: Kuemmerle et al.'s relation files (`parse_relations`, `read_relations`);
- `uci_sonar`: the UCI wall-following robot's 24-sonar readings (`parse_sonar_ring`,
  `read_sonar_ring`);
- `errors`: `LogFormatError`, the base of every reader's error.

Layer: may import island_mapping.core (the data types the views fill), never nodes, bag or cli.
"""
