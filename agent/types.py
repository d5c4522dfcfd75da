"""Value types of the agent: its configuration and the state message it answers queries with.

``AgentState`` is registered with the bus codec like every other wire message; it travels
only as a reply on the agent's ``state/<r>`` queryable (never published), so subscribers of
the documented keys never see it. Import agent.types to decode it (monitors, tests).
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from bus.messages import message
from planner.types import BoolArray

DEFAULT_START_TIMEOUT = 30.0
DEFAULT_ANNOUNCE_PERIOD = 0.5
DEFAULT_HW_TIMEOUT = 60.0
DEFAULT_LINGER = 1.0


@dataclass(frozen=True)
class AgentConfig:
    """Everything an agent process is told on its command line (connection aside)."""

    robot: int
    k: int
    algo: str
    world: str
    cell_size: int | None = None
    tree: str = "dfs"
    seed: int = 0
    incarnation: int = 1
    start_timeout: float = DEFAULT_START_TIMEOUT
    heartbeat_period: float = 0.2
    dead_after: float = 3.0
    announce_period: float = DEFAULT_ANNOUNCE_PERIOD
    hw_timeout: float = DEFAULT_HW_TIMEOUT
    linger: float = DEFAULT_LINGER


@message
@dataclass(frozen=True)
class AgentState:
    """An agent's re-learnable knowledge: its phase, its moves, every cycle index it knows
    covered (``pack_covered``: bits in cycle-index order), the robots it knows dead, the
    robots it took over and its drop counters ("kind.reason" -> count)."""

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


def pack_covered(covered: BoolArray) -> bytes:
    """Bits, then zlib: coverage is long runs, so even a 10^6-sub-cell map fits a message."""
    return zlib.compress(np.packbits(covered.astype(bool)).tobytes())


def unpack_covered(data: bytes, n: int) -> BoolArray:
    """The bool array of ``n`` packed by pack_covered; ValueError if ``data`` is not one."""
    try:
        raw = np.frombuffer(zlib.decompress(data), dtype=np.uint8)
    except zlib.error as error:
        raise ValueError(f"coverage bits do not decompress: {error}") from error
    if raw.size * 8 < n:
        raise ValueError(f"{raw.size} bytes cannot hold {n} bits")
    return np.unpackbits(raw, count=n).astype(bool)
