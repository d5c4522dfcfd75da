"""What a mission achieved: a tracker fed by bus messages and process exits, and its summary.

Ground truth comes from simhw (CoverEvents live, the WorldState query as the authority: a
publication can be dropped, a query answer cannot be partly lost); the agents' statuses,
events and death notices say who finished, who died and who took over. Nothing here does
I/O or reads a clock: times are passed in, so the tracker is tested with plain values.

The tracker decides when the launcher stops (coverage of the map it loaded, robots lost);
the figures of the summary (makespan, simulated seconds, revisits) are read off the
monitor's FleetModel, fed with every message the launcher hears, by
deploy.monitor.figures: the same function ``mstc report`` and ``mstc monitor`` use.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from bus.messages import (
    CoverEvent,
    DeathNotice,
    RobotEvent,
    RobotStatus,
    WorldState,
    world_free,
    world_visits,
)
from deploy.monitor.figures import mission_figures
from deploy.monitor.model import FleetModel
from deploy.monitor.types import Record, Via
from planner.types import BoolArray, SubCell


@dataclass
class SupervisedRobot:
    """What the launcher needs about one robot to decide on the mission: its state, whether
    it is lost (and why) or completed. The robot as the wire shows it in full is
    deploy.monitor.robots.RobotView, in the tracker's model."""

    robot: int
    state: str = "starting"
    moves: int = 0
    lost: str = ""  # why the robot is lost; empty while it is not
    completed: bool = False  # the robot knows the mission complete (or, ORMSTC, its part)
    finished: bool = False  # its own work is done (its section), until it takes over more
    taking_over: bool = False  # it took over a dead robot's section: at work until the end


@dataclass(frozen=True)
class MissionSummary:
    mission: str
    world: str
    algo: str
    robots: int
    reachable: int
    covered: int
    complete: bool
    makespan_moves: int
    total_moves: int
    revisited: int  # visits beyond the first, over all sub-cells (the report's "revisits")
    sim_seconds: float
    wall_seconds: float
    robots_lost: tuple[tuple[int, str], ...]
    takeovers: int
    planned_makespan: int | None
    outcome: str
    # deconflicted walks (--recovery rebalance): waits, detours, bumps summed over the
    # robots that stated them on completion, and how many did; None without any
    traffic: tuple[int, int, int, int] | None = None

    @property
    def coverage(self) -> float:
        return 100.0 * self.covered / self.reachable if self.reachable else 100.0

    def to_json(self) -> dict[str, Any]:
        data = asdict(self)
        data["coverage"] = self.coverage
        data["robots_lost"] = [{"robot": r, "why": why} for r, why in self.robots_lost]
        return data

    def wire(self) -> dict[str, int | float | str]:
        """A flat summary for MissionStatus.summary."""
        return {"coverage": round(self.coverage, 3), "covered": self.covered,
                "reachable": self.reachable, "makespan_moves": self.makespan_moves,
                "sim_seconds": round(self.sim_seconds, 3), "robots_lost": len(self.robots_lost),
                "takeovers": self.takeovers}


