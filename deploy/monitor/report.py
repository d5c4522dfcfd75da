"""What a recorded mission achieved, and whether its invariants held, from the record alone.

The records are replayed into the same FleetModel the live view uses; the figures are read
off it (snapshotting the robots' moves at the instant the last reachable sub-cell was first
covered). A recording may hold gaps (samples the recorder missed that no publisher's cache
could give back, deploy.monitor.live): the report names each, checks the invariants on what
the recording has, and does not fail an invariant on data a gap explains. ``to_json`` is the
stable form for other tools (schema "mstc-report", version 1).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from bus import keys
from deploy.monitor.figures import mission_figures
from deploy.monitor.model import FleetModel
from deploy.monitor.redundancy import EntryAccount, account_entries
from deploy.monitor.types import Gap, Record, Recording
from deploy.monitor.walkouts import kept_opt, remade_plan, walk_out_redundancy
from planner.algorithms import ALGORITHMS, Family, Revisits
from planner.offline.traffic import TrafficCounts

SHOWN_REVISITS = 10  # revisited sub-cells listed by the text report (--json lists all)

REPORT_SCHEMA = "mstc-report"
REPORT_VERSION = 1
# Keys a robot publishes itself (its messages per move); sim/* is simhw's ground truth.
_ROBOT_KINDS = ("hb", "status", "progress", "event", "look")
# Gaps that can hide ground-truth moves: simhw's cover events, or a source never heard.
_WALK_GAPS = ("sim/cover", "unknown")


@dataclass(frozen=True)
class RobotFigures:
    robot: int
    moves: int
    moves_at_coverage: int | None
    revisits: int
    look_steps: int
    messages: int
    messages_per_move: float | None
    dead: bool
    took_over: tuple[int, ...]
    # deconflicted walks (--recovery rebalance), as the robot's completion stated them
    traffic: TrafficCounts | None = None


@dataclass(frozen=True)
class DeathFigures:
    robot: int
    incarnation: int
    reason: str
    detected_by: tuple[int | None, ...]
    t: float
    since_last_heartbeat: float | None
    since_token_lost: float | None
    taken_over_by: tuple[int, ...]
    replanned_by: tuple[int, ...] = ()  # survivors whose re-plan took its work (rebalance)


@dataclass(frozen=True)
class Invariant:
    name: str
    status: str  # "ok", "failed" or "skipped"
    detail: str


@dataclass(frozen=True)
class MissionReport:
    mission: str
    algo: str
    robots: tuple[RobotFigures, ...]
    reachable: int | None
    covered: int
    complete: bool
    coverage_moves: int | None
    coverage_sim_seconds: float | None
    coverage_wall_seconds: float | None
    sim_seconds: float
    revisits: int
    revisited_cells: tuple[tuple[tuple[int, int], tuple[int, ...]], ...]
    # of the revisits: steps made only to sense (ORMSTC's looks from beside), each robot's
    # closing re-entry of its start, and the rest, made by coverage moves
    look_steps: int
    closing_reentries: int
    coverage_revisits: int
    deaths: tuple[DeathFigures, ...]
    conflicts: tuple[tuple[tuple[int, int], tuple[int, ...], int | None], ...]
    messages: int
    malformed_lines: tuple[tuple[int, str], ...]
    invariants: tuple[Invariant, ...]
    curve: tuple[tuple[float, float, int], ...]
    gaps: tuple[Gap, ...] = ()

    @property
    def coverage(self) -> float | None:
        return None if not self.reachable else 100.0 * self.covered / self.reachable

    @property
    def look_step_share(self) -> float | None:
        """Sensing overhead: the share of all moves that were steps made only to sense."""
        moves = sum(f.moves for f in self.robots)
        return round(self.look_steps / moves, 4) if moves else None

    @property
    def ok(self) -> bool:
        return all(inv.status != "failed" for inv in self.invariants)

    def to_json(self) -> dict[str, Any]:
        return {
            "schema": REPORT_SCHEMA, "version": REPORT_VERSION, "mission": self.mission,
            "algo": self.algo, "reachable": self.reachable, "covered": self.covered,
            "coverage_percent": self.coverage, "complete": self.complete,
            "coverage_moves": self.coverage_moves,
            "coverage_sim_seconds": self.coverage_sim_seconds,
            "coverage_wall_seconds": self.coverage_wall_seconds,
            "sim_seconds": self.sim_seconds, "revisits": self.revisits,
            "look_steps": self.look_steps, "look_step_share": self.look_step_share,
            "closing_reentries": self.closing_reentries,
            "coverage_revisits": self.coverage_revisits,
            "revisited_cells": [{"cell": list(c), "robots": list(r)}
                                for c, r in self.revisited_cells],
            "robots": [{"robot": f.robot, "moves": f.moves,
                        "moves_at_coverage": f.moves_at_coverage, "revisits": f.revisits,
                        "look_steps": f.look_steps,
                        "messages": f.messages, "messages_per_move": f.messages_per_move,
                        "dead": f.dead, "took_over": list(f.took_over),
                        "traffic": None if f.traffic is None else f.traffic.as_dict()}
                       for f in self.robots],
            "deaths": [{"robot": d.robot, "incarnation": d.incarnation, "reason": d.reason,
                        "detected_by": list(d.detected_by), "t": d.t,
                        "since_last_heartbeat": d.since_last_heartbeat,
                        "since_token_lost": d.since_token_lost,
                        "taken_over_by": list(d.taken_over_by),
                        "replanned_by": list(d.replanned_by)} for d in self.deaths],
            "conflicts": [{"cell": list(c), "claimants": list(who), "winner": w}
                          for c, who, w in self.conflicts],
            "messages": self.messages,
            "malformed_lines": [{"line": n, "reason": why} for n, why in self.malformed_lines],
            "invariants": [{"name": i.name, "status": i.status, "detail": i.detail}
                           for i in self.invariants],
            "gaps": [{"key": g.key, "family": g.family, "missed": g.missed, "since": g.since,
                      "until": g.until} for g in self.gaps],
            "ok": self.ok,
            "curve": [{"t": t, "sim_time": s, "covered": c} for t, s, c in self.curve],
        }


def replay_model(records: tuple[Record, ...]) -> tuple[FleetModel, dict[int, int] | None]:
    """The model after every record, and each robot's moves when coverage completed."""
    model = FleetModel(max_events=10_000)
    for record in records:
        model.apply(record)
    return model, model.moves_at_coverage


