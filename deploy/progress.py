"""Progress display of ``mstc up``: a rich live panel on a terminal, plain lines otherwise.

Plain mode (stdout not a TTY, or --plain) prints one line per event and a status line every
``period`` seconds, so logs and CI output stay readable and grep-able.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import Protocol, TextIO

from rich.console import Console, Group
from rich.live import Live
from rich.progress_bar import ProgressBar
from rich.table import Table
from rich.text import Text

from deploy.summary import MissionTracker


class ProgressView(Protocol):
    def event(self, text: str) -> None: ...

    def update(self, tracker: MissionTracker, elapsed: float) -> None: ...

    def close(self) -> None: ...


QUIET_S = 5.0  # the longest a view stays silent: a takeover walk covers nothing new for long


def status_line(tracker: MissionTracker, elapsed: float) -> str:
    return (f"[{elapsed:6.1f}s] coverage {tracker.coverage:5.1f} % "
            f"({tracker.covered}/{tracker.total}), robots alive {tracker.alive}/"
            f"{tracker.robots}, done {tracker.done}, takeovers {len(tracker.takeovers)}, "
            f"moves {sum(v.moves for v in tracker.views)}")


class Quiet:
    """Says when nothing has been printed for ``QUIET_S``: a status line is then due even
    though nothing changed, so that a long walk over covered ground is not silence."""

    def __init__(self, clock: Callable[[], float] = time.monotonic,
                 quiet: float = QUIET_S) -> None:
        self.clock = clock
        self.quiet = quiet
        self.last = clock()

    def printed(self) -> None:
        self.last = self.clock()

    def due(self) -> bool:
        return self.clock() - self.last >= self.quiet


class PlainProgress:
    def __init__(self, out: TextIO | None = None, period: float = 2.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.out = out or sys.stdout
        self.period = period
        self.clock = clock
        self.quiet = Quiet(clock)
        self._next = 0.0
        self._last = ""

    def event(self, text: str) -> None:
        print(text, file=self.out, flush=True)
        self.quiet.printed()

    def update(self, tracker: MissionTracker, elapsed: float) -> None:
        now = self.clock()
        line = status_line(tracker, elapsed)
        if now >= self._next and (line[9:] != self._last[9:] or self.quiet.due()):
            self._next = now + self.period
            self._last = line
            self.event(line)

    def close(self) -> None:
        return None


class RichProgress:
    """A live panel: coverage bar and one row per robot; events scroll above it."""

    def __init__(self, console: Console | None = None) -> None:
        self.console = console or Console()
        self._live = Live(Text("starting..."), console=self.console, refresh_per_second=4,
                          transient=True)
        self._live.start()

        self.quiet = Quiet()

    def event(self, text: str) -> None:
        self.console.print(text, markup=False, highlight=False)
        self.quiet.printed()

    def update(self, tracker: MissionTracker, elapsed: float) -> None:
        self._live.update(render(tracker, elapsed))
        if self.quiet.due():  # the panel alone leaves no trace in the scroll-back
            self.event(status_line(tracker, elapsed))

    def close(self) -> None:
        self._live.stop()


def render(tracker: MissionTracker, elapsed: float) -> Group:
    head = Text(status_line(tracker, elapsed))
    # the bar in a row of its own: alone it ends no line and the table's header followed it
    bar = Table.grid(padding=(0, 1))
    bar.add_row(ProgressBar(total=max(tracker.total, 1), completed=tracker.covered, width=40),
                Text(f"{tracker.coverage:5.1f} %"))
    table = Table(box=None, pad_edge=False)
    for column in ("robot", "state", "moves", "note"):
        table.add_column(column)
    for view in tracker.views:
        note = view.lost or ("mission complete" if view.completed else
                             "section complete" if view.finished else "")
        style = "red" if view.lost else ("green" if view.finished else "")
        table.add_row(str(view.robot), tracker.shown_state(view), str(view.moves), note,
                      style=style)
    return Group(head, bar, table)


def make_progress(plain: bool) -> ProgressView:
    """Plain lines if asked or if stdout is not a terminal; else the rich panel."""
    if plain or not sys.stdout.isatty():
        return PlainProgress()
    return RichProgress()