@dataclass
class MissionTracker:
    """Coverage and robot states of one mission, updated from messages."""

    reachable: BoolArray
    robots: int
    visits: np.ndarray = field(init=False)
    views: list[SupervisedRobot] = field(init=False)
    last_progress: float = 0.0
    takeovers: set[tuple[int, int | None]] = field(default_factory=set)
    replans: set[tuple[int, str]] = field(default_factory=set)  # (robot, what it said)
    heard: set[int] = field(default_factory=set)  # robots whose status was received
    agreed: set[str] = field(default_factory=set)  # agreement notes already logged
    declared: set[tuple[int, int]] = field(default_factory=set)  # lives declared dead
    # (life, detector) of death notices not taken: their detector was declared dead first
    refused: set[tuple[tuple[int, int], int | None]] = field(default_factory=set)
    log: list[str] = field(default_factory=list)
    # robot -> why its body will fail in simhw (a failure mstc up armed: deploy/kill_orders.py)
    failing: dict[int, str] = field(default_factory=dict)
    model: FleetModel = field(init=False)  # the figures' source, as in mstc monitor / report

    def __post_init__(self) -> None:
        self.visits = np.zeros(self.reachable.shape, dtype=np.int64)
        # Counted, not summed per question: the launcher asks at every cover it hears.
        self._total = int(self.reachable.sum())
        self._covered = 0
        self.views = [SupervisedRobot(r) for r in range(self.robots)]
        self.model = FleetModel(max_events=100)

    def observe(self, t: float, key: str, msg: object, via: Via = "sub") -> None:
        """Hand a received message to the model the summary's figures are read from (``t``:
        seconds since the launcher started)."""
        self.model.apply(Record(t, key, msg, via))

    # --- coverage ------------------------------------------------------------------------

    @property
    def total(self) -> int:
        return self._total

    @property
    def covered(self) -> int:
        return self._covered

    @property
    def coverage(self) -> float:
        return 100.0 * self.covered / self.total if self.total else 100.0

    @property
    def complete(self) -> bool:
        return self.covered == self.total

    def uncovered(self, limit: int = 5) -> list[SubCell]:
        cells = np.argwhere(self.reachable & (self.visits == 0))[:limit]
        return [(int(r), int(c)) for r, c in cells]

    def on_cover(self, event: CoverEvent, now: float) -> bool:
        """Record a cover; True if it covered a new reachable sub-cell."""
        r, c = event.cell
        if not (0 <= r < self.visits.shape[0] and 0 <= c < self.visits.shape[1]):
            return False
        new = self.visits[r, c] == 0 and bool(self.reachable[r, c]) and event.visits > 0
        self.visits[r, c] = max(int(self.visits[r, c]), event.visits)
        if new:
            self._covered += 1
            self.last_progress = now
        return bool(new)

    def on_world(self, state: WorldState, now: float) -> bool:
        """Merge a WorldState answer (the authority); True if coverage grew."""
        if state.shape != self.visits.shape:
            raise ValueError(f"world is {state.shape}, expected {self.visits.shape}")
        if not np.array_equal(world_free(state) | ~self.reachable, np.ones_like(self.reachable)):
            raise ValueError("world's free mask disagrees with the map the launcher loaded")
        before = self.covered
        self.visits = np.maximum(self.visits, world_visits(state).astype(np.int64))
        self._covered = int(((self.visits > 0) & self.reachable).sum())
        for truth in state.robots:
            if 0 <= truth.robot < self.robots:
                view = self.views[truth.robot]
                view.moves = max(0, truth.covered - 1)
                if truth.failed and not view.lost:
                    # only an admin command fails a body: mstc up's armed failure, or an
                    # operator's `mstc kill --hw`
                    self.lose(truth.robot, self.failing.get(
                        truth.robot, "body failed in simhw by an operator (mstc kill --hw)"))
        grew = self.covered > before
        if grew:
            self.last_progress = now
        return grew

    # --- robots --------------------------------------------------------------------------

    def lose(self, robot: int, why: str) -> None:
        view = self.views[robot]
        if not view.lost:
            view.lost = why
            view.state = "lost"
            self.log.append(f"robot {robot} lost: {why}")

    def on_status(self, status: RobotStatus) -> None:
        if not 0 <= status.robot < self.robots:
            return
        self.heard.add(status.robot)
        if not self.views[status.robot].lost:
            self.views[status.robot].state = status.state
        if status.state == "agreed" and status.message and status.message not in self.agreed:
            # the participants' agreement names robots that take no part or died before it
            self.agreed.add(status.message)
            self.log.append(f"robot {status.robot}: {status.message}")

    def on_event(self, event: RobotEvent) -> None:
        if not 0 <= event.robot < self.robots:
            return
        view = self.views[event.robot]
        if event.kind == "completed":
            view.completed = view.finished = True
        elif event.kind == "section_complete":
            # a takeover decided in the same step may be heard first
            view.finished = not view.taking_over
        elif event.kind == "completion_withdrawn":
            view.completed = view.finished = False
        elif event.kind == "takeover_started" and (pair := (event.robot, event.subject)) \
                not in self.takeovers:
            view.finished, view.taking_over = False, True  # at work on the dead's section
            self.takeovers.add(pair)
            self.log.append(f"robot {event.robot} takes over robot {event.subject}'s section")
        elif event.kind == "replanned" and (event.robot, event.detail) not in self.replans:
            self.replans.add((event.robot, event.detail))
            self.log.append(f"robot {event.robot} re-planned: {event.detail}")
        if event.kind in ("fenced", "stopped", "leaving"):
            view.state = event.kind

    def on_death(self, notice: DeathNotice, after: str = "") -> bool:
        """A death notice (after the model has heard it, ``observe``, if at all); True the
        first time this life is declared dead (several robots may declare the same death).
        Every such death gets a log line, also when the robot was known lost before (killed
        by us or by `mstc kill`, its process gone); ``after`` ends that line (how long after
        we failed it)."""
        if not 0 <= notice.robot < self.robots:
            return False
        if notice.reason == "leaving":
            # A robot announcing its own clean exit (after completion or SIGTERM): not lost.
            if not self.views[notice.robot].lost:
                self.views[notice.robot].state = "left"
            return False
        life = (notice.robot, notice.incarnation)
        if life in self.declared:
            return False
        by = "an observer" if notice.detected_by is None else f"robot {notice.detected_by}"
        declared = f"declared dead by {by} ({notice.reason})"
        about = self.model.roster.robots.get(notice.robot)
        if about is not None and self.model.roster.verdict_of_the_dead(notice, about):
            # mstc monitor's and report's rule: a robot declared dead itself declaring a live
            # one dead (waking from a long hang, or the far side of a healed partition),
            # which the agents do not act on either
            if (life, notice.detected_by) not in self.refused:
                self.refused.add((life, notice.detected_by))
                self.log.append(f"robot {notice.robot} {declared}: not taken, robot "
                                f"{notice.detected_by} was declared dead itself")
            return False
        self.declared.add(life)
        if self.views[notice.robot].lost:
            self.log.append(f"robot {notice.robot} {declared}{after}")
        else:
            self.lose(notice.robot, declared + after)
        return True

    def shown_state(self, view: SupervisedRobot) -> str:
        """The state a progress view shows: a robot whose section is covered is not
        "covering" any more, though it says so until the whole mission is."""
        if view.lost:
            return "lost"
        if view.completed:
            return "done"
        if view.finished and view.state in ("covering", "planned", "agreed"):
            return "section done"
        return view.state

    @property
    def done(self) -> int:
        """Robots whose own work is done (their section covered, or the mission known
        complete), counted as they finish rather than at the end."""
        return sum(v.finished and not v.lost for v in self.views)

    @property
    def announced(self) -> int:
        return len(self.heard)

    @property
    def alive(self) -> int:
        return sum(not v.lost for v in self.views)


