"""Readers of recorded real-robot data files (pure: numpy only, no rclpy).

Public API, by module (import the submodule; this package imports nothing):

- `carmen_lines`: the one CARMEN line parser (`parse_carmen`, `read_carmen_records` ->
  `CarmenRecords`: FLASER, RLASER, ROBOTLASER1, SONAR, ODOM, PARAM; `CarmenFormatError`);
- `carmen`: its views (`carmen_log` -> `CarmenLog` and `pose_track` ->
  core.relations.PoseTrack; the FLASER format's geometry `flaser_angles`,
  `sonar_like_indices`), re-exporting the parser's names;
- `geometry`: scan geometry from the data (`ScanGeometry`, `SensorKind`, `GeometryOverride`,
  `carmen_geometry`, `carmen_mount`, `laserscan_geometry`, `ScanGeometryError`);
- `times`: scan time checks (`check_scan_times`, `TimeReport`, `LogTimeError`);
- `relations`: Kuemmerle et al.'s relation files (`parse_relations`, `read_relations`);
- `reference`: reference trajectories (`read_reference`, `inside_islands`, `places`);
- `report`: the one evaluation of a recorded log (`RecordedLog`, `from_carmen`, `Scoring`,
  `evaluate_log`, `headline`);
- `islands`: the log's beams into the builder's passive mode (`build_islands_offline`);
- `uci_sonar`: the UCI wall-following robot's 24-sonar readings (`parse_sonar_ring`,
  `read_sonar_ring`);
- `errors`: `LogFormatError`, the base of every reader's error.

Layer: may import island_mapping.core (the data types the views fill), never nodes, bag or cli.
"""
