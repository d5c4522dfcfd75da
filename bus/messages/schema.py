"""The wire schema: one row per message kind, from which the rest of bus/ is derived.

A row (:class:`Kind`) names the message class (its ``KIND`` tag is the ``_kind`` on the
wire), the key families it travels on, its QoS class and the wire generation its fields last
changed in. ``bus.keys`` builds and parses every key from the families, ``bus.qos`` gives each
QoS class its Zenoh settings, ``bus.codec`` knows exactly the kinds and records listed here.
Adding a message type is a frozen dataclass in its subject's module and one row in
:data:`KINDS` (docs/protocol.md, "Adding a message type"). Each key family also says who
may write on it (:class:`Access`): ``bus.security.acl`` turns that into the router's access
rules, and ``bus.bridge`` drops a message whose robot id disagrees with its key.

Field types are limited to what the codec checks strictly: int, float, str, bool, bytes,
None, Literal[...], tuple[...] (fixed or ``tuple[X, ...]``), dict[str|int, X], unions, and
nested record dataclasses (listed in :data:`RECORDS`).
"""

from __future__ import annotations

import enum
import functools
import re
from dataclasses import dataclass
from typing import Any, Literal

from bus.messages.hardware import AdminCommand, AdminReply, HwCommand, HwReply
from bus.messages.lifecycle import DeathNotice, Heartbeat, MissionStatus, RobotEvent, RobotStatus
from bus.messages.ormstc import (
    OrmstcClaim,
    OrmstcCompletion,
    OrmstcConnection,
    OrmstcDeadRobot,
    OrmstcRetraction,
    OrmstcStart,
    OrmstcTreeEdge,
    OrmstcWithdrawal,
    SonarRays,
)
from bus.messages.plan import PlanShare
from bus.messages.progress import AgentState, LookStep, Progress, ReplanReport, ReplanShare
from bus.messages.tree import RadioStats, TreeReport
from bus.messages.world import BumpEvent, CoverEvent, GroundTruthPose, RobotTruth, WorldState

# The wire generation a process speaks. A kind whose fields change gets ``since`` = the new
# generation; payloads of older generations stay readable for every kind that has not changed
# since (docs/protocol.md, "Versioning rule"), so one kind's change does not make old
# recordings of the others unreadable.
# 2: WorldState.first/.crossed; AgentState in bus/ with tree/claims; 3: TreeReport.gone/.dead;
# 4: RobotStatus.roster; 5: Heartbeat.said/.heard; 7: AdminCommand.after_covered
SCHEMA_VERSION = 7


class QosClass(enum.Enum):
    """How a kind is delivered; bus.qos maps each class to Zenoh's priority, congestion
    control and express flag."""

    HEARTBEAT = "heartbeat"  # a priority of its own: bursts must not delay beats
    CRITICAL = "critical"  # small and must not be lost to a full queue
    CONTROL = "control"  # request / reply with a process that acts on it
    STREAM = "stream"  # the newest value supersedes the old: drop under congestion
    BULK = "bulk"  # large and rare


ROBOT, INCARNATION = "{robot}", "{incarnation}"
_ID_CHUNKS = (ROBOT, INCARNATION)

# Who may write: OWN is the robot whose id is the key's {robot} chunk, ROBOTS any robot,
# the others name a role (bus.security.roles). Reading is open to every authenticated role.
Audience = Literal["own", "robots", "simhw", "operator", "everyone"]
OWN: Audience = "own"
ROBOTS: Audience = "robots"
SIMHW: Audience = "simhw"
OPERATOR: Audience = "operator"
EVERYONE: Audience = "everyone"


@dataclass(frozen=True)
class Access:
    """Who may put samples on a family's keys, serve it as a queryable (declare it and
    reply), query it, and declare liveliness tokens on it; nobody else may."""

    put: tuple[Audience, ...] = ()
    serve: tuple[Audience, ...] = ()
    ask: tuple[Audience, ...] = ()
    token: tuple[Audience, ...] = ()


NOBODY = Access()
BY_OWN = Access(put=(OWN,))
BY_SIMHW = Access(put=(SIMHW,))
SERVED_BY_ROBOTS = Access(serve=(ROBOTS,), ask=(EVERYONE,))


