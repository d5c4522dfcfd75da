"""A crowded offline fleet's first plan, computed by one robot and shared with the others."""

from __future__ import annotations

import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import numpy.typing as npt

from bus.messages.base import SubCell, inflate

# A move's two bits: the sub-cell step it makes (row, col).
_STEPS = np.array([(-1, 0), (0, 1), (1, 0), (0, -1)], dtype=np.int64)


@dataclass(frozen=True)
class PlanShare:
    """The plan of the agreed participants as the one robot that computes it in a crowded
    fleet (``robot``, the lowest participant) made it, for the others to check and fly
    instead of each computing it (agent.offline.planshare). ``inputs`` names what it was
    made from (world, participants, starts, algorithm, tree, seed), ``digest`` is its
    planner.digest; the cycle is ``cycle_start`` then ``cycle`` (``pack_moves``), and each
    participant's walk (in robot-id order) is ``lengths`` moves of ``moves`` from its agreed
    start; ``walk_outs``, ``legs`` (as planner.digest writes them: "ccw12,cw3") and ``notes``
    are the plan's. ``problem`` is set, and the plan left out, when the sharer could not
    share it (it does not fit a message): the others then compute it themselves at once."""

    KIND: ClassVar[str] = "plan_share"
    robot: int
    incarnation: int
    inputs: str
    digest: str
    cycle_start: SubCell
    cycle: bytes
    lengths: tuple[int, ...]
    moves: bytes
    walk_outs: tuple[int, ...]
    legs: tuple[str, ...]
    notes: tuple[str, ...]
    problem: str


def pack_moves(path: Sequence[SubCell] | npt.NDArray[np.int64]) -> bytes:
    """The moves of a 4-adjacent walk, two bits each, then zlib: a 47 000-sub-cell plan packs
    to a few kilobytes. ValueError if two consecutive sub-cells are not 4-adjacent."""
    return _pack_steps(np.diff(np.asarray(path, dtype=np.int64).reshape(-1, 2), axis=0))


def join_moves(walks: Sequence[Sequence[SubCell] | npt.NDArray[np.int64]]) -> bytes:
    """The moves of every walk one after the other, packed (split_moves reads them)."""
    steps = [np.diff(np.asarray(walk, dtype=np.int64).reshape(-1, 2), axis=0) for walk in walks]
    return _pack_steps(np.vstack(steps) if steps else np.zeros((0, 2), dtype=np.int64))


def unpack_moves(data: bytes, start: SubCell, count: int) -> npt.NDArray[np.int64]:
    """The walk of ``count`` moves from ``start`` packed by pack_moves (``count + 1``
    sub-cells, start first); ValueError if ``data`` does not hold that many moves."""
    return _walk(start, _unpack_steps(data, count))


def split_moves(data: bytes, starts: Sequence[SubCell], lengths: Sequence[int]
                ) -> list[npt.NDArray[np.int64]]:
    """Walks packed one after the other (join_moves), cut at ``lengths`` and each begun at
    its start; ValueError if the data does not fit."""
    if len(starts) != len(lengths):
        raise ValueError(f"{len(lengths)} walk lengths for {len(starts)} starts")
    if any(n < 0 for n in lengths):
        raise ValueError("a walk cannot have a negative length")
    steps = _unpack_steps(data, sum(lengths))
    cuts = np.cumsum([0, *lengths])
    return [_walk(start, steps[a:b]) for start, a, b in zip(starts, cuts[:-1], cuts[1:],
                                                              strict=True)]


def _pack_steps(steps: npt.NDArray[np.int64]) -> bytes:
    codes = np.full(len(steps), -1, dtype=np.int64)
    for code, step in enumerate(_STEPS):
        codes[(steps == step).all(axis=1)] = code
    if (codes < 0).any():
        i = int(np.flatnonzero(codes < 0)[0])
        raise ValueError(f"step {i} of the walk is not one 4-adjacent move")
    # four moves to a byte, the first in the high bits
    quads = np.concatenate([codes, np.zeros(-len(codes) % 4, dtype=np.int64)]).reshape(-1, 4)
    packed = (quads[:, 0] << 6) | (quads[:, 1] << 4) | (quads[:, 2] << 2) | quads[:, 3]
    return zlib.compress(packed.astype(np.uint8).tobytes())


def _unpack_steps(data: bytes, count: int) -> npt.NDArray[np.int64]:
    if count < 0:
        raise ValueError(f"a walk cannot have {count} moves")
    size = (count + 3) // 4
    raw = np.frombuffer(inflate(data, size + 1), dtype=np.uint8)
    if raw.size != size:
        raise ValueError(f"{raw.size} bytes of moves, {size} expected for {count} moves")
    codes = np.stack([(raw >> shift) & 3 for shift in (6, 4, 2, 0)], axis=1).reshape(-1)
    return _STEPS[codes[:count]]


def _walk(start: SubCell, steps: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
    return np.cumsum(np.vstack([np.asarray([start], dtype=np.int64), steps]), axis=0)
