"""Message definitions and classes by type name, the way rosbag2 finds and concatenates them.

The `ros2msg` schema text of a type is its own `.msg` text, then for every dependency
(recursively, depth first, each once, dependencies of one definition in sorted order as rosbag2's
`std::set`) the block `"\\n" + "=" * 80 + "\\nMSG: <pkg>/<Type>\\n" + <its .msg text>`.
Definitions are found through AMENT_PREFIX_PATH (`share/<pkg>/msg/<Type>.msg`); no
rosidl_runtime_py (it is not on PyPI). Importing this module does not import rclpy.
"""

from __future__ import annotations

import importlib
import json
import os
import re
import sys
from functools import lru_cache
from pathlib import Path
from typing import Any, Literal

from island_mapping.bag.errors import MessageTypeError

SCHEMA_SEPARATOR = "=" * 80
"""rosbag2's delimiter line between concatenated definitions (80 '=')."""

PRIMITIVE_TYPES = frozenset(
    {
        "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
        "int32", "uint32", "int64", "uint64", "string", "wstring",
    }
)

_TYPE_NAME_RE = re.compile(r"^([A-Za-z][A-Za-z0-9_]*)/(?:msg/)?([A-Za-z][A-Za-z0-9_]*)$")
_FIELD_RE = re.compile(r"^\s*([A-Za-z][A-Za-z0-9_/]*)(?:<=\d+)?(?:\[[^\]]*\])?\s+([A-Za-z]\w*)")


def split_type_name(type_name: str) -> tuple[str, str]:
    """`sensor_msgs/msg/LaserScan` or `sensor_msgs/LaserScan` -> (`sensor_msgs`, `LaserScan`)."""
    m = _TYPE_NAME_RE.match(type_name.strip())
    if m is None:
        raise MessageTypeError(
            f"message type {type_name!r} is not of the form 'pkg/msg/Type' or 'pkg/Type'"
        )
    return m.group(1), m.group(2)


def full_type_name(type_name: str) -> str:
    """The ROS 2 form `pkg/msg/Type` of a type name."""
    pkg, name = split_type_name(type_name)
    return f"{pkg}/msg/{name}"


def _prefixes() -> list[Path]:
    raw = os.environ.get("AMENT_PREFIX_PATH") or sys.prefix
    return [Path(p) for p in raw.split(os.pathsep) if p]


def _msg_file(pkg: str, name: str, suffix: str) -> Path:
    for prefix in _prefixes():
        candidate = prefix / "share" / pkg / "msg" / f"{name}{suffix}"
        if candidate.is_file():
            return candidate
    searched = ", ".join(str(p) for p in _prefixes())
    raise MessageTypeError(
        f"no definition share/{pkg}/msg/{name}{suffix} for {pkg}/msg/{name} under "
        f"AMENT_PREFIX_PATH ({searched}); is the message package installed?"
    )


@lru_cache(maxsize=256)
def msg_text(type_name: str) -> str:
    """The verbatim `.msg` text of one type."""
    pkg, name = split_type_name(type_name)
    return _msg_file(pkg, name, ".msg").read_text(encoding="utf-8")


def _strip_comment(line: str) -> str:
    return line.split("#", 1)[0]


def fields_of(type_name: str) -> list[tuple[str, str]]:
    """(field type as written, field name) of every field of a type, constants excluded."""
    fields: list[tuple[str, str]] = []
    for raw in msg_text(type_name).splitlines():
        line = _strip_comment(raw).strip()
        if not line:
            continue
        m = _FIELD_RE.match(line)
        if m is None:
            continue
        rest = line[m.end():].lstrip()
        if rest.startswith("="):
            continue  # a constant, not a field
        fields.append((m.group(1), m.group(2)))
    return fields


def _resolve(field_type: str, package_context: str) -> str | None:
    """`pkg/Type` of a non-primitive field type, None for primitives."""
    if field_type in PRIMITIVE_TYPES:
        return None
    if field_type == "Header":
        return "std_msgs/Header"
    if "/" in field_type:
        pkg, name = split_type_name(field_type)
        return f"{pkg}/{name}"
    return f"{package_context}/{field_type}"


