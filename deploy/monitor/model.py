"""The fleet as the wire shows it: a pure model fed with received records.

No I/O and no clock: every record carries its receive time. ``apply`` updates the model and
returns the events worth a line. Ground truth (simhw's CoverEvents and WorldState answers)
decides coverage; agents' statuses, events and death notices say who joined, finished, died,
detected whom and took over; liveliness tokens say when a process vanished. Where a record
repeats what is known (re-announcements, state-query answers, the periodic world answer) the
model stays the same, so a monitor that joins late converges on the same picture.
"""

from __future__ import annotations

import re
from collections import Counter, deque
from typing import Any

from bus.messages import (
    AgentState,
    BumpEvent,
    CoverEvent,
    DeathNotice,
    GroundTruthPose,
    Heartbeat,
    LookStep,
    MissionStatus,
    Progress,
    RobotEvent,
    RobotStatus,
    TreeReport,
    WorldState,
    world_free,
    world_visits,
)
from deploy.monitor.coverage import CoverageMap
from deploy.monitor.ormstc import ClaimBook, fields_of
from deploy.monitor.planned import Edge
from deploy.monitor.robots import RobotView, Roster
from deploy.monitor.tree import TreeMission
from deploy.monitor.types import (
    Death,
    EventKind,
    MonitorEvent,
    Opaque,
    Picture,
    Record,
    TokenChange,
)
from deploy.monitor.world import WorldPicture
from planner.offline.traffic import TrafficCounts
from planner.types import BoolArray, SubCell