def build_report(recording: Recording) -> MissionReport:
    model, at_coverage = replay_model(recording.records)
    gaps = tuple(r.msg for r in recording.records if isinstance(r.msg, Gap))
    sent = _messages_by_robot(recording.records)
    algos = sorted({v.algo for v in model.robots.values() if v.algo})
    figures = tuple(
        RobotFigures(robot=v.robot, moves=v.moves,
                     moves_at_coverage=None if at_coverage is None else at_coverage.get(r, 0),
                     revisits=v.revisits, look_steps=v.look_steps,
                     messages=sent.get(r, 0),
                     messages_per_move=round(sent.get(r, 0) / v.moves, 3) if v.moves else None,
                     dead=v.dead, took_over=tuple(v.took_over), traffic=v.traffic)
        for r, v in sorted(model.robots.items()))
    account = _account(model)
    complete = model.cover.complete_at
    numbers = mission_figures(model)
    return MissionReport(
        mission=recording.header.mission, algo=",".join(algos) or "unknown", robots=figures,
        reachable=model.total(), covered=model.covered_count(), complete=complete is not None,
        coverage_moves=None if at_coverage is None else numbers.makespan_moves,
        coverage_sim_seconds=numbers.coverage_sim_seconds,
        coverage_wall_seconds=numbers.coverage_wall_seconds,
        sim_seconds=model.sim_time, revisits=numbers.revisits,
        revisited_cells=tuple((cell, tuple(model.cover.visitors.get(cell, ())))
                              for cell, n in sorted(model.covered_cells().items()) if n > 1),
        look_steps=account.look_steps, closing_reentries=len(account.closings),
        coverage_revisits=account.coverage_revisits,
        deaths=_deaths(model), conflicts=_conflicts(model),
        messages=sum(1 for r in recording.records if r.via == "sub"),
        malformed_lines=tuple((e.line, e.reason) for e in recording.errors),
        invariants=check_invariants(model, algos, gaps), curve=tuple(model.cover.curve),
        gaps=gaps)


