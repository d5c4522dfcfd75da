"""One computation in a process of its own, for the one robot of a crowded fleet that
computes for everyone (the first plan, agent.offline.planshare; a re-plan,
agent.offline.replan).

In a thread of its agent such a computation waits for the interpreter lock while the agent
answers its peers' messages and queries: a re-plan of 0.9 s of CPU took 177 s with 59
survivors on 2 cores. So it runs in a spawned process (the agent's Zenoh threads are not
forked) that leads a session of its own (``_lead_own_session``).
"""

from __future__ import annotations

import asyncio
import multiprocessing
import os
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from typing import Any, TypeVar

T = TypeVar("T")

# Who computes a plan or re-plan of a crowded fleet, and where. A fleet of ``share_from``
# participants (or survivors) has one compute it for all; on a large map one computation
# weighs as much as several: a participant counts once per SHARE_SUB_CELLS sub-cells (at
# least once), from SHARE_MIN of them (on 2 cores two computations cost the wall time of
# one, and a share adds a process start and a message). A re-plan costs 0.18 ms of CPU
# per sub-cell (7.2 s on 40 392), a balanced first plan 0.9-50 s there at k = 12-25.
SHARE_SUB_CELLS = 4_000
SHARE_MIN = 3
# A computation over at least this many sub-cells runs in a process of its own even where
# each robot computes it for itself: in a thread it holds the interpreter lock for seconds,
# and the agent's Zenoh threads, which need it to hand over every sample, fall behind
# (peers saw the robot's heartbeats stop or its liveliness token lapse). Below, the process
# start (0.5-1 s of CPU for the planner's imports) costs more than it spares.
APART_FROM_SUB_CELLS = 8_000


def shared_by_one(computers: int, sub_cells: int, share_from: int) -> bool:
    """Whether one of ``computers`` robots computes for all a plan or re-plan over
    ``sub_cells`` (from ``share_from`` of them, each weighing once per SHARE_SUB_CELLS)."""
    if computers >= share_from:
        return True
    weight = max(1.0, sub_cells / SHARE_SUB_CELLS)
    return computers >= SHARE_MIN and computers * weight >= share_from


def apart_from(sub_cells: int) -> bool:
    """Whether a computation over ``sub_cells`` runs in a process of its own."""
    return sub_cells >= APART_FROM_SUB_CELLS

# In a worker: why it could not lead a session of its own ("" when it does).
_session_note = ""


def _lead_own_session() -> None:
    """The worker's initializer, before it imports the planner: leave the agent's session.

    Linux shares the CPU between autogroups (one per session) before niceness counts, and a
    crowded fleet's agents are niced in theirs (deploy.autogroup): a worker in its agent's
    session got that agent's hundredth of the CPU, 1 s of CPU in 36 s of a 100-robot fleet's
    wait for it. A new session's autogroup starts at niceness 0, the router's weight: the
    fleet's one computation everyone waits for, about a second of CPU each time."""
    global _session_note
    try:
        os.setsid()
    except OSError as error:  # a session leader already; the result is the same either way
        _session_note = f" (in its agent's session: {error})"


def _in_own_session(work: Callable[..., T], *args: Any) -> tuple[T, str]:
    """``work(*args)`` in the worker, and why it is not in a session of its own ("")."""
    return work(*args), _session_note


async def computed_apart(work: Callable[..., T], *args: Any) -> tuple[T, str]:
    """``work(*args)`` (picklable, as its arguments and result) in a process of its own, in
    a session of its own (the note says why not: "" when it is). OSError or
    concurrent.futures.process.BrokenProcessPool when no process can be had."""
    pool = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"),
                               initializer=_lead_own_session)
    try:
        return await asyncio.get_running_loop().run_in_executor(pool, _in_own_session, work,
                                                                *args)
    finally:
        # the worker exits once it is done; the agent does not wait for it here
        pool.shutdown(wait=False, cancel_futures=True)
