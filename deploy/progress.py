"""Progress display of ``mstc up``: a rich live panel on a terminal, plain lines otherwise.

Plain mode (stdout not a TTY, or --plain) prints one line per event and a status line every
``period`` seconds, so logs and CI output stay readable and grep-able.
"""

from __future__ import annotations

import sys
import time
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


def status_line(tracker: MissionTracker, elapsed: float) -> str:
    done = sum(v.completed for v in tracker.views)
    return (f"[{elapsed:6.1f}s] coverage {tracker.coverage:5.1f} % "
            f"({tracker.covered}/{tracker.total}), robots alive {tracker.alive}/"
            f"{tracker.robots}, done {done}, takeovers {len(tracker.takeovers)}")


class PlainProgress:
    def __init__(self, out: TextIO | None = None, period: float = 2.0) -> None:
        self.out = out or sys.stdout
        self.period = period
        self._next = 0.0
        self._last = ""

    def event(self, text: str) -> None:
        print(text, file=self.out, flush=True)

    def update(self, tracker: MissionTracker, elapsed: float) -> None:
        now = time.monotonic()
        line = status_line(tracker, elapsed)
        if now >= self._next and line[9:] != self._last[9:]:
            self._next = now + self.period
            self._last = line
            print(line, file=self.out, flush=True)

    def close(self) -> None:
        return None


class RichProgress:
    """A live panel: coverage bar and one row per robot; events scroll above it."""

    def __init__(self, console: Console | None = None) -> None:
        self.console = console or Console()
        self._live = Live(Text("starting..."), console=self.console, refresh_per_second=4,
                          transient=True)
        self._live.start()

    def event(self, text: str) -> None:
        self.console.print(text, markup=False, highlight=False)

    def update(self, tracker: MissionTracker, elapsed: float) -> None:
        self._live.update(render(tracker, elapsed))

    def close(self) -> None:
        self._live.stop()


def render(tracker: MissionTracker, elapsed: float) -> Group:
    bar = ProgressBar(total=max(tracker.total, 1), completed=tracker.covered, width=40)
    head = Text(status_line(tracker, elapsed))
    table = Table(box=None, pad_edge=False)
    for column in ("robot", "state", "moves", "note"):
        table.add_column(column)
    for view in tracker.views:
        note = view.lost or ("section complete" if view.completed else "")
        style = "red" if view.lost else ("green" if view.completed else "")
        table.add_row(str(view.robot), view.state, str(view.moves), note, style=style)
    return Group(head, bar, table)


def make_progress(plain: bool) -> ProgressView:
    """Plain lines if asked or if stdout is not a terminal; else the rich panel."""
    if plain or not sys.stdout.isatty():
        return PlainProgress()
    return RichProgress()