@dataclass(frozen=True)
class KeyFamily:
    """Keys ``mstc/<mission>/<path>``; ``{robot}`` and ``{incarnation}`` chunks of ``path``
    are non-negative ints. ``label`` is the kind keys.parse reports (drop counters, logs).
    ``robot_field``: the field of a kind listed on this family that must equal the key's
    ``{robot}`` (None where the key names a receiver that no field names).
    ``cache``: how many samples per key its publishers keep for subscribers that missed
    them (bus.recovery: Zenoh's advanced pub/sub); 0 where a lost sample is superseded by
    the next one or means nothing later (heartbeats, poses, queries)."""

    label: str
    path: str
    access: Access = NOBODY
    robot_field: str | None = "robot"
    cache: int = 0

    @functools.cached_property
    def chunks(self) -> tuple[str, ...]:
        return tuple(self.path.split("/"))


def family(path: str, label: str | None = None, access: Access = NOBODY, *,
           robot_field: str | None = "robot", cache: int = 0) -> KeyFamily:
    """A key family; its label is its path without the id chunks unless given."""
    return KeyFamily(label or "/".join(c for c in path.split("/") if c not in _ID_CHUNKS),
                     path, access, robot_field, cache)


@dataclass(frozen=True)
class Kind:
    """One message kind: ``type`` travels on ``keys`` with ``qos``; its fields last changed
    in wire generation ``since``."""

    type: type[Any]
    keys: tuple[KeyFamily, ...]
    qos: QosClass
    since: int = 1

    @property
    def name(self) -> str:
        kind: str = self.type.KIND
        return kind


C = QosClass
# queryable (simhw): HwCommand -> HwReply; only the robot itself commands its body
HW_CMD = family("hw/{robot}/cmd", access=Access(serve=(SIMHW,), ask=(OWN,)))
# queryable (simhw): AdminCommand -> AdminReply; failure injection is the operator's alone
HW_ADMIN = family("hw/admin", access=Access(serve=(SIMHW,), ask=(OPERATOR,)))

# Publisher cache depths (samples per key) of the recoverable families: enough for a router
# restart or freeze of a few seconds at the fastest move rate measured (time scale 0, ~100
# moves/s per robot); a cut longer than that is marked as a gap in a recording.
STATE_CACHE = 16  # statuses, verdicts, deaths, re-plan reports: a few per life
EVENT_CACHE = 256  # events, bumps, ORMSTC starts, connections, completions
WALK_CACHE = 4096  # one sample per move: cover events, progress, look steps, edges, claims