def summarize(tracker: MissionTracker, *, mission: str, world: str, algo: str,
              wall_seconds: float, planned_makespan: int | None, outcome: str) -> MissionSummary:
    views = tracker.views
    figures = mission_figures(tracker.model)
    return MissionSummary(
        mission=mission, world=world, algo=algo, robots=tracker.robots,
        reachable=tracker.total, covered=tracker.covered, complete=tracker.complete,
        makespan_moves=figures.makespan_moves, total_moves=figures.total_moves,
        revisited=figures.revisits, sim_seconds=figures.sim_seconds, wall_seconds=wall_seconds,
        robots_lost=tuple((v.robot, v.lost) for v in views if v.lost),
        takeovers=len(tracker.takeovers), planned_makespan=planned_makespan, outcome=outcome,
        traffic=_traffic(tracker.model))


def _traffic(model: FleetModel) -> tuple[int, int, int, int] | None:
    counts = [v.traffic for v in model.robots.values() if v.traffic is not None]
    if not counts:
        return None
    return (sum(c.waits for c in counts), sum(c.detours for c in counts),
            sum(c.bumps for c in counts), len(counts))


def format_summary(s: MissionSummary) -> str:
    """The end-of-mission text block."""
    lost = ", ".join(f"{r} ({why})" for r, why in s.robots_lost) or "none"
    plan = "" if s.planned_makespan is None else f" (planned {s.planned_makespan})"
    verdict = "COMPLETE" if s.complete else "INCOMPLETE"
    return "\n".join([
        f"mission {s.mission}: {verdict} — {s.outcome}",
        f"  world {s.world}, algo {s.algo}, {s.robots} robots",
        f"  coverage    {s.coverage:.1f} % ({s.covered} / {s.reachable} reachable sub-cells)",
        f"  makespan    {s.makespan_moves} moves{plan}, {s.sim_seconds:.1f} simulated s "
        f"({s.total_moves} moves in all, {s.revisited} revisits)",
        f"  robots lost {len(s.robots_lost)}: {lost}",
        f"  takeovers   {s.takeovers}",
        *([] if s.traffic is None else [
            f"  traffic     {s.traffic[0]} waits, {s.traffic[1]} detours, {s.traffic[2]} "
            f"bumps (as {s.traffic[3]} robots stated them on completion)"]),
        f"  wall time   {s.wall_seconds:.1f} s",
    ])
