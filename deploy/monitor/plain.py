"""``--plain``: one line per event, for logs, CI and pipes (grep-able, no escape codes)."""

from __future__ import annotations

import sys
from collections.abc import Iterable
from typing import TextIO

from deploy.monitor.figures import mission_figures
from deploy.monitor.model import FleetModel
from deploy.monitor.types import MonitorEvent
from deploy.monitor.verdict import verdict_word


def format_event(event: MonitorEvent) -> str:
    """``<t> <kind> <text>``: t in seconds since the monitor (or recording) started."""
    return f"{event.t:9.3f} {event.kind:<16} {event.text}"


def status_line(model: FleetModel, drops: int = 0) -> str:
    """The model's figures on one line (printed at the end of a plain run)."""
    coverage = model.coverage()
    total = model.total()
    covered = model.covered_count()
    cov = f"{coverage:.1f} % ({covered}/{total})" if coverage is not None else \
        f"{covered} sub-cells (map unknown)"
    known, alive, dead, done = model.counts()
    numbers = mission_figures(model)
    mission = verdict_word(model)
    tree = model.tree.line()
    if tree:
        return f"{tree}, robots {known} alive {alive} dead {dead}, mission {mission}"
    return (f"coverage {cov}, makespan {numbers.makespan_moves} moves "
            f"{numbers.sim_seconds:.1f} simulated s, total {numbers.total_moves} moves, "
            f"sim {model.sim_time:.1f} s, robots {known} alive {alive} dead {dead} "
            f"done {done}, revisits {numbers.revisits}, drops {drops}, mission {mission}")


class PlainPrinter:
    """Prints events as they come; never colours, flushes every line."""

    def __init__(self, out: TextIO | None = None) -> None:
        self.out = out or sys.stdout
        self.lines = 0

    def events(self, events: Iterable[MonitorEvent]) -> None:
        for event in events:
            print(format_event(event), file=self.out, flush=True)
            self.lines += 1

    def final(self, model: FleetModel, drops: int = 0) -> None:
        print(f"{model.t:9.3f} {'summary':<16} {status_line(model, drops)}", file=self.out,
              flush=True)
