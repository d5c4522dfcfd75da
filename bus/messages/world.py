"""The simulator's ground truth (sim-only keys): poses, covers, bumps and the whole world."""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from bus.messages.base import Pose, SubCell, inflate


@dataclass(frozen=True)
class GroundTruthPose:
    KIND: ClassVar[str] = "gt_pose"
    robot: int
    pose: Pose
    sim_time: float


@dataclass(frozen=True)
class CoverEvent:
    """``visits`` is how many times ``cell`` (a sub-cell) has been covered, this one included."""

    KIND: ClassVar[str] = "cover"
    robot: int
    cell: SubCell
    sim_time: float
    visits: int


@dataclass(frozen=True)
class BumpEvent:
    """``at`` is where the body stood, ``into`` the sub-cell it tried to enter."""

    KIND: ClassVar[str] = "bump"
    robot: int
    at: SubCell
    into: SubCell
    sim_time: float


@dataclass(frozen=True)
class RobotTruth:
    robot: int
    pose: Pose
    alive: bool
    frozen: bool
    failed: bool
    covered: int


NO_ROBOT = 255  # "nobody" in the packed per-sub-cell and per-edge robot arrays


@dataclass(frozen=True)
class WorldState:
    """The whole world for a monitor. ``free`` is numpy.packbits of the row-major free mask;
    ``visits`` is zlib-compressed uint8 visit counts (saturating at 255), row-major;
    ``first`` the same for the robot that entered each sub-cell first (255: nobody);
    ``crossed`` the same for the first robot to cross each border between 2 x 2 cells:
    the ``right`` then the ``down`` array over cells (planner.types.SpanningTree's layout)."""

    KIND: ClassVar[str] = "world"
    map_name: str
    shape: tuple[int, int]
    free: bytes
    visits: bytes
    robots: tuple[RobotTruth, ...]
    sim_time: float
    time_scale: float
    first: bytes
    crossed: bytes


RobotArray = npt.NDArray[np.uint8]



def make_world_state(
    map_name: str, free: npt.NDArray[np.bool_], visits: npt.NDArray[np.integer[Any]],
    robots: tuple[RobotTruth, ...], sim_time: float, time_scale: float, *,
    first: RobotArray | None = None, crossed: tuple[RobotArray, RobotArray] | None = None,
) -> WorldState:
    """Pack a free mask, visit counts and first visitors (same 2-D shape; robot ids < 255)
    and the first crossers of cell borders into a WorldState; omitted arrays mean nobody."""
    if free.shape != visits.shape or free.ndim != 2:
        raise ValueError("free and visits must be 2-D arrays of the same shape")
    h, w = free.shape
    firsts = np.full(free.shape, NO_ROBOT, np.uint8) if first is None else first
    right, down = crossed if crossed is not None else (
        np.full((h // 2, max(w // 2 - 1, 0)), NO_ROBOT, np.uint8),
        np.full((max(h // 2 - 1, 0), w // 2), NO_ROBOT, np.uint8))
    if firsts.shape != free.shape or right.shape != (h // 2, max(w // 2 - 1, 0)) \
            or down.shape != (max(h // 2 - 1, 0), w // 2):
        raise ValueError("first must have the map's shape, crossed the cells' border shapes")
    counts = np.clip(visits, 0, 255).astype(np.uint8)
    return WorldState(
        map_name=map_name, shape=(int(h), int(w)),
        free=np.packbits(free.astype(bool), axis=None).tobytes(),
        visits=zlib.compress(counts.tobytes()), robots=robots,
        sim_time=float(sim_time), time_scale=float(time_scale),
        first=zlib.compress(firsts.astype(np.uint8).tobytes()),
        crossed=zlib.compress(right.astype(np.uint8).tobytes()
                              + down.astype(np.uint8).tobytes()))


def _cells(state: WorldState) -> int:
    """The sub-cell count of ``state.shape``; ValueError unless its free mask holds them
    (which also bounds what a forged shape can make us allocate)."""
    h, w = state.shape
    if h < 0 or w < 0 or h * w > len(state.free) * 8:
        raise ValueError(f"shape {state.shape} does not fit a free mask of "
                         f"{len(state.free)} bytes")
    return h * w


def world_free(state: WorldState) -> npt.NDArray[np.bool_]:
    """The free mask of a WorldState as a bool array of ``state.shape``."""
    count = _cells(state)
    bits = np.unpackbits(np.frombuffer(state.free, dtype=np.uint8), count=count)
    return bits.astype(bool).reshape(state.shape)


def world_visits(state: WorldState) -> npt.NDArray[np.uint8]:
    """The visit counts of a WorldState as a uint8 array of ``state.shape``."""
    return _unzip(state.visits, _cells(state)).reshape(state.shape)


def world_first(state: WorldState) -> RobotArray:
    """Who entered each sub-cell first (NO_ROBOT: nobody yet), an array of ``state.shape``."""
    return _unzip(state.first, _cells(state)).reshape(state.shape)


def world_crossed(state: WorldState) -> tuple[RobotArray, RobotArray]:
    """The first crossers of cell borders as (right, down) arrays (NO_ROBOT: nobody)."""
    _cells(state)
    h, w = state.shape[0] // 2, state.shape[1] // 2
    n_right, n_down = h * max(w - 1, 0), max(h - 1, 0) * w
    raw = _unzip(state.crossed, n_right + n_down)
    return (raw[:n_right].reshape(h, max(w - 1, 0)), raw[n_right:].reshape(max(h - 1, 0), w))


def _unzip(data: bytes, size: int) -> npt.NDArray[np.uint8]:
    """ValueError (not a zlib error) for a payload that does not unpack to ``size`` bytes;
    decompression stops one byte past ``size``, so a zip bomb costs nothing."""
    raw = np.frombuffer(inflate(data, size + 1), dtype=np.uint8)
    if raw.size != size:
        raise ValueError(f"packed array has {raw.size} bytes, expected {size}")
    return raw
