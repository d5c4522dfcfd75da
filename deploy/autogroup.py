"""A niced fleet process hands its niceness to its scheduler autogroup as well.

Linux (with ``kernel.sched_autogroup_enabled``, the default of most distributions) shares
the CPU fairly between *autogroups*, one per session, before niceness counts, and niceness
only weighs processes of the same autogroup against each other. ``mstc up`` starts every
child in a session of its own (deploy.fleet.Child), so an agent started with ``nice -n 10``
still weighed as much as the router: 60 agents on 2 cores left the router ~10 % of a core,
its receive queues held 100-500 kB per agent link and simhw's replies came after the agents'
5 s attempt timeout (docs/operations.md, "Fleet scale"). An agent that leads its own session
is alone in its autogroup, so giving the autogroup its niceness gives the router and simhw
(niceness 0) their share back. Unprivileged processes may lower an autogroup's priority, at
most one write every 100 ms on the whole host (EAGAIN): the write is retried a while.
"""

from __future__ import annotations

import errno
import logging
import os
import time
from pathlib import Path

AUTOGROUP = Path("/proc/self/autogroup")
RETRY_S = 0.05
PATIENCE_S = 3.0

_log = logging.getLogger("mstc.deploy")


def niceness() -> int:
    return os.getpriority(os.PRIO_PROCESS, 0)


def leads_own_session() -> bool:
    return os.getsid(0) == os.getpid()


def autogroup_nice(path: Path = AUTOGROUP) -> int | None:
    """The autogroup's niceness ("/autogroup-41 nice 19"), None where there is none."""
    try:
        return int(path.read_text().split()[-1])
    except (OSError, ValueError, IndexError):
        return None


def share_niceness(path: Path = AUTOGROUP, *, patience: float = PATIENCE_S) -> bool:
    """Give this process's autogroup its niceness when the process is niced and leads its
    own session (a user's shell session is never touched). True when the autogroup has it
    now; False where there is nothing to do or the kernel refused (logged, not raised)."""
    nice = niceness()
    if nice <= 0 or not leads_own_session():
        return False
    current = autogroup_nice(path)
    if current is None:
        return False  # no autogroups here (another OS, or a kernel without them)
    if current >= nice:
        return True
    deadline = time.monotonic() + patience
    while True:
        try:
            path.write_text(str(nice))
            return True
        except OSError as error:
            if error.errno != errno.EAGAIN or time.monotonic() >= deadline:
                _log.warning("could not give the autogroup niceness %d: %s", nice, error)
                return False
        time.sleep(RETRY_S)  # another process wrote within the kernel's 100 ms
