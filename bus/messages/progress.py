"""What a robot has covered: its progress, its look steps, and its re-learnable state."""

from __future__ import annotations

import zlib
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
    it stands on, the cycle indices it is still to walk, and every cycle index it knows
    covered (``pack_covered``). Every survivor re-plans from the same set of reports."""

    KIND: ClassVar[str] = "replan_report"
    robot: int
    incarnation: int
    dead: tuple[int, ...]
    position: int
    route: tuple[int, ...]
    covered: bytes


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
