"""Runs on record: rosbag2-compatible MCAP writing, reading, recovery, replay and importers.

Submodules: `schema` (message definitions), `qos`, `writer` (BagWriter), `reader` (open_bag),
`recover`, `text` (message -> YAML-like text), `player` (BagPlayer), `recorder` (RunRecorder),
`carmen` (CARMEN log importer). This package module imports nothing heavy; import submodules.
"""
