"""Zenoh's receive threads never run our code: each declaration's samples (or queries) are
queued by Zenoh for a thread of the declaration's own, which hands them to the loop's inbox.

Why: a Python callback run by Zenoh itself (``indirect=False``) runs on the thread that reads
the link and needs the GIL for every sample. In a process whose loop is busy, on a host whose
cores are all taken (a time-scale-0 fleet: every agent moves as fast as simhw answers), each
of those hand-overs waits for the scheduler, and a batch of samples kept the thread off its
link past the router's 1 s lease: the link expired, the session dropped and came back, and
the peers found the robot's token gone and declared it dead (docs/operations.md, "Flat
out"). The same wait in simhw's command queryables held the router's queue towards simhw.

This is zenoh-python's own ``Callback(..., indirect=True)``: a channel of 256 items per
declaration and a Python thread that waits on it without the GIL and without waking while
idle. A channel of our own drained by our own thread was tried first: zenoh-python's blocking
receive wakes every 0.1 s to check for signals, and a 100-agent fleet's 1 200 such threads
stalled before its first move (one run of benchmarks/bench_fleet.py big --robots 100,
load average 543). Past 256 items waiting, Zenoh's thread waits again: a declaration's
thread that far behind is starved, not slow. Measured side by side
(benchmarks/bench_handoff.py): a burst into one subscription is received 2.3 x as fast and
at 0.46 x the CPU per message as when Zenoh's thread ran the hand-over.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any, TypeVar

import zenoh

_log = logging.getLogger("mstc.bus")

D = TypeVar("D")


def handed_off(declare: Callable[[zenoh.handlers.Callback[Any]], D],
               on_item: Callable[[Any], None], name: str) -> D:
    """``declare(handler)`` (a subscriber, advanced subscriber or queryable): Zenoh's
    receive thread queues each item for a thread of the declaration's own, which passes it
    to ``on_item``.

    That thread ends when the declaration is undeclared (or its session closed), and it is
    not a daemon: the interpreter waits for it at exit. Undeclare before exiting (a Bus
    does, on leaving its ``async with``), or the process waits forever. As a daemon (tried)
    it was worse: a thread still waking from its undeclaration while the interpreter
    finalized was killed inside pyo3, which aborts the process ("FATAL: exception not
    rethrown": an agent that had completed its mission exited on SIGABRT in CI)."""
    return declare(zenoh.handlers.Callback(lambda item: _deliver(on_item, item, name),
                                           indirect=True))


def _deliver(on_item: Callable[[Any], None], item: Any, name: str) -> None:
    try:
        on_item(item)
    except Exception:  # noqa: BLE001 - one bad sample must not end the declaration's delivery
        _log.exception("receiving on %s failed", name)
