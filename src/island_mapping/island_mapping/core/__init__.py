"""The mapping core: numpy/scipy/networkx only; no rclpy, nothing of island_sim.

- `lines`: line models from points (fit_lines, LineFitConfig); `localize`: localize,
  localize_sonar, LocalizeConfig, LocalizationResult;
- `measure`: the distinctiveness measure R (line_measure, measure_map, evaluate_models,
  MeasureConfig); `fisher`: the Fisher score (fisher_measure, FisherConfig); `rays`: the rays
  both cast (MeasureError);
- `placement`: classify_place, PlaceKind; `tracker`: IslandTracker, TrackerConfig, IslandFix;
- `builder`: IslandBuilder, BuilderConfig, BuilderEvent; `graph`: TopoGraph and its formats;
  `realdata`: islands on logged laser data and their scoring.
Geometry and ray casting come from island_msgs_py. Import from the modules: this package module
re-exports nothing.
"""
