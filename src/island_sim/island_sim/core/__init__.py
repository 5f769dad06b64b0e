"""The simulator's core: numpy/scipy only, no rclpy, nothing of island_mapping.

- `world`: World, WorldError, world_from_dict / world_to_dict, save_world, start poses;
- `world_loader`: load_world (built-in names, YAML/JSON, HouseExpo, map YAML, images);
- `worlds_builtin`: BUILTIN_WORLDS, builtin_world; `importers`: import_image, import_houseexpo,
  ImageImportConfig, grid_to_segments, rectangles_to_segments; `images`: read_pgm, read_png;
- `sonar`: SonarConfig, SonarModel; `robot`: SimRobot, RobotConfig, OdometryConfig and the sim
  clock and lockstep (SimClock, SimLoopConfig, CommandGate, RealTimePacer);
- `hall_follower`: HallFollower (and, re-exported, its config); `hall_follower_config`:
  HallFollowerConfig, TurnPolicy, TurnChoice; `strategy_record`: StrategyRecorder (Go/Rot).
Imports point one way: world_loader -> importers -> images, worlds_builtin -> world,
hall_follower -> hall_follower_config and strategy_record. Import from the modules: this
package module re-exports nothing.
"""
