"""QoS profiles in rosbag2's `offered_qos_profiles` form (metadata.yaml version 9, Jazzy).

The same list of dicts is written twice: as a YAML *string* in each MCAP channel's metadata and as
a YAML *list* in metadata.yaml. Readers (rosbags) compare the two and skip a channel whose QoS
disagree, so both are produced from one `QosDict` list here. Importing this module does not
import rclpy (only the conversion helpers do, lazily).
"""

from __future__ import annotations

from typing import Any

import yaml
from island_msgs_py.inputs import load_yaml

from island_mapping.bag.errors import BagError

QosDict = dict[str, Any]

INFINITE_SEC = 9223372036
"""rosbag2's serialization of an infinite duration: RMW_DURATION_INFINITE split into sec..."""
INFINITE_NSEC = 854775807
"""...and nsec (2**63 - 1 ns)."""

_DDS_INFINITE_SEC = 2147483647  # Fast DDS reports an infinite duration as int32 max seconds.

HISTORY = ("system_default", "keep_last", "keep_all", "unknown")
RELIABILITY = ("system_default", "reliable", "best_effort", "unknown", "best_available")
DURABILITY = ("system_default", "transient_local", "volatile", "unknown", "best_available")
LIVELINESS = (
    "system_default", "automatic", "manual_by_node", "manual_by_topic", "unknown",
    "best_available",
)


def _duration(sec: int, nsec: int) -> dict[str, int]:
    if sec >= _DDS_INFINITE_SEC or sec * 1_000_000_000 + nsec >= 2**63 - 1:
        return {"sec": INFINITE_SEC, "nsec": INFINITE_NSEC}
    return {"sec": int(sec), "nsec": int(nsec)}


def default_qos(depth: int = 10, transient_local: bool = False) -> QosDict:
    """A reliable keep-last profile (rclpy's default; transient local for latched topics)."""
    return {
        "history": "keep_last",
        "depth": int(depth),
        "reliability": "reliable",
        "durability": "transient_local" if transient_local else "volatile",
        "deadline": _duration(0, 0),
        "lifespan": _duration(0, 0),
        "liveliness": "automatic",
        "liveliness_lease_duration": _duration(0, 0),
        "avoid_ros_namespace_conventions": False,
    }


def qos_to_yaml(profiles: list[QosDict]) -> str:
    """The YAML string stored in an MCAP channel's `offered_qos_profiles` metadata."""
    if not profiles:
        return ""
    return yaml.safe_dump(profiles, sort_keys=False, default_flow_style=False).strip()


def qos_from_yaml(text: str | list[QosDict]) -> list[QosDict]:
    """Parse channel metadata text (or an already parsed metadata.yaml list) into dicts."""
    if not text:
        return []
    items = load_yaml(text, "offered_qos_profiles", BagError) if isinstance(text, str) else text
    if not isinstance(items, list) or not all(isinstance(i, dict) for i in items):
        raise BagError(f"offered_qos_profiles must be a list of mappings, got {items!r}")
    out: list[QosDict] = []
    for item in items:
        d = dict(item)
        for key, names in (
            ("history", HISTORY), ("reliability", RELIABILITY), ("durability", DURABILITY),
            ("liveliness", LIVELINESS),
        ):
            value = d.get(key, "system_default")
            if isinstance(value, int):  # version <= 8 stored the enum value
                d[key] = names[value] if 0 <= value < len(names) else "unknown"
            else:
                d[key] = str(value).lower()
        out.append(d)
    return out


def _enum_name(value: Any) -> str:
    name = getattr(value, "name", str(value))
    return str(name).lower()


def qos_from_rclpy(profile: Any) -> QosDict:
    """A QosDict from an rclpy QoSProfile (e.g. TopicEndpointInfo.qos_profile)."""

    def dur(d: Any) -> dict[str, int]:
        ns = int(d.nanoseconds)
        return _duration(ns // 1_000_000_000, ns % 1_000_000_000)

    return {
        "history": _enum_name(profile.history),
        "depth": int(profile.depth),
        "reliability": _enum_name(profile.reliability),
        "durability": _enum_name(profile.durability),
        "deadline": dur(profile.deadline),
        "lifespan": dur(profile.lifespan),
        "liveliness": _enum_name(profile.liveliness),
        "liveliness_lease_duration": dur(profile.liveliness_lease_duration),
        "avoid_ros_namespace_conventions": bool(profile.avoid_ros_namespace_conventions),
    }


def rclpy_qos(profiles: list[QosDict], depth: int = 10) -> Any:
    """The rclpy QoSProfile a player or recorder uses for these offered profiles.

    Reliable unless every publisher was best effort; transient local when every publisher was
    (latched topics replay latched), like rosbag2's adaptive QoS.
    """
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    best_effort = bool(profiles) and all(p.get("reliability") == "best_effort" for p in profiles)
    latched = bool(profiles) and all(p.get("durability") == "transient_local" for p in profiles)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=max(depth, max((int(p.get("depth", 0)) for p in profiles), default=0)),
        reliability=ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE,
        durability=(
            DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE
        ),
    )
