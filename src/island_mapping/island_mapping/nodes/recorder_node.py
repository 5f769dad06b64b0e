"""recorder_node: record topics of the running graph to a rosbag2 MCAP directory.

    ros2 run island_mapping recorder_node --ros-args -p output_dir:=runs/today \\
        -p recorder.topics:="['/sonar/scan', '/odom']" -p recorder.compression:=zstd

Parameters: `output_dir` (default `run_<UTC date-time>`, must not exist) and `recorder.<field>`
for every field of island_mapping.bag.recorder.RecorderConfig (topics: empty = all; absolute
names, as the recorder sees the whole graph whatever its own namespace). All are read-only: the
bag is opened with them. Ctrl-C or SIGTERM closes the bag properly (summary + metadata.yaml);
after SIGKILL use `islands bag recover`.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from typing import Any

from island_msgs_py.ros_params import declare_config, log_ready, run_node
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node

from island_mapping.bag.errors import BagError
from island_mapping.bag.recorder import RecorderConfig, RunRecorder

NODE_NAME = "recorder"
PREFIX = "recorder"


class RecorderNode(Node):
    """Owns a RunRecorder writing to the `output_dir` parameter."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self._closed = True  # nothing to close until the recorder exists
        stamp = time.strftime("%Y_%m_%d-%H_%M_%S", time.gmtime())
        out = self.declare_parameter(
            "output_dir",
            f"run_{stamp}",
            ParameterDescriptor(description="bag directory to create (must not exist)",
                                read_only=True),
        ).value
        self.config = declare_config(self, PREFIX, RecorderConfig())
        self.recorder = RunRecorder(self, out, config=self.config)
        self._closed = False
        self.get_logger().info(
            f"recording {'all topics' if not self.config.topics else self.config.topics} "
            f"to {self.recorder.path}"
        )
        log_ready(self)

    def close(self) -> None:
        """Close the bag (summary + metadata.yaml); idempotent."""
        if self._closed:
            return
        self._closed = True
        path = self.recorder.close()
        # After Ctrl-C the context is shut down and /rosout is gone: plain stderr.
        print(
            f"recorder_node: closed {path}: {self.recorder.writer.message_count} messages on "
            f"{len(self.recorder.recorded_topics)} topics",
            file=sys.stderr,
        )

    def destroy_node(self) -> None:
        self.close()
        super().destroy_node()


def main(args: Sequence[str] | None = None) -> int:
    # SIGTERM (e.g. from a launcher) stops it like Ctrl-C (run_node); destroy_node closes the bag.
    return run_node(RecorderNode, NODE_NAME, args, config_errors=(BagError, ValueError))


if __name__ == "__main__":
    sys.exit(main())