class FleetModel:
    """Everything a monitor knows about one mission. Feed it with :meth:`apply`."""

    def __init__(self, max_events: int = 1000) -> None:
        self.invalid: Counter[str] = Counter()
        self.roster = Roster(self.invalid)
        self.world = WorldPicture(self.invalid)
        self.claims = ClaimBook()
        self.tree = TreeMission()
        self.mission: MissionStatus | None = None
        self.sim_time = 0.0
        self.time_scale: float | None = None
        self.t = 0.0
        self.events: deque[MonitorEvent] = deque(maxlen=max_events)
        self.event_count = 0
        self.kinds: Counter[str] = Counter()
        self.deaths: dict[tuple[int, int], Death] = {}
        self.takeovers: list[tuple[float, int, int | None]] = []
        # (t, robot, the dead its re-plan names) of every re-plan (offline `rebalance`)
        self.replans: list[tuple[float, int, tuple[int, ...]]] = []
        # each robot's moves once the record that completed the coverage was applied
        self.moves_at_coverage: dict[int, int] | None = None
        self._seen_events: set[tuple[Any, ...]] = set()
        self._new: list[MonitorEvent] = []

    @property
    def robots(self) -> dict[int, RobotView]:
        return self.roster.robots

    @property
    def cover(self) -> CoverageMap:
        return self.world.cover

    @property
    def edges(self) -> dict[Edge, int]:
        """Tree edges drawn between cells, with the robot whose tree each belongs to."""
        return self.world.edges

    # --- input ---------------------------------------------------------------------------

    def apply(self, record: Record) -> list[MonitorEvent]:
        """Update the model with one record; return the events it caused."""
        self._new = []
        self.t = max(self.t, record.t)
        self.kinds[record.kind] += 1
        msg = record.msg
        handler = _HANDLERS.get(type(msg))
        if handler is not None:
            handler(self, record, msg)
        else:
            self._other(record, msg)
        if self.moves_at_coverage is None and self.cover.complete_at is not None:
            self.moves_at_coverage = {r: v.moves for r, v in self.robots.items()}
        return self._new

    def _emit(self, t: float, kind: EventKind, robot: int | None, text: str) -> None:
        event = MonitorEvent(t, kind, robot, text)
        self.events.append(event)
        self.event_count += 1
        self._new.append(event)

    def note(self, t: float, kind: EventKind, text: str) -> MonitorEvent:
        """An event of the mission found outside the records (a verdict read off them)."""
        self._emit(t, kind, None, text)
        return self.events[-1]

    def _once(self, *identity: Any) -> bool:
        """True the first time ``identity`` is seen (re-announcements are not news)."""
        if identity in self._seen_events:
            return False
        self._seen_events.add(identity)
        return True

    def _sim(self, sim_time: float) -> None:
        self.sim_time = max(self.sim_time, sim_time)

    def _heartbeat(self, record: Record, hb: Heartbeat) -> None:
        view = self.roster.valid(record, hb.robot, "heartbeat")
        if view is None or (view.death is not None and hb.incarnation <= view.death.incarnation):
            return  # a fenced life
        view.incarnation = max(view.incarnation, hb.incarnation)
        view.last_heartbeat = record.t
        if not (view.done or view.left or view.ended):
            view.state = hb.state
        if hb.pose is not None and view.pose is None:
            view.pose = hb.pose
        self._sim(hb.sim_time)

    def _status(self, record: Record, st: RobotStatus) -> None:
        view = self.roster.valid(record, st.robot, "status")
        if view is None or st.incarnation < view.incarnation:
            return
        view.incarnation = st.incarnation
        view.start = (int(st.start[0]), int(st.start[1]))
        view.algo = st.algo
        if st.plan_digest and not view.plan_digest:
            view.plan_digest = st.plan_digest  # the agreed plan's (a later life re-announces it)
        if not (view.dead and st.state not in ("fenced", "stopped", "left")):
            view.state = st.state
        view.done = view.done or st.state == "done"
        if self._once("joined", st.robot, st.incarnation):
            self._emit(record.t, "joined", st.robot,
                       f"robot {st.robot} joined (life {st.incarnation}, start {view.start}, "
                       f"algo {st.algo})")

    def _progress(self, record: Record, pr: Progress) -> None:
        view = self.roster.valid(record, pr.robot, "progress")
        if view is None:
            return
        cell = (int(pr.cell[0]), int(pr.cell[1]))
        view.reported_moves = max(view.reported_moves, pr.seq)
        self.cover.reported[cell] = self.cover.reported.get(cell, 0) + 1
        if not view.path:
            heading = view.pose[2] if view.pose else 0
            view.pose = (cell[0], cell[1], heading)
        self._sim(pr.sim_time)

    def _event(self, record: Record, ev: RobotEvent) -> None:
        view = self.roster.valid(record, ev.robot, "event")
        if view is None or not self._once("event", ev.robot, ev.incarnation, ev.kind,
                                          ev.subject, ev.detail):
            return
        r, s, detail = ev.robot, ev.subject, f" ({ev.detail})" if ev.detail else ""
        if ev.kind == "takeover_started":
            if s is not None:
                view.took_over.append(s)
            self.takeovers.append((record.t, r, s))
            self._emit(record.t, "takeover", r, f"robot {r} takes over robot {s}{detail}")
        elif ev.kind == "takeover_finished":
            self._emit(record.t, "takeover_done", r, f"robot {r} finished robot {s}'s "
                                                     f"section{detail}")
        elif ev.kind == "replanned":
            self.replans.append((record.t, r, _dead_of_replan(ev.detail)))
            self._emit(record.t, "replanned", r, f"robot {r} re-planned{detail}")
        elif ev.kind == "section_complete":
            self._emit(record.t, "section_complete", r, f"robot {r} covered its section"
                                                        f"{detail}")
        elif ev.kind == "completed":
            view.done = True
            view.state = "done"
            view.traffic = TrafficCounts.parse(ev.detail) or view.traffic
            self._emit(record.t, "completed", r, f"robot {r} completed{detail}")
        elif ev.kind == "completion_withdrawn":
            view.done = False
            self._emit(record.t, "withdrawn", r, f"robot {r} withdrew its completion"
                                                 f"{detail}")
        elif ev.kind in ("leaving", "fenced", "stopped"):
            view.left = view.left or ev.kind == "leaving"
            view.ended = view.ended or ("" if ev.kind == "leaving" else ev.kind)
            view.state = "left" if ev.kind == "leaving" else ev.kind
            kind: EventKind = "left" if ev.kind == "leaving" else ev.kind
            self._emit(record.t, kind, r, f"robot {r} {view.state}{detail}")

    def _look_step(self, record: Record, step: LookStep) -> None:
        view = self.roster.valid(record, step.robot, "look_step")
        if view is not None and self._once("look", step.robot, step.incarnation, step.seq):
            view.look_steps += 1
            self.cover.looked(step.robot, (int(step.cell[0]), int(step.cell[1])))

    def _death(self, record: Record, notice: DeathNotice) -> None:
        view = self.roster.valid(record, notice.robot, "death")
        if view is None:
            return
        ident = (notice.robot, notice.incarnation)
        known = self.deaths.get(ident)
        if known is not None:
            if notice.detected_by not in known.detectors:
                self.deaths[ident] = Death(known.notice, known.t, known.last_heartbeat,
                                           known.token_lost,
                                           (*known.detectors, notice.detected_by))
            return
        if self.roster.verdict_of_the_dead(notice, view):
            self.invalid["death.dead_detector"] += 1
            return
        if notice.reason == "leaving":
            view.left = True
            if self._once("left", *ident):
                self._emit(record.t, "left", notice.robot, f"robot {notice.robot} left")
            return
        if view.death is None or view.death.incarnation < notice.incarnation:
            view.death = notice
            view.state = "dead"
        self.deaths[ident] = Death(notice, record.t, view.last_heartbeat, view.token_lost,
                                   (notice.detected_by,))
        by = "an observer" if notice.detected_by is None else f"robot {notice.detected_by}"
        since = "" if view.last_heartbeat is None else \
            f", {record.t - view.last_heartbeat:.2f} s after its last heartbeat"
        self._emit(record.t, "detected_dead", notice.robot,
                   f"robot {notice.robot} declared dead by {by} ({notice.reason}{since})")

    def _mission(self, record: Record, status: MissionStatus) -> None:
        if self.tree.on_status(status):
            self._emit(record.t, "world", None, self.tree.line())
        final = self.mission is not None and self.mission.state != "running"
        if final and status.state == "running":
            return
        self.mission = status
        if status.state != "running" and self._once("mission", status.state):
            kind: EventKind = "mission_complete" if status.state == "complete" \
                else "mission_failed"
            self._emit(record.t, kind, None, f"mission {status.state}: {status.message}")

    def _pose(self, record: Record, gt: GroundTruthPose) -> None:
        view = self.roster.valid(record, gt.robot, "gt_pose")
        if view is not None:
            view.pose = (int(gt.pose[0]), int(gt.pose[1]), int(gt.pose[2]))
            self._sim(gt.sim_time)

    def _bump(self, record: Record, bump: BumpEvent) -> None:
        if self.roster.valid(record, bump.robot, "bump") is not None:
            self._emit(record.t, "bump", bump.robot, f"robot {bump.robot} bumped at "
                                                     f"{tuple(bump.at)} into {tuple(bump.into)}")
            self._sim(bump.sim_time)

    def _token(self, record: Record, change: TokenChange) -> None:
        view = self.roster.valid(record, change.robot, "token")
        if view is None or change.incarnation < view.incarnation:
            return
        view.incarnation = change.incarnation
        view.token = change.present
        if change.present:
            view.token_lost = None
        elif view.token_lost is None and not view.left:
            view.token_lost = record.t
            if self._once("vanished", change.robot, change.incarnation):
                self._emit(record.t, "died", change.robot, f"robot {change.robot}'s process "
                                                           f"vanished (liveliness token gone)")

    # --- coverage ------------------------------------------------------------------------

    def _cover(self, record: Record, ev: CoverEvent) -> None:
        view = self.roster.valid(record, ev.robot, "cover")
        if view is None:
            return
        cell = (int(ev.cell[0]), int(ev.cell[1]))
        self._sim(ev.sim_time)
        if not self.cover.visit(ev.robot, cell, ev.visits):
            return  # a duplicate delivery of a visit already counted
        if view.path:
            self.world.crossing(view.path[-1], cell, ev.robot)
        view.path.append(cell)
        heading = view.pose[2] if view.pose else 0
        view.pose = (cell[0], cell[1], heading)
        if ev.visits > 1:
            view.revisits += 1
        self._set_visits(record.t, cell, ev.visits)

    def _set_visits(self, t: float, cell: SubCell, count: int) -> None:
        if self.cover.set_visits(t, self.sim_time, cell, count, self.roster.positions()):
            self._emit(t, "world", None, "every reachable sub-cell is covered")

    def _world(self, record: Record, state: WorldState) -> None:
        if self.cover.set_map(state.map_name, world_free(state)):
            self._emit(record.t, "world", None, f"world {state.map_name}: "
                                                f"{state.shape[0]} x {state.shape[1]} sub-cells")
        self.time_scale = state.time_scale
        self._sim(state.sim_time)
        for cell, count in self.cover.newer_counts(world_visits(state)):
            self._set_visits(record.t, cell, count)
        self.world.merge_firsts(state)
        for truth in state.robots:
            view = self.roster.valid(record, truth.robot, "world")
            if view is None:
                continue
            view.pose = (int(truth.pose[0]), int(truth.pose[1]), int(truth.pose[2]))
            view.truth_moves = max(view.truth_moves, truth.covered - 1)
            view.frozen = truth.frozen
            if truth.failed and not view.failed:
                view.failed = True
                self._emit(record.t, "died", truth.robot, f"robot {truth.robot}'s body failed")
        if self.cover.check_complete(record.t, self.sim_time, self.roster.positions()):
            self._emit(record.t, "world", None, "every reachable sub-cell is covered")

    def _tree_report(self, record: Record, report: TreeReport) -> None:
        self.tree.on_report(record, report)

    def _agent_state(self, record: Record, st: AgentState) -> None:
        view = self.roster.valid(record, st.robot, "agent_state")
        if view is None or st.incarnation < view.incarnation:
            return
        if not view.dead and not view.left:
            view.state = st.state
            view.done = view.done or st.state == "done"
        view.reported_moves = max(view.reported_moves, st.moves)
        view.took_over.extend(d for d in st.took_over if d not in view.took_over)
        if st.tree_kind:
            view.tree_kind, view.seed = st.tree_kind, st.seed
        for event in self.claims.restore(record.t, st.robot, st.tree, st.claims):
            if event.edge is not None:
                self.world.built_edge(event.edge, st.robot)

    def _other(self, record: Record, msg: Any) -> None:
        """ORMSTC messages, typed or not."""
        kind = record.kind
        fields = msg.fields if isinstance(msg, Opaque) else fields_of(msg)
        parsed = self.roster.parse(record.key)
        if parsed is not None and parsed.kind.startswith("ormstc/"):
            for event in self.claims.apply(record.t, parsed.kind, fields):
                if event.kind == "tree_edge_retracted" and event.edge is not None:
                    self.world.retracted_edge(event.edge)
                elif event.edge is not None and event.robot is not None:
                    self.world.built_edge(event.edge, event.robot)
                if event.kind in ("completed", "withdrawn") and event.robot is not None:
                    self.roster.robot(event.robot).done = event.kind == "completed"
                if event.text:
                    self._emit(record.t, event.kind, event.robot, event.text)
            return
        self.invalid[f"{kind}.unhandled"] += 1

    # --- derived -------------------------------------------------------------------------

    def planned_tree(self) -> frozenset[Edge] | None:
        """The offline plan's tree edges, or None until the wire has told enough to rebuild it."""
        return self.world.planned_tree(self.robots)

    def reachable(self) -> BoolArray | None:
        return self.cover.reachable(self.roster.positions())

    def covered_cells(self) -> dict[SubCell, int]:
        return self.cover.covered_cells()

    def covered_count(self) -> int:
        return self.cover.covered_count(self.roster.positions())

    def total(self) -> int | None:
        return self.cover.total(self.roster.positions())

    def coverage(self) -> float | None:
        total = self.total()
        return None if not total else 100.0 * self.covered_count() / total

    def revisits(self) -> int:
        return self.cover.revisits()

    def counts(self) -> tuple[int, int, int, int]:
        """Robots (known, alive, dead, done)."""
        return self.roster.counts()

    def picture(self) -> Picture:
        visits = self.covered_cells()
        return Picture(
            covered=frozenset(visits), visits=frozenset(visits.items()),
            robots=tuple((v.robot, v.moves, v.dead, v.done, v.left)
                         for v in sorted(self.robots.values(), key=lambda v: v.robot)),
            mission=self.mission.state if self.mission else "",
            owners=frozenset(self.cover.owner.items()), edges=frozenset(self.edges.items()))


_HANDLERS: dict[type[Any], Any] = {
    Heartbeat: FleetModel._heartbeat, RobotStatus: FleetModel._status,
    Progress: FleetModel._progress, RobotEvent: FleetModel._event,
    LookStep: FleetModel._look_step,
    DeathNotice: FleetModel._death, MissionStatus: FleetModel._mission,
    GroundTruthPose: FleetModel._pose, BumpEvent: FleetModel._bump,
    TokenChange: FleetModel._token, CoverEvent: FleetModel._cover,
    WorldState: FleetModel._world, AgentState: FleetModel._agent_state,
    TreeReport: FleetModel._tree_report,
}


_REPLAN_DEAD = re.compile(r"dead \[([0-9, ]*)\]")


def _dead_of_replan(detail: str) -> tuple[int, ...]:
    """The robots a ``replanned`` event names dead (its detail reads "dead [2, 5], ...")."""
    found = _REPLAN_DEAD.search(detail)
    if found is None:
        return ()
    return tuple(int(x) for x in found.group(1).replace(",", " ").split())
