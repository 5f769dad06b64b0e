"""`load_world(spec)`: a world from a built-in name or a file of any supported kind.

The one dispatch over the world sources: built-ins (`worlds_builtin`), YAML/JSON segment files
(`world.world_from_dict`), HouseExpo JSON, ROS map_server YAML and occupancy images
(`importers`). It sits above them all, so none of them imports it.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from island_msgs_py.json_checks import describe
from island_msgs_py.limits import MAX_PATH_CHARS

from island_sim.core import importers, worlds_builtin
from island_sim.core.generate import SPEC_PREFIX, generated_world
from island_sim.core.world import (
    MAX_NAME_CHARS,
    World,
    WorldError,
    read_structured,
    world_from_dict,
)

_STRUCTURED_SUFFIXES = (".yaml", ".yml", ".json")
_IMAGE_SUFFIXES = (".pgm", ".png")


def load_world(spec: str | Path, resolution_m: float | None = None) -> World:
    """A world from a built-in name or a file.

    Built-ins: paper_fig3, paper_fig4, corridor, square_room, t_junction; generated offices
    `gen:office:seed=N,scale=S` (`generate.py`).
    Files: YAML/JSON with `segments` (see `world_from_dict`), or with `verts` (HouseExpo), or
    with `image` (a ROS map_server YAML: image path relative to the file, `resolution` [m/px],
    `origin` [x, y, theta]); occupancy images .pgm/.png with `resolution_m` [m/px] (default
    0.1), origin at the lower-left corner, dark pixels = walls.
    """
    if isinstance(spec, str) and spec in worlds_builtin.BUILTIN_WORLDS:
        return worlds_builtin.builtin_world(spec)
    if isinstance(spec, str) and spec.startswith(SPEC_PREFIX):
        return generated_world(spec)
    path = Path(spec)
    suffix = path.suffix.lower()
    try:
        exists = path.exists()
    except OSError as exc:  # e.g. a name too long for the file system
        raise WorldError(f"{describe(str(spec))}: cannot read: {exc.strerror or exc}") from None
    if not exists:
        if not suffix:
            raise WorldError(
                f"{spec}: neither a built-in world "
                f"({', '.join(sorted(worlds_builtin.BUILTIN_WORLDS))}) nor an existing file"
            )
        raise WorldError(f"{path}: no such file")
    if suffix in _IMAGE_SUFFIXES:
        cfg = importers.ImageImportConfig(
            resolution_m=resolution_m if resolution_m is not None else 0.1
        )
        return importers.import_image(path, cfg)
    if suffix not in _STRUCTURED_SUFFIXES:
        raise WorldError(
            f"{path}: unknown world file extension {path.suffix!r} "
            f"(use {', '.join(_STRUCTURED_SUFFIXES + _IMAGE_SUFFIXES)})"
        )
    data = read_structured(path)
    if "segments" in data:
        return world_from_dict(data, str(path))
    if "verts" in data:
        return importers.import_houseexpo(path, data)
    if "image" in data:
        return _load_map_yaml(path, data, resolution_m)
    raise WorldError(
        f"{path}: missing key 'segments' (or 'verts' for HouseExpo, 'image' for a map YAML)"
    )


def _load_map_yaml(path: Path, data: dict[str, Any], resolution_m: float | None) -> World:
    """A ROS map_server YAML (image, resolution, origin, occupied_thresh, free_thresh); every
    error names this file and the key."""
    image = data["image"]
    if not isinstance(image, str) or not image or len(image) > MAX_PATH_CHARS or "\0" in image:
        raise WorldError(f"{path}: 'image' must be a file name of at most {MAX_PATH_CHARS} "
                         f"characters, got {describe(image)}")
    img_path = Path(image) if Path(image).is_absolute() else path.parent / image
    kwargs: dict[str, float] = {}
    res = resolution_m if resolution_m is not None else _number(data, "resolution", 0.1, path)
    origin = data.get("origin", [0.0, 0.0, 0.0])
    if not isinstance(origin, list | tuple) or len(origin) not in (2, 3):
        raise WorldError(f"{path}: 'origin' must be [x, y, theta], got {describe(origin)}")
    kwargs["origin_x_m"] = _number({"origin[0]": origin[0]}, "origin[0]", 0.0, path)
    kwargs["origin_y_m"] = _number({"origin[1]": origin[1]}, "origin[1]", 0.0, path)
    for key in ("occupied_thresh", "free_thresh"):
        if key in data:
            kwargs[key] = _number(data, key, 0.0, path)
    try:
        cfg = importers.ImageImportConfig(resolution_m=res, **kwargs)
    except WorldError as exc:
        raise WorldError(f"{path}: {exc}") from None
    try:
        exists = img_path.exists()
    except OSError as exc:
        raise WorldError(f"{path}: 'image': cannot read: {exc.strerror or exc}") from None
    if not exists:
        raise WorldError(f"{path}: 'image' {describe(image)}: no such file "
                         f"{describe(str(img_path))}")
    world = importers.import_image(img_path, cfg)
    name = data.get("name", path.stem)
    return World(world.segments, name=str(name)[:MAX_NAME_CHARS] if isinstance(name, str)
                 else path.stem, start_pose=world.start_pose)


def _number(data: dict[str, Any], key: str, default: float, path: Path) -> float:
    """data[key] (or `default`) as a finite number; WorldError naming the file and key."""
    value = data.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise WorldError(f"{path}: {key!r} must be a number, got {describe(value)}")
    try:
        f = float(value)
    except OverflowError:
        f = math.inf
    if not math.isfinite(f):
        raise WorldError(f"{path}: {key!r} must be a finite number, got {describe(value)}")
    return f