def _messages_by_robot(records: tuple[Record, ...]) -> dict[int, int]:
    counts: dict[int, int] = {}
    for record in records:
        if record.via != "sub":
            continue
        parsed = keys.parse(record.key)
        if parsed is None:
            continue
        if (parsed.kind in _ROBOT_KINDS or parsed.kind.startswith("ormstc/")) \
                and parsed.robot is not None:
            sender: int | None = parsed.robot
        elif parsed.kind == "death":
            sender = getattr(record.msg, "detected_by", None)
        else:
            continue
        if sender is not None:
            counts[sender] = counts.get(sender, 0) + 1
    return counts


def _deaths(model: FleetModel) -> tuple[DeathFigures, ...]:
    out = []
    for (robot, inc), death in sorted(model.deaths.items()):
        takers = tuple(sorted({r for _, r, dead in model.takeovers if dead == robot}))
        replanners = tuple(sorted({r for _, r, dead in model.replans if robot in dead}))
        out.append(DeathFigures(
            robot=robot, incarnation=inc, reason=death.notice.reason,
            detected_by=death.detectors, t=death.t,
            since_last_heartbeat=None if death.last_heartbeat is None
            else round(death.t - death.last_heartbeat, 6),
            since_token_lost=None if death.token_lost is None
            else round(death.t - death.token_lost, 6),
            taken_over_by=takers, replanned_by=replanners))
    return tuple(out)


def _conflicts(model: FleetModel) -> tuple[tuple[tuple[int, int], tuple[int, ...],
                                                 int | None], ...]:
    settled = [(c.cell, c.claimants, c.winner) for c in model.claims.conflicts]
    return tuple(settled + [(c.cell, c.claimants, None) for c in model.claims.unsettled()])


def _account(model: FleetModel) -> EntryAccount:
    starts = {r: v.start for r, v in model.robots.items() if v.start is not None}
    return account_entries(model.cover, starts)


def check_invariants(model: FleetModel, algos: list[str],
                     gaps: tuple[Gap, ...] = ()) -> tuple[Invariant, ...]:
    return (_all_covered(model, gaps), _redundancy(model, algos), _adjacent(model, gaps))


def _walk_gaps(gaps: tuple[Gap, ...], robot: int | None = None) -> list[Gap]:
    """The gaps that may hide ground-truth moves (of ``robot``, or of anyone)."""
    out = []
    for gap in gaps:
        if gap.family not in _WALK_GAPS:
            continue
        parsed = keys.parse(gap.key)
        whose = None if parsed is None else parsed.robot
        if robot is None or whose is None or whose == robot:
            out.append(gap)
    return out


def _interval(gap: Gap) -> str:
    since = "the start" if gap.since is None else f"{gap.since:.2f} s"
    return f"{gap.key} {since} to {gap.until:.2f} s ({gap.missed} lost)"


def _all_covered(model: FleetModel, gaps: tuple[Gap, ...] = ()) -> Invariant:
    name = "every reachable free sub-cell covered"
    reachable = model.reachable()
    if reachable is None or not model.cover.visits:
        return Invariant(name, "skipped", "no world state or ground truth in the record")
    missing = [(int(r), int(c)) for r, c in zip(*reachable.nonzero(), strict=True)
               if (int(r), int(c)) not in model.cover.visits]
    if missing:
        what = f"{len(missing)} of {int(reachable.sum())} reachable sub-cells never seen " \
               f"covered, e.g. {missing[:5]}"
        hidden = _walk_gaps(gaps)
        if hidden:
            return Invariant(name, "skipped", f"{what}; the recording lost ground truth "
                                              f"({_interval(hidden[0])}): cannot tell")
        return Invariant(name, "failed", what.replace("never seen covered", "never covered"))
    return Invariant(name, "ok", f"all {int(reachable.sum())} covered")


