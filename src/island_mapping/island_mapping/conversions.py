"""island_mapping's messages <-> its core types: the builder's per-scan decisions and the
explorer's requests (exploration by the map, issue 16).

- **Decisions** (`island_builder/decision`, std_msgs/String JSON, managed mode only): one per
  scan the builder decided, `{"stamp_ns": int, "mode": "follow"|"drive"|"idle", "events":
  [builder events]}`. The explorer decides a scan only once it has the builder's decision of
  the same stamp, so it sees the builder's events of that scan first (as the offline harness
  does) and knows whether the builder side answers it.
- **Explorer requests** (`island_builder/explorer`, rcl_interfaces/SetParameters): one
  parameter per request, applied in order, each a JSON string: `docked`
  `{"island": id, "origin_odom": {x, y, theta}}`, `handover` `{"island": id, "exit": index or
  null, "prefix": "Go 150, Rot 90"}`, `abort` `{}`, `confirm` `{"island": id}` (the held
  star was at that island), `reject` `{}` (it was at none of its hypotheses).
- **Status** (`explorer/status`, std_msgs/String JSON): `ExplorerStatus.to_dict()`.

Every malformed value raises `ExplorerMessageError` naming the field (an `InputError`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

from island_msgs_py.errors import InputError
from island_msgs_py.types import ControlStrategy, ExitUpdate, Island, IslandTypeError, NewExit
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from std_msgs.msg import String

from island_mapping.core.builder import (
    BuilderEvent,
    CommandMode,
    EventKind,
    Hypothesis,
    event_to_dict,
)
from island_mapping.core.builder.hooks import GraphItem
from island_mapping.core.explore import Abort, Confirm, Docked, ExplorerStatus, Handover, Reject
from island_msgs_py import conversions as cv
from island_msgs_py import json_checks as jc
from island_msgs_py import json_io

DOCKED_PARAM = "docked"
HANDOVER_PARAM = "handover"
ABORT_PARAM = "abort"
CONFIRM_PARAM = "confirm"
REJECT_PARAM = "reject"
REQUEST_PARAMS = (DOCKED_PARAM, HANDOVER_PARAM, ABORT_PARAM, CONFIRM_PARAM, REJECT_PARAM)
MAX_REQUEST_CHARS = 65536
"""A request's JSON longer than this is refused (a strategy prefix is a few hundred) [chars]."""
MAX_DECISION_CHARS = 8 * 1024 * 1024
"""A decision message longer than this is refused (it carries at most a few islands) [chars]."""

ExplorerRequest = Docked | Handover | Abort | Confirm | Reject


class ExplorerMessageError(InputError):
    """A decision, request or status message is malformed (the message names the field)."""


@dataclass(frozen=True)
class Decision:
    """The builder's verdict on the scan of `stamp_ns`: who answers it from the builder side
    (`mode`) and the events it emitted."""

    stamp_ns: int
    mode: CommandMode
    events: tuple[BuilderEvent, ...]


# ----------------------------------------------------------------------------- decisions


def decision_to_msg(stamp_ns: int, mode: CommandMode, events: tuple[BuilderEvent, ...]) -> String:
    return String(data=json.dumps({"stamp_ns": int(stamp_ns), "mode": mode.value,
                                   "events": [event_to_dict(e) for e in events]}))


def msg_to_decision(msg: String) -> Decision:
    """The decision a message carries; ExplorerMessageError when malformed."""
    if len(msg.data) > MAX_DECISION_CHARS:
        raise ExplorerMessageError(f"decision: {len(msg.data)} characters, the limit is "
                                   f"{MAX_DECISION_CHARS}")
    try:
        d = jc.obj(jc.loads(msg.data, "decision"), "decision", {"stamp_ns", "mode", "events"},
                   {"stamp_ns", "mode", "events"})
        stamp = jc.int_(d["stamp_ns"], "decision.stamp_ns")
        mode = _enum(CommandMode, d["mode"], "decision.mode")
        events = tuple(event_from_dict(e, f"decision.events[{k}]")
                       for k, e in enumerate(jc.list_(d["events"], "decision.events")))
    except (InputError, IslandTypeError) as exc:
        raise ExplorerMessageError(str(exc)) from None
    return Decision(stamp, mode, events)


def _enum(cls: Any, value: Any, path: str) -> Any:
    try:
        return cls(jc.str_(value, path))
    except ValueError:
        raise ExplorerMessageError(f"{path}: expected one of {[m.value for m in cls]}, got "
                                   f"{jc.describe(value)}") from None


def _opt(d: Any, key: str, fn: Any, path: str) -> Any:
    v = d.get(key)
    return None if v is None else fn(v, f"{path}.{key}")


