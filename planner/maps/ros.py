"""ROS map_server YAML: the metadata of an occupancy image.

PyYAML's safe_load reads it (no arbitrary object construction from a file); the composed node
tree gives the line of each key, so an error points at the line to fix.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from planner.errors import MapFormatError
from planner.maps.image import Thresholds

REQUIRED = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")
MODES = ("trinary", "scale")


@dataclass(frozen=True)
class RosMap:
    """What the planner needs from a map_server YAML."""

    image: Path
    resolution: float
    origin: tuple[float, float, float]
    thresholds: Thresholds


def _key_lines(text: str) -> dict[str, int]:
    import yaml

    node = yaml.compose(text, Loader=yaml.SafeLoader)
    if not isinstance(node, yaml.MappingNode):
        return {}
    return {str(key.value): key.start_mark.line + 1 for key, _ in node.value}


def _load(text: str, source: str) -> tuple[dict[str, Any], dict[str, int]]:
    # PyYAML is imported here, not at the top, for the reason read_image gives for Pillow
    import yaml

    try:
        data = yaml.safe_load(text)
        lines = _key_lines(text)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark
        line = mark.line + 1 if mark is not None else None
        column = mark.column + 1 if mark is not None else None
        raise MapFormatError(source, f"invalid YAML: {exc.problem}", line=line,
                             column=column) from None
    except yaml.YAMLError as exc:
        raise MapFormatError(source, f"invalid YAML: {exc}") from None
    if not isinstance(data, dict):
        raise MapFormatError(source, "expected a mapping with keys " + ", ".join(REQUIRED))
    return data, lines


def _number(data: dict[str, Any], key: str, lines: dict[str, int], source: str,
            low: float, high: float) -> float:
    value = data[key]
    if isinstance(value, bool) or not isinstance(value, int | float) or not low <= value <= high:
        raise MapFormatError(source, f"key '{key}' must be a number in [{low}, {high}], "
                             f"got {value!r}", line=lines.get(key))
    return float(value)


def _origin(data: dict[str, Any], lines: dict[str, int], source: str) -> tuple[float, ...]:
    value = data["origin"]
    if (not isinstance(value, list) or len(value) != 3
            or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)):
        raise MapFormatError(source, f"key 'origin' must be a list [x, y, yaw] of 3 numbers, "
                             f"got {value!r}", line=lines.get("origin"))
    return tuple(float(v) for v in value)


def parse_ros_yaml(text: str, source: str | os.PathLike[str]) -> RosMap:
    """The map metadata; the image path is resolved against the YAML's folder."""
    where = os.fspath(source)
    data, lines = _load(text, where)
    missing = [key for key in REQUIRED if key not in data]
    if missing:
        raise MapFormatError(where, f"missing key '{missing[0]}' (a ROS map YAML needs "
                             + ", ".join(REQUIRED) + ")")
    image = data["image"]
    if not isinstance(image, str) or not image:
        raise MapFormatError(where, f"key 'image' must be a file name, got {image!r}",
                             line=lines.get("image"))
    negate = data["negate"]
    if negate not in (0, 1) or isinstance(negate, float):
        raise MapFormatError(where, f"key 'negate' must be 0 or 1, got {negate!r}",
                             line=lines.get("negate"))
    mode = data.get("mode", "trinary")
    if mode not in MODES:
        # raw mode stores occupancy percentages, not grey levels: a different map language.
        raise MapFormatError(where, f"key 'mode' must be one of {', '.join(MODES)}, got "
                             f"{mode!r}", line=lines.get("mode"))
    resolution = _number(data, "resolution", lines, where, 0.0, float("inf"))
    if resolution <= 0:
        raise MapFormatError(where, f"key 'resolution' must be positive, got {resolution!r}",
                             line=lines.get("resolution"))
    x, y, yaw = _origin(data, lines, where)
    thresholds = Thresholds(
        occupied=_number(data, "occupied_thresh", lines, where, 0.0, 1.0),
        free=_number(data, "free_thresh", lines, where, 0.0, 1.0),
        negate=bool(negate))
    return RosMap(image=Path(where).parent / image, resolution=resolution,
                  origin=(x, y, yaw), thresholds=thresholds)


def cell_size_for(ros: RosMap, tool_width: float, source: str) -> int:
    """Pixels per sub-cell for a tool of ``tool_width`` metres."""
    if isinstance(tool_width, bool) or not isinstance(tool_width, int | float) or tool_width <= 0:
        raise MapFormatError(source, f"tool_width must be a positive number of metres, "
                             f"got {tool_width!r}")
    size = round(tool_width / ros.resolution)
    if size < 1:
        raise MapFormatError(source, f"tool_width {tool_width} m is smaller than one pixel "
                             f"({ros.resolution} m)")
    return size
