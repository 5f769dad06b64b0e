"""island_msgs_py: what the simulator (island_sim) and the map (island_mapping) share.

ROS-free (numpy only):
- `types`: Pose2D, StrategyPrimitive, ControlStrategy, ModelType, LineModel, Island, Edge,
  wrap_angle, as_segments, IslandTypeError; `json_io`: their versioned JSON and atomic files;
- `geometry`: pose algebra on (N, 3) arrays, points to/from frames, ranges_to_points,
  point-segment distances, clearance_m;
- `raycast`: raycast, SegmentIndex, RayHits, RayCaster (the project's one ray caster);
- `stamps`: ScanOdomPairer, the project's one scan/odometry stamp pairer: Paired (a scan with
  the odometry of its stamp), and with `every_odometry` every OdometrySample in stamp order,
  StreamSample (extra pose streams such as ground truth), paired_only, StampError; StampJoin
  (two streams of one item per stamp, joined in stamp order).
With rclpy and standard messages:
- `conversions`: shared types and sensor/drive messages (Time, LaserScan, Odometry, Twist) <->
  core values, ConversionError; `qos`: STREAM_QOS, LATCHED; `ros_params`: declare_config,
  run_node, BadMessageLog, ensure_ros_env; `scan_inputs`: subscribe_paired_scans.
Import from the modules: this package module re-exports nothing.
"""