KINDS: tuple[Kind, ...] = (
    # a robot's life (bus.messages.lifecycle)
    Kind(Heartbeat, (family("hb/{robot}", access=BY_OWN),), C.HEARTBEAT, since=5),
    Kind(RobotStatus, (family("status/{robot}", access=BY_OWN, cache=STATE_CACHE),),
         C.CRITICAL, since=4),
    Kind(RobotEvent, (family("event/{robot}", access=BY_OWN, cache=EVENT_CACHE),), C.CRITICAL),
    # <robot>: the dead one; any robot may declare a death (bus.liveness checks the detector)
    Kind(DeathNotice, (family("death/{robot}", access=Access(put=(ROBOTS,)),
                                cache=STATE_CACHE),), C.CRITICAL),
    # the verdict is the robots'; a tree fleet's launcher announces its set-up on it too
    Kind(MissionStatus, (family("mission", access=Access(put=(ROBOTS, OPERATOR)),
                                cache=STATE_CACHE),
                         family("state/mission", access=SERVED_BY_ROBOTS)), C.CRITICAL),
    # what a robot covered (bus.messages.progress)
    Kind(Progress, (family("progress/{robot}", access=BY_OWN, cache=WALK_CACHE),), C.STREAM),
    # a lost look step would make a report see a coverage revisit
    Kind(LookStep, (family("look/{robot}", access=BY_OWN, cache=WALK_CACHE),), C.CRITICAL),
    # only the reply of the state/<r> queryable, which also answers the robot's kept messages
    Kind(AgentState, (family("state/{robot}", access=Access(serve=(OWN,), ask=(EVERYONE,))),),
         C.STREAM, since=2),
    # a survivor's input to the re-plan after a death: the others wait for it
    Kind(ReplanReport, (family("replan/{robot}", access=BY_OWN, cache=STATE_CACHE),),
         C.CRITICAL, since=6),
    # a crowded fleet's re-plan, computed by one survivor, checked and walked by the others
    Kind(ReplanShare, (family("replanned/{robot}", access=BY_OWN, cache=STATE_CACHE),),
         C.CRITICAL, since=5),
    # a crowded fleet's first plan, computed by its lowest robot, checked and flown by the others
    Kind(PlanShare, (family("planned/{robot}", access=BY_OWN, cache=STATE_CACHE),),
         C.CRITICAL, since=5),
    # the simulated hardware (bus.messages.hardware)
    Kind(HwCommand, (HW_CMD,), C.CONTROL),
    Kind(HwReply, (HW_CMD,), C.CONTROL),
    Kind(AdminCommand, (HW_ADMIN,), C.CONTROL, since=7),
    Kind(AdminReply, (HW_ADMIN,), C.CONTROL),
    # the simulator's ground truth (bus.messages.world)
    Kind(GroundTruthPose, (family("sim/pose/{robot}", access=BY_SIMHW),), C.STREAM),
    Kind(CoverEvent, (family("sim/cover/{robot}", access=BY_SIMHW, cache=WALK_CACHE),),
         C.STREAM),
    Kind(BumpEvent, (family("sim/bump/{robot}", access=BY_SIMHW, cache=EVENT_CACHE),), C.STREAM),
    Kind(WorldState, (family("sim/world", access=Access(serve=(SIMHW,), ask=(EVERYONE,))),),
         C.BULK, since=2),
    # ORMSTC (bus.messages.ormstc): one priority for every ORMSTC kind keeps each sender's
    # messages in order across keys; <robot> is the sender
    Kind(OrmstcTreeEdge, (family("ormstc/tree/{robot}", access=BY_OWN, cache=WALK_CACHE),),
         C.CRITICAL),
    Kind(OrmstcClaim, (family("ormstc/claim/{robot}", access=BY_OWN, cache=WALK_CACHE),),
         C.CRITICAL),
    Kind(OrmstcConnection, (family("ormstc/conn/{robot}", access=BY_OWN, cache=EVENT_CACHE),),
         C.CRITICAL),
    Kind(OrmstcStart, (family("ormstc/start/{robot}", access=BY_OWN, cache=EVENT_CACHE),),
         C.CRITICAL),
    Kind(OrmstcDeadRobot, (family("ormstc/dead/{robot}", access=BY_OWN, cache=EVENT_CACHE),),
         C.CRITICAL),
    Kind(OrmstcCompletion, (family("ormstc/done/{robot}", access=BY_OWN, cache=EVENT_CACHE),),
         C.CRITICAL),
    Kind(OrmstcWithdrawal, (family("ormstc/withdraw/{robot}", access=BY_OWN, cache=EVENT_CACHE),),
         C.CRITICAL),
    # a new kind (no generation bump: docs/protocol.md, "Versioning rule")
    Kind(OrmstcRetraction, (family("ormstc/retract/{robot}", access=BY_OWN, cache=EVENT_CACHE),),
         C.CRITICAL, since=5),
    # what a robot's sonar showed free, for its peers' sensing: outside ormstc/* (not the
    # machine's ordered stream), dropped rather than delaying claims under congestion
    Kind(SonarRays, (family("sonar/{robot}", access=BY_OWN),), C.STREAM, since=5),
    # connected tree coverage (bus.messages.tree): a lost report stalls the whole team's
    # step, so never drop it; the outbox is the robot's, only the radio fills inboxes
    # (an outbox carries relayed reports too: its robot is the sender)
    Kind(TreeReport, (family("tree/robot/{robot}/outbox", "tree/outbox", BY_OWN,
                             robot_field="sender"),
                      family("tree/robot/{robot}/inbox", "tree/inbox", BY_SIMHW,
                             robot_field=None)), C.CRITICAL, since=3),
    # queryable (the radio, which runs with the simulator's role)
    Kind(RadioStats, (family("tree/radio", access=Access(serve=(SIMHW,), ask=(EVERYONE,))),),
         C.CONTROL, since=2),
)