def event_from_dict(d: Any, path: str = "event") -> BuilderEvent:
    """A builder event from its JSON form (`event_to_dict`), checked field by field."""
    keys = {"kind", "t_s", "odom_pose", "epsilon_m", "measure", "bound", "legs_m", "partial",
            "anchor_odom", "island", "edge", "accepted_island_id", "reason",
            "revisited_island_id", "island_pose", "island_pose_t_s", "residual_m",
            "exit_updates", "truth_pose", "hypotheses"}
    obj = jc.obj(d, path, keys, {"kind", "t_s", "odom_pose", "epsilon_m"})
    updates = obj.get("exit_updates") or []
    return BuilderEvent(
        kind=_enum(EventKind, obj["kind"], f"{path}.kind"),
        t_s=jc.float_(obj["t_s"], f"{path}.t_s"),
        odom_pose=json_io.pose_from_dict(obj["odom_pose"], f"{path}.odom_pose"),
        epsilon_m=jc.float_(obj["epsilon_m"], f"{path}.epsilon_m"),
        anchor_odom=_opt(obj, "anchor_odom", json_io.pose_from_dict, path),
        island=_opt(obj, "island", json_io.island_from_dict, path),
        edge=_opt(obj, "edge", json_io.edge_from_dict, path),
        accepted_island_id=_opt(obj, "accepted_island_id", jc.island_id, path),
        revisited_island_id=_opt(obj, "revisited_island_id", jc.island_id, path),
        island_pose=_opt(obj, "island_pose", json_io.pose_from_dict, path),
        island_pose_t_s=_opt(obj, "island_pose_t_s", jc.float_, path),
        exit_updates=tuple(json_io.exit_update_from_dict(u, f"{path}.exit_updates[{k}]")
                           for k, u in enumerate(jc.list_(updates, f"{path}.exit_updates"))),
        hypotheses=tuple(_hypothesis(h, f"{path}.hypotheses[{k}]") for k, h in enumerate(
            jc.list_(obj.get("hypotheses") or [], f"{path}.hypotheses"))),
    )


def _hypothesis(d: Any, path: str) -> Hypothesis:
    obj = jc.obj(d, path, {"island", "pose", "inlier_fraction"},
                 {"island", "pose", "inlier_fraction"})
    return Hypothesis(jc.island_id(obj["island"], f"{path}.island"),
                      json_io.pose_from_dict(obj["pose"], f"{path}.pose"),
                      jc.float_(obj["inlier_fraction"], f"{path}.inlier_fraction"))


# ----------------------------------------------------------------------------- map items


def graph_item_to_parameter(item: GraphItem | NewExit) -> Parameter:
    """One `topo_graph/add` item: an island, an edge, an exit's new state or a new exit."""
    if isinstance(item, Island):
        return cv.island_to_parameter(item)
    if isinstance(item, ExitUpdate):
        return cv.exit_update_to_parameter(item)
    if isinstance(item, NewExit):
        return cv.new_exit_to_parameter(item)
    return cv.edge_to_parameter(item)


# ----------------------------------------------------------------------------- requests


def _string_param(name: str, doc: dict[str, Any]) -> Parameter:
    return Parameter(name=name, value=ParameterValue(type=ParameterType.PARAMETER_STRING,
                                                     string_value=json.dumps(doc)))


def request_to_parameter(request: ExplorerRequest) -> Parameter:
    """One explorer request as an `island_builder/explorer` item."""
    if isinstance(request, Docked):
        return _string_param(DOCKED_PARAM, {"island": request.island_id,
                                            "origin_odom": json_io.pose_to_dict(
                                                request.origin_odom)})
    if isinstance(request, Handover):
        return _string_param(HANDOVER_PARAM, {"island": request.island_id,
                                              "exit": request.exit_index,
                                              "prefix": str(request.prefix)})
    if isinstance(request, Confirm):
        return _string_param(CONFIRM_PARAM, {"island": request.island_id})
    if isinstance(request, Reject):
        return _string_param(REJECT_PARAM, {})
    return _string_param(ABORT_PARAM, {})


def parameter_to_request(param: Parameter, path: str = "parameter") -> ExplorerRequest:
    """Decode one `island_builder/explorer` item; ExplorerMessageError names what is wrong."""
    if param.name not in REQUEST_PARAMS:
        raise ExplorerMessageError(f"{path}.name: expected one of {list(REQUEST_PARAMS)}, got "
                                   f"{param.name[:40]!r}")
    if param.value.type != ParameterType.PARAMETER_STRING:
        raise ExplorerMessageError(f"{path}.value: expected a string holding JSON, got "
                                   f"parameter type {param.value.type}")
    text = param.value.string_value
    if len(text) > MAX_REQUEST_CHARS:
        raise ExplorerMessageError(f"{path}.value: {len(text)} characters, the limit is "
                                   f"{MAX_REQUEST_CHARS}")
    where = f"{path} ({param.name})"
    try:
        if param.name in (ABORT_PARAM, REJECT_PARAM):
            jc.obj(jc.loads(text or "{}", where), where, set(), set())
            return Abort() if param.name == ABORT_PARAM else Reject()
        if param.name == CONFIRM_PARAM:
            d = jc.obj(jc.loads(text, where), where, {"island"}, {"island"})
            return Confirm(jc.island_id(d["island"], f"{where}.island"))
        if param.name == DOCKED_PARAM:
            d = jc.obj(jc.loads(text, where), where, {"island", "origin_odom"},
                       {"island", "origin_odom"})
            return Docked(jc.island_id(d["island"], f"{where}.island"),
                          json_io.pose_from_dict(d["origin_odom"], f"{where}.origin_odom"))
        d = jc.obj(jc.loads(text, where), where, {"island", "exit", "prefix"},
                   {"island", "exit", "prefix"})
        exit_index = None if d["exit"] is None else jc.int_(d["exit"], f"{where}.exit")
        return Handover(jc.island_id(d["island"], f"{where}.island"), exit_index,
                        ControlStrategy.parse(jc.str_(d["prefix"], f"{where}.prefix")))
    except (InputError, IslandTypeError) as exc:
        raise ExplorerMessageError(str(exc)) from None


# ----------------------------------------------------------------------------- status


def status_to_msg(status: ExplorerStatus) -> String:
    return String(data=json.dumps(status.to_dict()))
