"""Builtin worlds: small ASCII maps shipped inside the package.

importlib.resources reads them, so they work from a wheel or zip as well as from a checkout.
"""

from __future__ import annotations

from importlib import resources

from planner.errors import MapReadError
from planner.maps.ascii import parse_ascii
from planner.types import OccupancyGrid

BUILTIN_WORLDS: tuple[str, ...] = ("example", "open-room", "office", "grid30x20", "cave", "room")
_PACKAGE = "planner.data.worlds"


def builtin_world(name: str) -> OccupancyGrid:
    """The builtin world called ``name`` (one of BUILTIN_WORLDS)."""
    if name not in BUILTIN_WORLDS:
        raise MapReadError(name, "unknown builtin world; the builtin worlds are "
                           + ", ".join(BUILTIN_WORLDS))
    text = resources.files(_PACKAGE).joinpath(f"{name}.txt").read_text(encoding="utf-8")
    return parse_ascii(text, source=f"builtin:{name}", name=name)