# Families that carry no kind of their own: the incarnation is in the liveliness key because
# tokens aggregate per key (docs/protocol.md, "Keys").
ALIVE = family("alive/{robot}/{incarnation}", access=Access(token=(OWN,)))

# Dataclasses that appear nested inside messages.
RECORDS: tuple[type[Any], ...] = (RobotTruth,)


def _families() -> tuple[KeyFamily, ...]:
    seen: dict[str, KeyFamily] = {}
    for fam in (*(f for kind in KINDS for f in kind.keys), ALIVE):
        if seen.setdefault(fam.label, fam) != fam:
            raise TypeError(f"key label {fam.label!r} names two paths")
        if fam.chunks[0] in _ID_CHUNKS or not all(
                c in _ID_CHUNKS or re.fullmatch(r"[a-z_]+", c) for c in fam.chunks):
            raise TypeError(f"key path {fam.path!r}: literal first chunk, ids {_ID_CHUNKS}")
    families = tuple(seen.values())
    for i, a in enumerate(families):
        for b in families[i + 1:]:
            if not _disjoint(a, b):
                raise TypeError(f"keys of {a.path!r} and {b.path!r} could be the same")
    return families


def _disjoint(a: KeyFamily, b: KeyFamily) -> bool:
    """No concrete key is of both families (ids are digits, literals are not)."""
    return len(a.chunks) != len(b.chunks) or any(
        x != y and not (x in _ID_CHUNKS and y in _ID_CHUNKS) for x, y in zip(
            a.chunks, b.chunks, strict=True))


def _registry() -> dict[str, type[Any]]:
    types: dict[str, type[Any]] = {}
    for kind in KINDS:
        name = kind.type.__dict__.get("KIND")
        if not isinstance(name, str) or not name:
            raise TypeError(f"{kind.type.__name__} needs a non-empty KIND class variable")
        if name in types:
            raise TypeError(f"message kind {name!r} listed twice")
        types[name] = kind.type
        if type(kind.since) is not int or not 1 <= kind.since <= SCHEMA_VERSION:
            raise TypeError(f"{kind.type.__name__}: since must be a generation "
                            f"1..{SCHEMA_VERSION}")
    return types


FAMILIES: tuple[KeyFamily, ...] = _families()
# key label -> publisher cache depth, for the families whose lost samples can be recovered
RECOVERABLE: dict[str, int] = {fam.label: fam.cache for fam in FAMILIES if fam.cache > 0}
MESSAGE_TYPES: dict[str, type[Any]] = _registry()  # KIND -> class
KIND_SINCE: dict[str, int] = {kind.name: kind.since for kind in KINDS}
RECORD_TYPES: frozenset[type[Any]] = frozenset(RECORDS)
# (kind, key label) -> the message field that must equal the key's {robot}: Zenoh's access
# control stops robot 3 from writing on robot 5's keys, this stops it from writing robot 5's
# messages on its own.
ROBOT_NAMED: dict[tuple[str, str], str] = {
    (kind.name, fam.label): fam.robot_field for kind in KINDS for fam in kind.keys
    if ROBOT in fam.chunks and fam.robot_field is not None
    and fam.robot_field in getattr(kind.type, "__dataclass_fields__", {})}


def version_problem(kind: str, version: object) -> str | None:
    """Why a payload of ``kind`` at wire generation ``version`` cannot be read here, or None."""
    if type(version) is not int or not 1 <= version <= SCHEMA_VERSION:
        return f"schema version {version!r}, expected 1..{SCHEMA_VERSION}"
    since = KIND_SINCE.get(kind, 1)
    if version < since:
        return (f"{kind} of schema version {version}: its fields changed in version {since} "
                f"(this mstc speaks {SCHEMA_VERSION})")
    return None
