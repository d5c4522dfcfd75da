"""The wire schema: one row per message kind, from which the rest of bus/ is derived.

A row (:class:`Kind`) names the message class (its ``KIND`` tag is the ``_kind`` on the
wire), the key families it travels on, its QoS class and the wire generation its fields last
changed in. ``bus.keys`` builds and parses every key from the families, ``bus.qos`` gives each
QoS class its Zenoh settings, ``bus.codec`` knows exactly the kinds and records listed here.
Adding a message type is a frozen dataclass in its subject's module and one row in
:data:`KINDS` (docs/protocol.md, "Adding a message type").

Field types are limited to what the codec checks strictly: int, float, str, bool, bytes,
None, Literal[...], tuple[...] (fixed or ``tuple[X, ...]``), dict[str|int, X], unions, and
nested record dataclasses (listed in :data:`RECORDS`).
"""

from __future__ import annotations

import enum
import functools
import re
from dataclasses import dataclass
from typing import Any

from bus.messages.hardware import AdminCommand, AdminReply, HwCommand, HwReply
from bus.messages.lifecycle import DeathNotice, Heartbeat, MissionStatus, RobotEvent, RobotStatus
from bus.messages.ormstc import (
    OrmstcClaim,
    OrmstcCompletion,
    OrmstcConnection,
    OrmstcDeadRobot,
    OrmstcStart,
    OrmstcTreeEdge,
    OrmstcWithdrawal,
)
from bus.messages.progress import AgentState, LookStep, Progress
from bus.messages.tree import RadioStats, TreeReport
from bus.messages.world import BumpEvent, CoverEvent, GroundTruthPose, RobotTruth, WorldState

# The wire generation a process speaks. A kind whose fields change gets ``since`` = the new
# generation; payloads of older generations stay readable for every kind that has not changed
# since (docs/protocol.md, "Versioning rule"), so one kind's change does not make old
# recordings of the others unreadable.
# 2: WorldState.first/.crossed; AgentState in bus/ with tree/claims; 3: TreeReport.gone/.dead;
# 4: RobotStatus.roster
SCHEMA_VERSION = 4


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


@dataclass(frozen=True)
class KeyFamily:
    """Keys ``mstc/<mission>/<path>``; ``{robot}`` and ``{incarnation}`` chunks of ``path``
    are non-negative ints. ``label`` is the kind keys.parse reports (drop counters, logs)."""

    label: str
    path: str

    @functools.cached_property
    def chunks(self) -> tuple[str, ...]:
        return tuple(self.path.split("/"))


def family(path: str, label: str | None = None) -> KeyFamily:
    """A key family; its label is its path without the id chunks unless given."""
    return KeyFamily(label or "/".join(c for c in path.split("/") if c not in _ID_CHUNKS),
                     path)


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
HW_CMD = family("hw/{robot}/cmd")  # queryable (simhw): HwCommand -> HwReply
HW_ADMIN = family("hw/admin")  # queryable (simhw): AdminCommand -> AdminReply

KINDS: tuple[Kind, ...] = (
    # a robot's life (bus.messages.lifecycle)
    Kind(Heartbeat, (family("hb/{robot}"),), C.HEARTBEAT),
    Kind(RobotStatus, (family("status/{robot}"),), C.CRITICAL, since=4),
    Kind(RobotEvent, (family("event/{robot}"),), C.CRITICAL),
    Kind(DeathNotice, (family("death/{robot}"),), C.CRITICAL),  # <robot>: the dead one
    Kind(MissionStatus, (family("mission"), family("state/mission")), C.CRITICAL),
    # what a robot covered (bus.messages.progress)
    Kind(Progress, (family("progress/{robot}"),), C.STREAM),
    # a lost look step would make a report see a coverage revisit
    Kind(LookStep, (family("look/{robot}"),), C.CRITICAL),
    # only the reply of the state/<r> queryable, which also answers the robot's kept messages
    Kind(AgentState, (family("state/{robot}"),), C.STREAM, since=2),
    # the simulated hardware (bus.messages.hardware)
    Kind(HwCommand, (HW_CMD,), C.CONTROL),
    Kind(HwReply, (HW_CMD,), C.CONTROL),
    Kind(AdminCommand, (HW_ADMIN,), C.CONTROL),
    Kind(AdminReply, (HW_ADMIN,), C.CONTROL),
    # the simulator's ground truth (bus.messages.world)
    Kind(GroundTruthPose, (family("sim/pose/{robot}"),), C.STREAM),
    Kind(CoverEvent, (family("sim/cover/{robot}"),), C.STREAM),
    Kind(BumpEvent, (family("sim/bump/{robot}"),), C.STREAM),
    Kind(WorldState, (family("sim/world"),), C.BULK, since=2),  # queryable (simhw)
    # ORMSTC (bus.messages.ormstc): one priority for every ORMSTC kind keeps each sender's
    # messages in order across keys; <robot> is the sender
    Kind(OrmstcTreeEdge, (family("ormstc/tree/{robot}"),), C.CRITICAL),
    Kind(OrmstcClaim, (family("ormstc/claim/{robot}"),), C.CRITICAL),
    Kind(OrmstcConnection, (family("ormstc/conn/{robot}"),), C.CRITICAL),
    Kind(OrmstcStart, (family("ormstc/start/{robot}"),), C.CRITICAL),
    Kind(OrmstcDeadRobot, (family("ormstc/dead/{robot}"),), C.CRITICAL),
    Kind(OrmstcCompletion, (family("ormstc/done/{robot}"),), C.CRITICAL),
    Kind(OrmstcWithdrawal, (family("ormstc/withdraw/{robot}"),), C.CRITICAL),
    # connected tree coverage (bus.messages.tree): a lost report stalls the whole team's
    # step, so never drop it; the outbox is the robot's, only the radio fills inboxes
    Kind(TreeReport, (family("tree/robot/{robot}/outbox", "tree/outbox"),
                      family("tree/robot/{robot}/inbox", "tree/inbox")), C.CRITICAL, since=3),
    Kind(RadioStats, (family("tree/radio"),), C.CONTROL, since=2),  # queryable (radio)
)

# Families that carry no kind of their own: the incarnation is in the liveliness key because
# tokens aggregate per key (docs/protocol.md, "Keys").
ALIVE = family("alive/{robot}/{incarnation}")

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
MESSAGE_TYPES: dict[str, type[Any]] = _registry()  # KIND -> class
KIND_SINCE: dict[str, int] = {kind.name: kind.since for kind in KINDS}
RECORD_TYPES: frozenset[type[Any]] = frozenset(RECORDS)


def version_problem(kind: str, version: object) -> str | None:
    """Why a payload of ``kind`` at wire generation ``version`` cannot be read here, or None."""
    if type(version) is not int or not 1 <= version <= SCHEMA_VERSION:
        return f"schema version {version!r}, expected 1..{SCHEMA_VERSION}"
    since = KIND_SINCE.get(kind, 1)
    if version < since:
        return (f"{kind} of schema version {version}: its fields changed in version {since} "
                f"(this mstc speaks {SCHEMA_VERSION})")
    return None
