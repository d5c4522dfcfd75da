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
