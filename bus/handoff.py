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
thread that far behind is starved, not slow. Measured side by
side (benchmarks/bench_handoff.py): a burst into one subscription is received 2.3 x as fast
and at 0.46 x the CPU per message as when Zenoh's thread ran the hand-over.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import Any, TypeVar

import zenoh

_log = logging.getLogger("mstc.bus")

D = TypeVar("D")


def handed_off(declare: Callable[[zenoh.handlers.Callback[Any]], D],
               on_item: Callable[[Any], None], name: str) -> D:
    """``declare(handler)`` (a subscriber, advanced subscriber or queryable): Zenoh's
    receive thread queues each item for a thread of the declaration's own, which passes it
    to ``on_item``. That thread is a daemon: a process that exits without undeclaring does
    not wait for it (see _declared_from_a_daemon)."""
    handler: zenoh.handlers.Callback[Any] = zenoh.handlers.Callback(
        lambda item: _deliver(on_item, item, name), indirect=True)
    return _declared_from_a_daemon(lambda: declare(handler), name)


def _declared_from_a_daemon(declare: Callable[[], D], name: str) -> D:
    """Runs ``declare`` on a short-lived daemon thread and returns what it declared.
    zenoh-python starts an ``indirect`` callback's thread from the declaring thread, which
    it inherits daemon-ness from: declared from the loop's (main) thread, it was a
    non-daemon thread, and a process that ended without undeclaring waited for it forever
    at exit. (Such a process now ends with pyo3's abort when the thread wakes during
    finalization; a Bus undeclares everything before that.)"""
    declared: list[D] = []
    failed: list[BaseException] = []

    def run() -> None:
        try:
            declared.append(declare())
        except BaseException as error:  # noqa: BLE001 - re-raised on the caller's thread
            failed.append(error)

    thread = threading.Thread(target=run, name=f"declare {name}", daemon=True)
    thread.start()
    thread.join()
    if failed:
        raise failed[0]
    return declared[0]


def _deliver(on_item: Callable[[Any], None], item: Any, name: str) -> None:
    try:
        on_item(item)
    except Exception:  # noqa: BLE001 - one bad sample must not end the declaration's delivery
        _log.exception("receiving on %s failed", name)