@lru_cache(maxsize=256)
def dependencies(type_name: str) -> tuple[str, ...]:
    """Direct non-primitive dependencies (`pkg/Type`), sorted like rosbag2's std::set."""
    pkg, _ = split_type_name(type_name)
    deps = {d for t, _ in fields_of(type_name) if (d := _resolve(t, pkg)) is not None}
    return tuple(sorted(deps))


@lru_cache(maxsize=256)
def schema_text(type_name: str) -> str:
    """The rosbag2 `ros2msg` schema text of a type (its definition plus all dependencies)."""
    parts = [msg_text(type_name)]
    seen: set[str] = set()

    def append(tn: str) -> None:
        for dep in dependencies(tn):
            if dep in seen:
                continue
            seen.add(dep)
            parts.append(f"\n{SCHEMA_SEPARATOR}\nMSG: {dep}\n{msg_text(dep)}")
            append(dep)

    append(type_name)
    return "".join(parts)


@lru_cache(maxsize=256)
def type_description_hash(type_name: str) -> str:
    """The RIHS01 type hash of a type from its installed type description (.json), or ''."""
    pkg, name = split_type_name(type_name)
    try:
        path = _msg_file(pkg, name, ".json")
        data = json.loads(path.read_text(encoding="utf-8"))
    except (MessageTypeError, OSError, ValueError):
        return ""
    for entry in data.get("type_hashes", []):
        if entry.get("type_name") == f"{pkg}/msg/{name}":
            return str(entry.get("hash_string", ""))
    return ""


@lru_cache(maxsize=256)
def stamp_is_first_field(type_name: str) -> bool:
    """True when the CDR payload starts with a builtin_interfaces/Time (a Header or Clock).

    Then the stamp is at bytes 4..12 of the CDR payload (int32 sec, uint32 nanosec) after the
    4-byte encapsulation header, so recorders can read it without deserializing.
    """
    pkg, _ = split_type_name(type_name)
    fields = fields_of(type_name)
    if not fields:
        return False
    ftype, _ = fields[0]
    dep = _resolve(ftype, pkg)
    if dep == "builtin_interfaces/Time":
        return True
    if dep == "std_msgs/Header":
        return True
    return False


def stamp_ns_from_cdr(data: bytes) -> int | None:
    """Nanoseconds of the leading Time of a CDR payload (see stamp_is_first_field).

    None when the payload is too short to hold one. 0 is returned as 0: it is both "never set"
    and the first instant of sim time, and only the caller knows which.
    """
    if len(data) < 12:
        return None
    order: Literal["little", "big"] = "little" if data[1] in (0x01, 0x03) else "big"
    sec = int.from_bytes(data[4:8], order, signed=True)
    nsec = int.from_bytes(data[8:12], order, signed=False)
    return sec * 1_000_000_000 + nsec


@lru_cache(maxsize=256)
def message_class(type_name: str) -> Any:
    """The installed Python message class of `pkg/msg/Type` (imports `pkg.msg`)."""
    pkg, name = split_type_name(type_name)
    try:
        module = importlib.import_module(f"{pkg}.msg")
    except ImportError as exc:
        raise MessageTypeError(
            f"message package {pkg!r} for type {type_name!r} is not installed: {exc}"
        ) from None
    cls = getattr(module, name, None)
    if cls is None:
        raise MessageTypeError(f"package {pkg!r} has no message {name!r} (type {type_name!r})")
    return cls


def type_name_of(msg: Any) -> str:
    """`pkg/msg/Type` of a message instance or class."""
    cls = msg if isinstance(msg, type) else type(msg)
    module = cls.__module__.split(".")
    if len(module) < 2 or module[1] != "msg":
        raise MessageTypeError(f"{cls.__module__}.{cls.__name__} is not a ROS message class")
    return f"{module[0]}/msg/{cls.__name__}"
