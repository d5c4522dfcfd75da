"""What a robot has covered: its progress, its look steps, and its re-learnable state."""

from __future__ import annotations

import itertools
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import numpy.typing as npt

from bus.messages.base import SubCell, inflate


@dataclass(frozen=True)
class Progress:
    KIND: ClassVar[str] = "progress"
    robot: int
    incarnation: int
    seq: int
    cell: SubCell
    sim_time: float


@dataclass(frozen=True)
class LookStep:
    """An ORMSTC robot stepped into ``cell`` (a sub-cell of its own cell) only to sense: the
    ``seq``-th step aside or back of a look from beside (docs/ormstc.md, sensing), so that a
    report can tell these entries from coverage revisits."""

    KIND: ClassVar[str] = "look_step"
    robot: int
    incarnation: int
    seq: int
    cell: SubCell


@dataclass(frozen=True)
class AgentState:
    """An agent's re-learnable knowledge, the reply of its ``state/<r>`` queryable (never
    published): its phase, its moves, every cycle index it knows covered (``pack_covered``:
    bits in cycle-index order; offline algorithms), the robots it knows dead, the robots it
    took over, its drop counters ("kind.reason" -> count), for ORMSTC its tree edges
    (parent, child) and its claims not settled yet (cells of 2 x 2 sub-cells), and for
    offline algorithms the plan's tree kind and seed (so a monitor can rebuild the tree)."""

    KIND: ClassVar[str] = "agent_state"
    robot: int
    incarnation: int
    state: str
    moves: int
    n: int
    covered: bytes
    dead: tuple[int, ...]
    took_over: tuple[int, ...]
    drops: dict[str, int] = field(default_factory=dict)
    tree: tuple[tuple[tuple[int, int], tuple[int, int]], ...] = ()
    claims: tuple[tuple[int, int], ...] = ()
    tree_kind: str = ""
    seed: int = 0


@dataclass(frozen=True)
class ReplanReport:
    """What a survivor holds when it stops to re-plan after deaths (offline agents with
    ``--recovery rebalance``): the robots it knows dead (the re-plan's epoch), the cycle index
    it stands on, the cycle indices it is still to walk, every cycle index it knows covered
    (``pack_covered``) and its simulated time when it stopped (the places it is heard of
    later were walked after the report: agent.offline.bodies). Every survivor re-plans from
    the same set of reports."""

    KIND: ClassVar[str] = "replan_report"
    robot: int
    incarnation: int
    dead: tuple[int, ...]
    position: int
    route: tuple[int, ...]
    covered: bytes
    sim_time: float


@dataclass(frozen=True)
class ReplanShare:
    """The re-plan of epoch ``dead`` as the one survivor that computes it in a crowded fleet
    (``robot``) made it, for the others to check and walk instead of each computing it
    (agent.offline.replan): ``digest`` names the reports it was made from, ``robots`` the
    survivors, ``lengths`` their routes' lengths and ``places`` the routes one after the
    other (``pack_routes``)."""

    KIND: ClassVar[str] = "replan_share"
    robot: int
    incarnation: int
    dead: tuple[int, ...]
    digest: str
    robots: tuple[int, ...]
    lengths: tuple[int, ...]
    places: bytes


def pack_routes(routes: Sequence[Sequence[int]]) -> bytes:
    """The routes one after the other as int32 steps (each place minus the one before),
    then zlib: a route is mostly steps of one along the cycle, so it packs to little."""
    flat = np.fromiter((p for route in routes for p in route), dtype=np.int64)
    return zlib.compress(np.diff(flat, prepend=0).astype("<i4").tobytes())


def unpack_routes(data: bytes, lengths: Sequence[int]) -> list[list[int]]:
    """The routes packed by pack_routes, cut at ``lengths``; ValueError if ``data`` is not
    that many places."""
    if any(n < 0 for n in lengths):
        raise ValueError("a route cannot have a negative length")
    total = sum(lengths)
    raw = inflate(data, 4 * total + 1)  # one byte more shows a stream that is too long
    if len(raw) != 4 * total:
        raise ValueError(f"{len(raw)} bytes of routes, {4 * total} expected")
    flat = np.cumsum(np.frombuffer(raw, dtype="<i4").astype(np.int64)).tolist()
    cuts = np.cumsum([0, *lengths]).tolist()
    return [flat[a:b] for a, b in itertools.pairwise(cuts)]


def pack_covered(covered: npt.NDArray[np.bool_]) -> bytes:
    """Bits, then zlib: coverage is long runs, so even a 10^6-sub-cell map fits a message."""
    return zlib.compress(np.packbits(covered.astype(bool)).tobytes())


def unpack_covered(data: bytes, n: int) -> npt.NDArray[np.bool_]:
    """The bool array of ``n`` packed by pack_covered; ValueError if ``data`` is not one."""
    if n < 0:
        raise ValueError(f"cannot unpack {n} bits")
    # Stop decompressing at the bytes n bits need: a zip bomb then costs nothing.
    raw = np.frombuffer(inflate(data, (n + 7) // 8), dtype=np.uint8)
    if raw.size * 8 < n:
        raise ValueError(f"{raw.size} bytes cannot hold {n} bits")
    return np.unpackbits(raw, count=n).astype(bool)
