"""ORMSTC machine messages <-> bus messages, and the checks every received one passes.

The planner's messages (planner.ormstc.types) carry no life and no order; on the wire each
becomes its bus.messages twin with the sender's ``incarnation`` and ``seq`` (1, 2, ... per
life, over all ORMSTC kinds), published on ``mstc/<m>/ormstc/<kind>/<robot>``. All kinds share
one QoS (bus.qos CRITICAL), so one sender's messages stay in order across keys: the machine
assumes FIFO per sender. A receiver drops (and counts) a message about a robot outside the
fleet, on a key naming another robot, or from a life older than one already heard. Each
sender's messages are delivered in ``seq`` order (planner.ormstc.streams): a duplicate is
dropped, a gap (a message dropped, lost or reordered on the way) is counted and what follows
it held back until the gap is filled; the sender says a message again when a peer's
heartbeat shows it lacking (``Heartbeat.heard``), and its heartbeat's ``said`` shows a lost
last message. What Zenoh loses during a router outage is not repaired message by
message: when a peer is heard again after a silence (:class:`Rejoin`), every robot restates
what its peers must know of it (planner.ormstc.conflicts.restate) with fresh ``seq`` numbers,
and a receiver drops a start, tree edge or freed robot it already heard from that life
(counted in ``Inbound.repeats``), so hearing a restatement changes nothing else.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from bus import keys
from bus.drops import DropCounter
from bus.messages import (
    ORMSTC_MESSAGES,
    Cell,
    OrmstcClaim,
    OrmstcCompletion,
    OrmstcConnection,
    OrmstcDeadRobot,
    OrmstcRetraction,
    OrmstcStart,
    OrmstcTreeEdge,
    OrmstcWire,
    OrmstcWithdrawal,
)
from planner.ormstc.streams import PeerStreams
from planner.ormstc.types import (
    ClaimMsg,
    CompletionMsg,
    ConnectionMsg,
    DeadRobotMsg,
    Message,
    RetractionMsg,
    StartMsg,
    TreeEdgeMsg,
    WithdrawalMsg,
)

WIRE_TYPES = ORMSTC_MESSAGES

_KEY: dict[type, Callable[[str, int], str]] = {
    OrmstcStart: keys.ormstc_start, OrmstcClaim: keys.ormstc_claim,
    OrmstcTreeEdge: keys.ormstc_tree, OrmstcConnection: keys.ormstc_conn,
    OrmstcDeadRobot: keys.ormstc_dead, OrmstcCompletion: keys.ormstc_done,
    OrmstcWithdrawal: keys.ormstc_withdraw, OrmstcRetraction: keys.ormstc_retract,
}


def to_wire(msg: Message, incarnation: int, seq: int) -> OrmstcWire:
    """The bus message for a machine message of this life."""
    r, i, s = msg.robot, incarnation, seq
    if isinstance(msg, StartMsg):
        return OrmstcStart(r, i, s, msg.sub)
    if isinstance(msg, ClaimMsg):
        return OrmstcClaim(r, i, s, msg.cell, msg.covered)
    if isinstance(msg, TreeEdgeMsg):
        return OrmstcTreeEdge(r, i, s, msg.parent, msg.child)
    if isinstance(msg, ConnectionMsg):
        return OrmstcConnection(r, i, s, msg.peer, msg.mine, msg.theirs)
    if isinstance(msg, DeadRobotMsg):
        return OrmstcDeadRobot(r, i, s, msg.dead)
    if isinstance(msg, CompletionMsg):
        return OrmstcCompletion(r, i, s, msg.cells)
    if isinstance(msg, RetractionMsg):
        return OrmstcRetraction(r, i, s, msg.parent, msg.child)
    return OrmstcWithdrawal(r, i, s, msg.peer)


def from_wire(wire: OrmstcWire) -> Message:
    """The machine message a bus message carries."""
    if isinstance(wire, OrmstcStart):
        return StartMsg(wire.robot, wire.sub)
    if isinstance(wire, OrmstcClaim):
        return ClaimMsg(wire.robot, wire.cell, wire.covered)
    if isinstance(wire, OrmstcTreeEdge):
        return TreeEdgeMsg(wire.robot, wire.parent, wire.child)
    if isinstance(wire, OrmstcConnection):
        return ConnectionMsg(wire.robot, wire.peer, wire.mine, wire.theirs)
    if isinstance(wire, OrmstcDeadRobot):
        return DeadRobotMsg(wire.robot, wire.dead)
    if isinstance(wire, OrmstcCompletion):
        return CompletionMsg(wire.robot, wire.cells)
    if isinstance(wire, OrmstcRetraction):
        return RetractionMsg(wire.robot, wire.parent, wire.child)
    return WithdrawalMsg(wire.robot, wire.peer)


def key_for(mission: str, wire: OrmstcWire) -> str:
    return _KEY[type(wire)](mission, wire.robot)


@dataclass
class Inbound:
    """Per-sender bookkeeping of received ORMSTC messages (one robot's view of the fleet):
    checks, then in-order delivery per sender life with duplicates removed and gaps held
    back until repaired (planner.ormstc.streams.PeerStreams)."""

    me: int
    k: int
    drops: DropCounter
    streams: PeerStreams[OrmstcWire] = field(default_factory=PeerStreams)
    repeats: int = 0  # facts heard again (restatements), not delivered
    _facts: set[tuple[object, ...]] = field(default_factory=set)

    @property
    def gaps(self) -> int:
        return self.streams.gaps

    def accept(self, key: str, wire: OrmstcWire,
               now: float = 0.0) -> list[tuple[OrmstcWire, Message]]:
        """The messages to deliver now, in the sender's order (none: own echo, dropped and
        counted, a duplicate, or held back behind a gap)."""
        robot = wire.robot
        kind = keys.kind_of(key)
        parsed = keys.parse(key)
        if parsed is None or parsed.robot != robot or not 0 <= robot < self.k:
            self.drops.count(kind, "invalid", f"robot {robot} on {key} (fleet 0..{self.k - 1})")
            return []
        if robot == self.me:
            return []
        if self.streams.stale(robot, wire.incarnation):
            newest = self.streams.streams[robot].life
            self.drops.count(kind, "stale", f"robot {robot} life {wire.incarnation} < {newest}")
            return []
        gaps = self.streams.gaps
        taken = self.streams.receive(robot, wire.incarnation, wire.seq, wire, now)
        if self.streams.gaps > gaps:
            self.drops.count(kind, "gap", f"robot {robot}: seq {wire.seq}, "
                             f"{self.streams.gaps - gaps} missing before it (held back)")
        out = []
        for item in taken:
            message = self._deliverable(key, item)
            if message is not None:
                out.append((item, message))
        return out

    def heartbeat(self, robot: int, incarnation: int, said: int, now: float,
                  acked: int | None = None) -> None:
        """A peer's heartbeat: it had said ``said`` messages (a lost last one shows here)
        and taken ``acked`` of ours."""
        if 0 <= robot < self.k and robot != self.me:
            self.streams.digest(robot, incarnation, said, now, acked)

    def _deliverable(self, key: str, wire: OrmstcWire) -> Message | None:
        if self._peers_out_of_range(wire):
            self.drops.count(keys.kind_of(key), "invalid", f"{wire} names a robot outside "
                             "the fleet")
            return None
        fact = _fact(wire)
        if fact is not None:
            if fact in self._facts:
                self.repeats += 1
                return None
            self._facts.add(fact)
        return from_wire(wire)

    def _peers_out_of_range(self, wire: OrmstcWire) -> bool:
        other = getattr(wire, "dead", getattr(wire, "peer", None))
        return other is not None and not 0 <= other < self.k


def _fact(wire: OrmstcWire) -> tuple[object, ...] | None:
    """What a start, tree edge, retraction or freed robot says for good (claims, completions and
    withdrawals are not facts: they may be said again and mean something new)."""
    if isinstance(wire, OrmstcStart):
        return (wire.robot, wire.incarnation, "start", wire.sub)
    if isinstance(wire, OrmstcTreeEdge):
        return (wire.robot, wire.incarnation, "tree", wire.parent, wire.child)
    if isinstance(wire, OrmstcDeadRobot):
        return (wire.robot, wire.incarnation, "dead", wire.dead)
    if isinstance(wire, OrmstcRetraction):
        return (wire.robot, wire.incarnation, "retract", wire.parent, wire.child)
    return None


@dataclass
class Rejoin:
    """When to restate this robot's ORMSTC messages: a peer heard again after ``silence``
    seconds without a heartbeat was cut off (a router restart, a broken link), and whatever
    either side said meanwhile is lost. Restate ``delays`` after that (the first lets the
    peer's subscriptions reach the router, the second covers a peer that came back later);
    due times closer than the first delay are merged, so a fleet coming back costs each
    robot one or two restatements, and a mission without outages none."""

    silence: float
    delays: tuple[float, ...] = (0.3, 1.5)
    last_heard: dict[int, float] = field(default_factory=dict)
    due: list[float] = field(default_factory=list)
    count: int = 0  # restatements made

    def heard(self, robot: int, now: float) -> bool:
        """Note a sign of life of ``robot``; True if it ends a silence."""
        last = self.last_heard.get(robot)
        self.last_heard[robot] = now
        if last is None or now - last < self.silence:
            return False
        for delay in self.delays:
            at = now + delay
            if all(abs(t - at) >= self.delays[0] for t in self.due):
                self.due.append(at)
        self.due.sort()
        return True

    def take(self, now: float) -> bool:
        """Whether a restatement is due at ``now`` (each due time is used once)."""
        if not self.due or self.due[0] > now:
            return False
        self.due = [t for t in self.due if t > now]
        self.count += 1
        return True

    def next_due(self) -> float | None:
        return self.due[0] if self.due else None


@dataclass
class TreeBook:
    """This robot's ORMSTC tree edges and unsettled claims, as it said them on the wire, for
    its state replies: ORMSTC messages are said once, so a late joiner learns them here."""

    tree: list[tuple[Cell, Cell]] = field(default_factory=list)
    claims: dict[Cell, None] = field(default_factory=dict)  # insertion-ordered set
    owners: dict[Cell, int] = field(default_factory=dict)  # peers' cells, as heard

    def sent(self, wire: OrmstcWire) -> None:
        if isinstance(wire, OrmstcClaim) and wire.cell not in self.owners:
            self.claims[wire.cell] = None
        elif isinstance(wire, OrmstcTreeEdge):
            self.tree.append((wire.parent, wire.child))
            self.claims.pop(wire.child, None)
        elif isinstance(wire, OrmstcRetraction):  # the cell is given up: no edge, no claim
            if (wire.parent, wire.child) in self.tree:
                self.tree.remove((wire.parent, wire.child))
            self.claims.pop(wire.child, None)

    def heard(self, wire: OrmstcWire) -> None:
        """A peer's tree edge settles our claim on its child cell (we lost it); a dead
        robot's cells are free again."""
        if isinstance(wire, OrmstcTreeEdge):
            self.owners[wire.child] = wire.robot
            self.claims.pop(wire.child, None)
        elif isinstance(wire, OrmstcDeadRobot):
            self.owners = {c: r for c, r in self.owners.items() if r != wire.dead}