def _redundancy(model: FleetModel, algos: list[str]) -> Invariant:
    # A robot that died, stopped on an error or left unfinished, or was taken over, is a
    # failure for coverage: the others walk over covered cells to take over its share.
    failures = sorted({r for r, v in model.robots.items()
                       if v.dead or v.ended or (v.left and not v.done)}
                      | {dead for _, _, dead in model.takeovers if dead is not None})
    if len(algos) != 1:
        return Invariant("redundancy", "skipped", f"algorithm unknown or mixed: {algos}")
    algo = algos[0]
    if failures:
        return Invariant("redundancy", "skipped",
                         f"the run had failures (robots {failures}); takeovers revisit cells")
    counts = model.covered_cells()
    known = ALGORITHMS.get(algo)
    promise = known.revisits if known is not None else Revisits.ANY
    if known is not None and known.family is Family.ONLINE:
        return _ormstc_redundancy(model)
    shown = algo
    if promise is Revisits.WALK_OUTS:
        name = f"no sub-cell covered twice except on walk-outs ({algo})"
        if not any(v.path for v in model.robots.values()):  # no plan to make again for it
            return Invariant(name, "skipped", "no ground-truth walks in the record")
        plan = remade_plan(model, algo)
        if isinstance(plan, str):
            return Invariant(name, "skipped", plan)
        if not kept_opt(plan):
            return Invariant(name, *walk_out_redundancy(model, plan))
        promise, shown = ALGORITHMS["opt"].revisits, f"{algo}, which kept opt's plan"
    if promise is Revisits.NONE:
        twice = sorted(c for c, n in counts.items() if n > 1)
        if twice:
            return Invariant(f"no sub-cell covered twice ({algo})", "failed",
                             f"{len(twice)} sub-cells covered more than once, e.g. "
                             + _whose(model, twice))
        return Invariant(f"no sub-cell covered twice ({algo})", "ok", "every sub-cell once")
    if promise is Revisits.BACKTRACK:
        name = f"at most twice, by the same robot ({shown})"
        thrice = sorted(c for c, n in counts.items() if n > 2)
        shared = sorted(c for c, who in model.cover.visitors.items() if len(set(who)) > 1)
        if thrice or shared:
            what = [f"{len(thrice)} covered 3+ times"] if thrice else []
            what += [f"{len(shared)} covered by two robots"] if shared else []
            return Invariant(name, "failed", f"{', '.join(what)}, e.g. "
                             + _whose(model, (thrice + shared)))
        return Invariant(name, "ok", f"{sum(n > 1 for n in counts.values())} sub-cells "
                                     f"covered twice, each by one robot")
    return Invariant("redundancy", "skipped", f"no redundancy promise known for {algo!r}")


def _ormstc_redundancy(model: FleetModel) -> Invariant:
    """What ORMSTC promises: the coverage walk enters no sub-cell twice. Steps made only to
    sense and each robot's closing re-entry of its start are counted, not failed."""
    name = "no sub-cell covered twice by coverage moves (ormstc)"
    account = _account(model)
    excused = f"{account.look_steps} look steps and {len(account.closings)} closing " \
              f"re-entries of starts excepted"
    if account.covered_twice:
        where = "; ".join(f"{c} by robots {list(who)}" for c, who in account.covered_twice[:5])
        return Invariant(name, "failed", f"{len(account.covered_twice)} sub-cells entered more "
                                         f"than once by coverage moves, e.g. {where} ({excused})")
    return Invariant(name, "ok", f"every sub-cell once ({excused})")


def _whose(model: FleetModel, cells: list[tuple[int, int]]) -> str:
    return "; ".join(f"{c} by robots {model.cover.visitors.get(c, ['?'])}" for c in cells[:5])


def _adjacent(model: FleetModel, gaps: tuple[Gap, ...] = ()) -> Invariant:
    """Each recorded step is to a 4-neighbour; a jump in the walk of a robot whose ground
    truth the recording lost is where the lost moves were, not a failure."""
    name = "every move 4-adjacent"
    jumps = 0
    for r, view in sorted(model.robots.items()):
        hidden = bool(_walk_gaps(gaps, r))
        for i, (a, b) in enumerate(zip(view.path, view.path[1:], strict=False)):
            if abs(a[0] - b[0]) + abs(a[1] - b[1]) != 1:
                if not hidden:
                    return Invariant(name, "failed", f"robot {r} step {i}: {a} -> {b}")
                jumps += 1
    if not any(v.path for v in model.robots.values()):
        return Invariant(name, "skipped", "no ground-truth walks in the record")
    across = f"; {jumps} jumps across the recording's gaps not checked" if jumps else ""
    return Invariant(name, "ok", f"{sum(v.moves for v in model.robots.values())} moves{across}")


