"""`load_world(spec)`: a world from a built-in name or a file of any supported kind.

The one dispatch over the world sources: built-ins (`worlds_builtin`), YAML/JSON segment files
(`world.world_from_dict`), HouseExpo JSON, ROS map_server YAML and occupancy images
(`importers`). It sits above them all, so none of them imports it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from island_sim.core import importers, worlds_builtin
from island_sim.core.generate import SPEC_PREFIX, generated_world
from island_sim.core.world import World, WorldError, read_structured, world_from_dict

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
    if not path.exists():
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
    """A ROS map_server YAML (image, resolution, origin, occupied_thresh, free_thresh)."""
    image = data["image"]
    if not isinstance(image, str) or not image:
        raise WorldError(f"{path}: 'image' must be a file name")
    img_path = Path(image) if Path(image).is_absolute() else path.parent / image
    kwargs: dict[str, float] = {}
    try:
        res = resolution_m if resolution_m is not None else float(data.get("resolution", 0.1))
        origin = data.get("origin", [0.0, 0.0, 0.0])
        kwargs["origin_x_m"], kwargs["origin_y_m"] = float(origin[0]), float(origin[1])
        for key in ("occupied_thresh", "free_thresh"):
            if key in data:
                kwargs[key] = float(data[key])
    except (TypeError, ValueError, IndexError, KeyError) as exc:
        raise WorldError(f"{path}: bad resolution/origin/thresholds: {exc}") from exc
    cfg = importers.ImageImportConfig(resolution_m=res, **kwargs)
    world = importers.import_image(img_path, cfg)
    name = str(data.get("name", path.stem))
    return World(world.segments, name=name, start_pose=world.start_pose)
