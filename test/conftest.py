"""Shared pytest setup: DDS stays on this machine, one random domain per session, ROS helpers."""

from __future__ import annotations

import os
import random
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

# Before anything imports rclpy: discovery on loopback only, a random domain for this session
# so that concurrent sessions on one machine never see each other.
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
if "ROS_DOMAIN_ID" not in os.environ:
    os.environ["ROS_DOMAIN_ID"] = str(random.SystemRandom().randint(1, 101))
os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)
os.environ.setdefault("MPLBACKEND", "Agg")

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO_ROOT.parent / "shared" / "data"


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """../shared/data, or skip when the evaluation data is not beside the checkout."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"shared data not found at {SHARED_DATA}")
    return SHARED_DATA


@pytest.fixture
def ros_context() -> Iterator[Any]:
    """A fresh, initialized rclpy Context for one test; shut down afterwards."""
    import rclpy
    from rclpy.context import Context

    ctx = Context()
    rclpy.init(context=ctx)
    try:
        yield ctx
    finally:
        ctx.try_shutdown()


def spin_until(
    executor: Any, condition: Callable[[], bool], timeout_s: float = 10.0, step_s: float = 0.01
) -> bool:
    """Spin `executor` until `condition()` is true or `timeout_s` wall seconds pass."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            return False
        executor.spin_once(timeout_sec=step_s)
    return True


@pytest.fixture
def spin() -> Callable[..., bool]:
    """The `spin_until(executor, condition, timeout_s)` helper as a fixture."""
    return spin_until
