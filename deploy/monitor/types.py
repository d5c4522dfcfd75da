"""Frozen value types of the monitor: what it receives, records and reports as events."""

from __future__ import annotations

import asyncio
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

from bus.messages import DeathNotice
from planner.geometry import SubCell

Via = Literal["sub", "query", "token", "gap"]


@dataclass
class RecorderLink:
    """What a launcher knows of the recorder running beside it in its process: ``subscribed``
    is set once the recorder listens, and ``written`` counts the records it has written by
    key family ("tree/outbox", ...). A launcher whose messages no publisher cache can give
    back starts its robots only once the recorder listens, and keeps the router up until the
    recorder has written as many as the launcher itself heard."""

    subscribed: asyncio.Event = field(default_factory=asyncio.Event)
    written: Counter[str] = field(default_factory=Counter)

EventKind = Literal[
    "joined", "state", "claimed", "conflict_lost", "tree_edge", "tree_edge_retracted", "died",
    "detected_dead",
    "takeover", "takeover_done", "replanned", "section_complete", "completed", "withdrawn", "left",
    "fenced", "stopped", "bump", "mission_complete", "mission_failed", "world",
]


@dataclass(frozen=True)
class Opaque:
    """A message whose kind this process has no bus type for (a newer peer's kind, or a
    test's stand-in): its kind and its fields as decoded by msgpack."""

    kind: str
    fields: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class TokenChange:
    """A liveliness token of ``robot``'s life ``incarnation`` appeared or vanished."""

    robot: int
    incarnation: int
    present: bool

    KIND = "token"


@dataclass(frozen=True)
class Gap:
    """Samples on ``key`` (of the family ``family``) the recorder missed and no publisher's
    cache could give back: ``missed`` of them, after the last one heard at ``since`` (None:
    none heard before) and before ``until`` (recording seconds, as Record.t)."""

    key: str
    family: str
    missed: int
    since: float | None
    until: float

    KIND = "gap"


@dataclass(frozen=True)
class Record:
    """One received message: ``t`` is the receive time in seconds since the recording
    (or the monitor) started; ``msg`` a bus message, an Opaque or a TokenChange."""

    t: float
    key: str
    msg: Any
    via: Via = "sub"

    @property
    def kind(self) -> str:
        if isinstance(self.msg, Opaque):
            return self.msg.kind
        return str(getattr(type(self.msg), "KIND", type(self.msg).__name__))


@dataclass(frozen=True)
class Header:
    """First line of a recording (docs/protocol.md, "Recording schema")."""

    mission: str
    started: float  # Unix time of t = 0
    source: str  # "monitor" or "up"
    wire_version: int


@dataclass(frozen=True)
class LineError:
    """A recording line that could not be read (1-based line number)."""

    line: int
    reason: str

    def __str__(self) -> str:
        return f"line {self.line}: {self.reason}"


@dataclass(frozen=True)
class MonitorEvent:
    """Something worth one line: ``t`` as in Record, ``robot`` the subject (if any)."""

    t: float
    kind: EventKind
    robot: int | None
    text: str


@dataclass(frozen=True)
class Recording:
    """A recording as read: its header, the records that decoded, and the lines that did not."""

    header: Header
    records: tuple[Record, ...]
    errors: tuple[LineError, ...]


@dataclass(frozen=True)
class Death:
    """A robot declared dead: the first notice, when it was heard, and the signs before."""

    notice: DeathNotice
    t: float
    last_heartbeat: float | None
    token_lost: float | None
    detectors: tuple[int | None, ...]


@dataclass(frozen=True)
class Picture:
    """What a monitor shows, minus timing: compared between early and late watchers."""

    covered: frozenset[SubCell]
    visits: frozenset[tuple[SubCell, int]]
    robots: tuple[tuple[int, int, bool, bool, bool], ...]  # id, moves, dead, done, left
    mission: str
    owners: frozenset[tuple[SubCell, int]] = frozenset()  # sub-cell, robot that entered first
    edges: frozenset[tuple[tuple[SubCell, SubCell], int]] = frozenset()  # cell edge, robot
