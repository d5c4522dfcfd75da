"""The live terminal view: map, side panel and event log, rendered with rich from the model.

The map is drawn per coarse cell, with the spanning-tree edges between cells: a cell is
``·`` uncovered, ``▒`` partly and ``█`` fully covered in the colour of the robot that covered
it first (white when the monitor joined late and cannot tell), ``?`` claimed (magenta when
two robots claim it), ``#`` blocked; robots are arrows in their colour (``✖`` dead, ``○``
left). A map too big for the terminal is drawn
every s-th cell without edges.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from rich.console import Group, RenderableType
from rich.panel import Panel
from rich.table import Table
from rich.text import Text

from deploy.monitor.figures import mission_figures, robot_hex
from deploy.monitor.layout import PANEL_ROWS, SIDE_WIDTH, EventLog, layout
from deploy.monitor.model import FleetModel, RobotView
from deploy.monitor.plain import format_event
from deploy.monitor.redundancy import look_revisits
from deploy.monitor.types import MonitorEvent
from deploy.monitor.verdict import verdict_word

ARROWS = "▲▶▼◀"
_EVENT_STYLE = {"died": "bold red", "detected_dead": "red", "takeover": "yellow",
                "conflict_lost": "magenta", "mission_complete": "bold green",
                "mission_failed": "bold red", "completed": "green", "withdrawn": "yellow",
                "fenced": "red"}


LEGEND = Text.assemble(
    ("█", "bold"), "covered ", ("▒", "bold"), "partly ", ("·", "grey50"), "uncovered ",
    ("?", "bold magenta"), "claimed ", ("#", "grey37"), "blocked ", ("▲", "bold"),
    "robot ", ("✖", "bold red"), "dead ", "○left ", ("─", "dim"), "tree edge", style="dim")


def colour(robot: int) -> str:
    return robot_hex(robot)


@dataclass(frozen=True)
class FeedStats:
    """How the feed is doing (not part of the model: it is about this process)."""

    source: str = "live"
    rate: float = 0.0  # messages per second, recent
    drops: dict[str, int] = field(default_factory=dict)  # "kind.reason" -> count
    queue: int = 0
    max_queue: int = 0

    @property
    def dropped(self) -> int:
        return sum(self.drops.values())


def render(model: FleetModel, stats: FeedStats, *, width: int = 120, height: int = 40,
           log: EventLog | None = None) -> RenderableType:
    """The whole screen for a console of ``width`` x ``height`` characters, laid out by its
    size (deploy.monitor.layout); ``log``: the events kept for the screen (default: the
    model's recent events)."""
    log = log if log is not None else EventLog(model.events)
    rows = figure_rows(model, stats)
    side_rows = len(rows) + len(model.robots) + 1 + 2 * PANEL_ROWS
    shape = _shape(model)
    # the map drawn with its edges: 2 c - 1 characters for c cells
    drawn = None if shape is None else \
        ((shape[0] + 1) // 2 * 2 - 1, (shape[1] + 1) // 2 * 2 - 1)
    figure_lines, robot_lines = math.ceil(len(rows) / 2), len(model.robots) + 1
    legend = len(LEGEND.plain)
    lay = layout(width, height, side_rows, figure_lines, drawn, robot_lines, legend)
    drawing = render_map(model, lay.map_width, lay.map_rows)
    # a map drawn every s-th cell may take fewer rows than it was given: the log gets them
    lay = layout(width, height, side_rows, figure_lines,
                 (len(drawing.plain.splitlines()), lay.map_width), robot_lines, legend)
    map_panel = Panel(Group(drawing, LEGEND), title=_title(model))
    events = Panel(event_log(*log.lines(lay.log_lines)), title="events")
    if not lay.beside:
        robots = [Panel(robot_table(model), title="robots")] if lay.robots_below else []
        return Group(map_panel, Panel(_two_up(rows), title="fleet"), *robots, events)
    grid = Table.grid(padding=(0, 1))
    grid.add_column()
    grid.add_column(width=SIDE_WIDTH)
    grid.add_row(map_panel, Group(Panel(_one_up(rows), title="fleet"),
                                  Panel(robot_table(model), title="robots")))
    return Group(grid, events)


def _title(model: FleetModel) -> str:
    return f"map {model.cover.map_name}" if model.cover.map_name else "map (waiting for the world)"


def render_map(model: FleetModel, max_w: int, max_h: int) -> Text:
    """The map as text no wider than ``max_w`` and no taller than ``max_h``."""
    shape = _shape(model)
    if shape is None:
        return Text("waiting for the world state or coverage...", style="dim")
    ch, cw = (shape[0] + 1) // 2, (shape[1] + 1) // 2
    robots = _robots_by_cell(model)
    if 2 * ch - 1 <= max_h and 2 * cw - 1 <= max_w:
        return _with_edges(model, ch, cw, robots)
    # rows and columns stepped apart, so that a wide terminal shows more of a map's width
    row_step, col_step = max(1, math.ceil(ch / max_h)), max(1, math.ceil(cw / max_w))
    # a terminal's characters are twice as tall as wide: draw a cell two wide if there is room
    wide = 2 if 2 * math.ceil(cw / col_step) <= max_w else 1
    runs = _Runs()
    for i in range(0, ch, row_step):
        for j in range(0, cw, col_step):
            glyph, style = _cell_glyph(model, (i, j), robots)
            runs.add(glyph * wide if glyph not in ARROWS else glyph + " " * (wide - 1), style)
        runs.add("\n", "")
    return _trimmed(runs.text())


def _trimmed(text: Text) -> Text:
    text.rstrip()  # no empty row below the map
    return text


class _Runs:
    """Text built from runs of one style: rich renders a Text in time growing with its
    spans, and a map is mostly long runs of one glyph style."""

    def __init__(self) -> None:
        self._parts: list[tuple[str, str]] = []
        self._chars: list[str] = []
        self._style = ""

    def add(self, chars: str, style: str) -> None:
        if style != self._style and self._chars:
            self._parts.append(("".join(self._chars), self._style))
            self._chars = []
        self._style = style
        self._chars.append(chars)

    def text(self) -> Text:
        if self._chars:
            self._parts.append(("".join(self._chars), self._style))
            self._chars = []
        return Text.assemble(*self._parts)


def _with_edges(model: FleetModel, ch: int, cw: int,
                robots: dict[tuple[int, int], RobotView]) -> Text:
    runs = _Runs()
    planned = model.planned_tree() or frozenset()
    for i in range(ch):
        for j in range(cw):
            runs.add(*_cell_glyph(model, (i, j), robots))
            if j + 1 < cw:
                runs.add(*_edge_glyph(model, ((i, j), (i, j + 1)), "─", planned))
        runs.add("\n", "")
        if i + 1 < ch:
            for j in range(cw):
                runs.add(*_edge_glyph(model, ((i, j), (i + 1, j)), "│", planned))
                if j + 1 < cw:
                    runs.add(" ", "")
            runs.add("\n", "")
    return _trimmed(runs.text())


def _edge_glyph(model: FleetModel, edge: tuple[tuple[int, int], tuple[int, int]],
                glyph: str, planned: frozenset[tuple[tuple[int, int], tuple[int, int]]]
                ) -> tuple[str, str]:
    """A walked (or ORMSTC-built) edge in its robot's colour; a planned one not walked yet
    dim (offline plans, once the monitor could rebuild the tree)."""
    owner = model.edges.get(edge)
    if owner is not None:
        return glyph, colour(owner)
    return (glyph, "dim") if edge in planned else (" ", "")


def _shape(model: FleetModel) -> tuple[int, int] | None:
    if model.cover.free is not None:
        return (int(model.cover.free.shape[0]), int(model.cover.free.shape[1]))
    cells = list(model.covered_cells()) + [(v.pose[0], v.pose[1])
                                           for v in model.robots.values() if v.pose]
    cells += [(2 * r + 1, 2 * c + 1) for r, c in [*model.claims.open, *model.claims.owner]]
    if not cells:
        return None
    return (max(r for r, _ in cells) + 1, max(c for _, c in cells) + 1)


def _robots_by_cell(model: FleetModel) -> dict[tuple[int, int], RobotView]:
    out: dict[tuple[int, int], RobotView] = {}
    for view in sorted(model.robots.values(), key=lambda v: v.dead):
        if view.pose is not None:
            out.setdefault((view.pose[0] // 2, view.pose[1] // 2), view)
    return out


def _cell_glyph(model: FleetModel, cell: tuple[int, int],
                robots: dict[tuple[int, int], RobotView]) -> tuple[str, str]:
    view = robots.get(cell)
    if view is not None and view.pose is not None:
        if view.dead:
            return "✖", "bold red"
        if view.left:
            return "○", colour(view.robot)
        return ARROWS[view.pose[2] % 4], f"bold black on {colour(view.robot)}"
    subs = [(2 * cell[0] + dr, 2 * cell[1] + dc) for dr in (0, 1) for dc in (0, 1)]
    free = model.cover.free
    if free is not None and not all(
            r < free.shape[0] and c < free.shape[1] and free[r, c] for r, c in subs):
        return "#", "grey37"
    covered = model.covered_cells()
    done = [s for s in subs if s in covered]
    if not done:
        claimants = model.claims.open.get(cell)
        if claimants:  # claimed, not entered yet; two claimants are a conflict
            return "?", "bold magenta" if len(claimants) > 1 else colour(min(claimants))
        return "·", "grey50"
    owner = next((model.cover.owner[s] for s in done if s in model.cover.owner), None)
    style = "white" if owner is None else colour(owner)
    return ("█" if len(done) == 4 else "▒"), style


FigureRow = tuple[str, str, str]  # label, value, style


def figure_rows(model: FleetModel, stats: FeedStats) -> list[FigureRow]:
    """The fleet's figures, one (label, value, style) each."""
    rows: list[FigureRow] = []
    coverage, total = model.coverage(), model.total()
    covered = model.covered_count()
    rows.append(("coverage", f"{coverage:.1f} % ({covered}/{total})"
                 if coverage is not None else f"{covered} sub-cells (map unknown)", ""))
    if model.tree.line():
        rows.append(("tree", model.tree.line(), ""))
    numbers = mission_figures(model)
    rows.append(("moves", f"makespan {numbers.makespan_moves}, total {numbers.total_moves}", ""))
    scale = "" if model.time_scale is None else f" (x{model.time_scale:g})"
    covered_in = "" if numbers.coverage_sim_seconds is None else \
        f", covered in {numbers.coverage_sim_seconds:.1f} s"
    rows.append(("sim time", f"{model.sim_time:.1f} s{scale}{covered_in}", ""))
    known, alive, dead, done = model.counts()
    rows.append(("robots", f"{known}: {alive} alive, {dead} dead, {done} done", ""))
    rows.append(("redundancy", redundancy_line(model, numbers.revisits), ""))
    rows.append(("claims", f"{model.claims.claims}, {len(model.claims.conflicts)} "
                           f"conflicts settled, {len(model.claims.unsettled())} open", ""))
    rows.append(("messages", f"{model.kinds.total()} ({stats.rate:.0f}/s)", ""))
    drops = ", ".join(f"{k} {n}" for k, n in sorted(stats.drops.items())) or "0"
    invalid = sum(model.invalid.values())
    rows.append(("drops", drops + (f", invalid {invalid}" if invalid else ""),
                 "red" if stats.dropped or invalid else ""))
    rows.append(("queue", f"{stats.queue} (max {stats.max_queue})", ""))
    mission = verdict_word(model)
    rows.append(("mission", mission, {"complete": "green", "failed": "bold red"}.get(mission, "")))
    rows.append(("source", stats.source, ""))
    return rows


def _one_up(rows: list[FigureRow]) -> Table:
    table = Table.grid(padding=(0, 1))
    table.add_column(style="bold", no_wrap=True)
    table.add_column(no_wrap=True, overflow="ellipsis")  # one row each: the layout counts them
    for label, value, style in rows:
        table.add_row(label, value, style=style)
    return table


def _two_up(rows: list[FigureRow]) -> Table:
    """Two figures to a row: the narrow layout's figures below the map."""
    table = Table.grid(padding=(0, 1), expand=True)
    widest = max((len(name) for name, _, _ in rows), default=1)
    for _ in range(2):  # labels whole; long values are cut, not the labels
        table.add_column(style="bold", no_wrap=True, min_width=widest)
        table.add_column(no_wrap=True, overflow="ellipsis", ratio=1)
    for i in range(0, len(rows), 2):
        pair = rows[i:i + 2]
        cells: list[Text | str] = []
        for label, value, style in pair:
            cells += [label, Text(value, style=style)]
        table.add_row(*cells)
    return table


def redundancy_line(model: FleetModel, revisits: int) -> str:
    """Revisits, the part of them that were look steps, and every look step (a look into a
    sub-cell not entered before is no revisit)."""
    looks = sum(v.look_steps for v in model.robots.values())
    if not looks:
        return f"{revisits} revisits"
    return f"{revisits} revisits: {look_revisits(model.cover)} by look steps (of {looks})"


def robot_table(model: FleetModel) -> Table:
    table = Table(box=None, pad_edge=False, show_edge=False)
    for name in ("id", "state", "moves", "pose", "note"):
        table.add_column(name)
    for view in sorted(model.robots.values(), key=lambda v: v.robot):
        pose = "-" if view.pose is None else f"{view.pose[0]},{view.pose[1]}"
        table.add_row(Text(str(view.robot), style=colour(view.robot)), view.state,
                      str(view.moves), pose, _note(view),
                      style="red" if view.dead else "")
    return table


def _note(view: RobotView) -> str:
    if view.death is not None:
        by = view.death.detected_by
        return f"dead ({view.death.reason}, by {'observer' if by is None else by})"
    if view.failed:
        return "body failed"
    if view.token_lost is not None:
        return "process gone"
    if view.took_over:
        return "took over " + ",".join(map(str, view.took_over))
    return "done" if view.done else ""


def event_log(pinned: list[MonitorEvent], others: list[MonitorEvent] | None = None) -> Text:
    """The pinned events (deaths, takeovers, re-plans...), a dim rule, then the latest of the
    rest; one row each (a long line is cut, not wrapped, so the layout's rows hold)."""
    text = Text(no_wrap=True, overflow="ellipsis")
    lines: list[tuple[MonitorEvent | None, str]] = [(e, _EVENT_STYLE.get(e.kind, ""))
                                                    for e in pinned]
    if pinned and others:
        lines.append((None, "dim"))
    lines += [(e, _EVENT_STYLE.get(e.kind, "")) for e in others or ()]
    for i, (event, style) in enumerate(lines):
        line = "─" * 20 + " latest " + "─" * 20 if event is None else format_event(event)
        text.append(("\n" if i else "") + line, style)
    return text