def format_report(report: MissionReport) -> str:
    """The human-readable report."""
    cov = "unknown" if report.coverage is None else \
        f"{report.coverage:.1f} % ({report.covered}/{report.reachable})"
    lines = [f"mission {report.mission} ({report.algo}): coverage {cov}"]
    if report.complete:
        lines.append(f"  covered in {report.coverage_moves} moves (makespan), "
                     f"{report.coverage_sim_seconds:.1f} simulated s, "
                     f"{report.coverage_wall_seconds:.1f} s after recording started")
    lines.append(f"  {report.revisits} revisits; {report.messages} messages; "
                 f"sim time {report.sim_seconds:.1f} s")
    if report.look_steps or report.closing_reentries:
        share = report.look_step_share
        lines.append(f"  sensing overhead: {report.look_steps} look steps"
                     f"{'' if share is None else f' ({100 * share:.1f} % of all moves)'}; "
                     f"{report.closing_reentries} closing re-entries of starts; "
                     f"{report.coverage_revisits} revisits by coverage moves")
    for f in report.robots:
        per = "-" if f.messages_per_move is None else f"{f.messages_per_move:.2f}"
        extra = (" DEAD" if f.dead else "") + \
            (f" took over {list(f.took_over)}" if f.took_over else "")
        looks = f", {f.look_steps} look steps" if f.look_steps else ""
        traffic = "" if f.traffic is None else f", {f.traffic.describe()}"
        lines.append(f"  robot {f.robot}: {f.moves} moves, {f.revisits} revisits{looks}"
                     f"{traffic}, {f.messages} messages ({per}/move){extra}")
    for c, who in report.revisited_cells[:SHOWN_REVISITS]:
        lines.append(f"  revisited {c} by robots {list(who)}")
    if len(report.revisited_cells) > SHOWN_REVISITS:
        lines.append(f"  ... and {len(report.revisited_cells) - SHOWN_REVISITS} more revisited "
                     f"sub-cells (all of them in --json)")
    for d in report.deaths:
        hb = "-" if d.since_last_heartbeat is None else f"{d.since_last_heartbeat:.3f} s"
        tok = "-" if d.since_token_lost is None else f"{d.since_token_lost:.3f} s"
        lines.append(f"  death: robot {d.robot} (life {d.incarnation}) by {list(d.detected_by)}"
                     f" ({d.reason}), {hb} after its last heartbeat, {tok} after its token "
                     f"vanished; {_recovered_by(d)}")
    for cell, who, winner in report.conflicts:
        lines.append(f"  conflict over cell {cell}: {list(who)} -> "
                     f"{'unsettled' if winner is None else f'robot {winner}'}")
    for number, why in report.malformed_lines:
        lines.append(f"  malformed line {number} skipped: {why}")
    for gap in report.gaps:
        lines.append(f"  gap in the recording: {_interval(gap)}, not recoverable from "
                     f"the publishers' caches")
    for inv in report.invariants:
        mark = {"ok": "ok     ", "failed": "FAILED ", "skipped": "skipped"}[inv.status]
        lines.append(f"  [{mark}] {inv.name}: {inv.detail}")
    failed = [inv.name for inv in report.invariants if inv.status == "failed"]
    lines.append("verdict: ok (no invariant failed)" if not failed else
                 f"verdict: FAILED ({'; '.join(failed)})")
    return "\n".join(lines)


def _recovered_by(death: DeathFigures) -> str:
    if death.replanned_by and not death.taken_over_by:
        return f"its work re-planned by {list(death.replanned_by)}"
    text = f"taken over by {list(death.taken_over_by) or 'nobody'}"
    if death.replanned_by:
        text += f", re-planned by {list(death.replanned_by)}"
    return text
