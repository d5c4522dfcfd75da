"""Map loading: one module per file format, dispatched here on the file's suffix.

    load_map("office.txt")                       # plain ASCII, one character per sub-cell
    load_map("arena.map")                        # Moving AI
    load_map("floor.yaml", tool_width=0.5)       # ROS map_server YAML + image
    load_map("indoor_real.pgm", cell_size=10)    # occupancy image, 10 px per sub-cell
    resolve_world("office")                      # a builtin world, else a path
    resolve_world("rooms:30x40:3")               # a generated world (planner.maps.generated)
"""

from __future__ import annotations

import os
from pathlib import Path

from planner.errors import MapFormatError, MapReadError
from planner.maps.ascii import parse_ascii
from planner.maps.discretize import downsample
from planner.maps.files import describe, read_image, read_text
from planner.maps.generated import EXAMPLES, generated_world, is_generated
from planner.maps.image import ROS_DEFAULTS, Thresholds, free_pixels
from planner.maps.movingai import parse_movingai
from planner.maps.ros import cell_size_for, parse_ros_yaml
from planner.maps.worlds import BUILTIN_WORLDS, builtin_world
from planner.types import BoolArray, OccupancyGrid

__all__ = ["BUILTIN_WORLDS", "builtin_world", "load_map", "parse_ascii", "resolve_world"]

TEXT_SUFFIXES = (".txt", ".ascii")
MOVINGAI_SUFFIXES = (".map",)
ROS_SUFFIXES = (".yaml", ".yml")
IMAGE_SUFFIXES = (".pgm", ".png", ".ppm", ".pbm", ".bmp", ".gif", ".tif", ".tiff", ".jpg",
                  ".jpeg", ".webp")
ACCEPTED = TEXT_SUFFIXES + MOVINGAI_SUFFIXES + ROS_SUFFIXES + IMAGE_SUFFIXES


def _size(cell_size: int | None) -> int:
    return 1 if cell_size is None else cell_size


def _image_free(path: str | os.PathLike[str], thresholds: Thresholds) -> BoolArray:
    return free_pixels(read_image(path), thresholds, describe(path))


def _load_free(path: str | os.PathLike[str], suffix: str, cell_size: int | None,
               tool_width: float | None) -> tuple[BoolArray, int]:
    """The per-character/pixel free mask and the pixels per sub-cell to apply to it."""
    source = describe(path)
    if tool_width is not None and suffix not in ROS_SUFFIXES:
        raise MapFormatError(source, "tool_width needs the map's resolution, which only a ROS "
                             ".yaml map gives; pass cell_size (pixels per sub-cell) instead")
    if suffix in TEXT_SUFFIXES:
        return parse_ascii(read_text(path), source).free, _size(cell_size)
    if suffix in MOVINGAI_SUFFIXES:
        return parse_movingai(read_text(path), source), _size(cell_size)
    if suffix in ROS_SUFFIXES:
        ros = parse_ros_yaml(read_text(path), source)
        if tool_width is not None:
            by_width = cell_size_for(ros, tool_width, source)
            if cell_size is not None and cell_size != by_width:
                raise MapFormatError(source, f"cell_size {cell_size} disagrees with tool_width "
                                     f"{tool_width} m at {ros.resolution} m/px ({by_width} px)")
            cell_size = by_width
        return _image_free(ros.image, ros.thresholds), _size(cell_size)
    return _image_free(path, ROS_DEFAULTS), _size(cell_size)


def load_map(path: str | os.PathLike[str], cell_size: int | None = None, *,
             name: str | None = None, tool_width: float | None = None) -> OccupancyGrid:
    """Load a map file as sub-cells; the format follows the suffix.

    ``cell_size`` is pixels (or characters) per sub-cell side, default 1; ``tool_width`` (ROS
    YAML only) gives it in metres instead. A sub-cell is free only if all its pixels are.
    """
    suffix = Path(path).suffix.lower()
    if suffix not in ACCEPTED:
        raise MapFormatError(describe(path), f"unknown map format {suffix or '(no suffix)'!r}; "
                             "accepted suffixes: " + ", ".join(ACCEPTED))
    free, size = _load_free(path, suffix, cell_size, tool_width)
    sub_cells = downsample(free, size, describe(path))
    return OccupancyGrid(sub_cells, name=name if name is not None else Path(path).stem)


def resolve_world(spec: str | os.PathLike[str], cell_size: int | None = None) -> OccupancyGrid:
    """A builtin world by name (BUILTIN_WORLDS), a generated world by its spec
    (planner.maps.generated, e.g. ``rooms:30x40:3``), else a map file by path."""
    text = os.fspath(spec)
    if text in BUILTIN_WORLDS:
        world = builtin_world(text)
        return OccupancyGrid(downsample(world.free, _size(cell_size), text), name=text)
    if is_generated(text) and not Path(text).exists():
        world = generated_world(text)
        return OccupancyGrid(downsample(world.free, _size(cell_size), text), name=text)
    if not Path(text).exists():
        raise MapReadError(text, "neither a builtin world, a generated world nor an existing "
                           "map file; the builtin worlds are " + ", ".join(BUILTIN_WORLDS)
                           + "; generated ones look like " + ", ".join(EXAMPLES))
    return load_map(text, cell_size)
