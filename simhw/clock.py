"""The simulated clock: sim seconds run at ``time_scale`` x wall seconds, or as fast as possible.

Motions are timed through ``run(lane, duration)``; a lane is one body, so bodies move
concurrently. The scaled clock sleeps ``duration / time_scale`` wall seconds. The fast clock
(time_scale 0 or inf) never sleeps: each lane keeps its own virtual time, the sum of its own
motion durations, so k bodies moving at once do not add up their durations; ``now()`` is the
latest lane time. Tests inject the fast clock and never sleep.
"""

from __future__ import annotations

import asyncio
import math
import time
from collections.abc import Callable
from typing import Protocol


class SimClock(Protocol):
    def now(self) -> float:
        """Current sim time in seconds."""
        ...

    def lane_now(self, lane: int) -> float:
        """Current sim time as seen by ``lane`` (where its next motion starts)."""
        ...

    async def run(self, lane: int, duration: float) -> tuple[float, float]:
        """Let ``duration`` sim seconds pass for ``lane``; return (start, end) sim times."""
        ...


class ScaledClock:
    """Sim time = ``time_scale`` x wall time since the clock was made."""

    def __init__(self, time_scale: float,
                 wall: Callable[[], float] = time.monotonic) -> None:
        if not (math.isfinite(time_scale) and time_scale > 0):
            raise ValueError(f"time_scale must be a positive finite number, got {time_scale}")
        self.time_scale = time_scale
        self._wall = wall
        self._t0 = wall()

    def now(self) -> float:
        return (self._wall() - self._t0) * self.time_scale

    def lane_now(self, lane: int) -> float:
        return self.now()

    async def run(self, lane: int, duration: float) -> tuple[float, float]:
        start = self.now()
        await asyncio.sleep(max(duration, 0.0) / self.time_scale)
        return start, start + max(duration, 0.0)


class FastClock:
    """Virtual time per lane; no waiting at all (yields to the loop once per motion)."""

    def __init__(self) -> None:
        self._lanes: dict[int, float] = {}

    def now(self) -> float:
        return max(self._lanes.values(), default=0.0)

    def lane_now(self, lane: int) -> float:
        return self._lanes.get(lane, 0.0)

    async def run(self, lane: int, duration: float) -> tuple[float, float]:
        start = self._lanes.get(lane, 0.0)
        end = start + max(duration, 0.0)
        self._lanes[lane] = end
        await asyncio.sleep(0)
        return start, end


def make_clock(time_scale: float) -> ScaledClock | FastClock:
    """``0`` or ``inf`` -> FastClock, otherwise a ScaledClock (negative or NaN is an error)."""
    if time_scale == 0 or (math.isinf(time_scale) and time_scale > 0):
        return FastClock()
    return ScaledClock(time_scale)
