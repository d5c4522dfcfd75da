"""A robot's life on the wire: its heartbeat, its hello, its events, deaths, the mission."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar, Literal

from bus.messages.base import Pose, SubCell, SummaryValue

RobotStateName = str  # free text such as "starting", "covering", "done", "fenced"

EventKind = Literal[
    "started", "section_complete", "takeover_started", "takeover_finished", "leaving",
    "completed", "completion_withdrawn", "fenced", "stopped", "replanned",
]


@dataclass(frozen=True)
class Heartbeat:
    """A robot's sign of life. ``said`` and ``heard`` serve loss repair of its algorithm's
    numbered messages (ORMSTC, planner.ormstc.streams; 0 and () elsewhere): how many it has
    said this life, and (robot, incarnation, seq) of the last message of each peer it has
    taken in order."""

    KIND: ClassVar[str] = "heartbeat"
    robot: int
    incarnation: int
    seq: int
    pose: Pose | None
    state: str
    sim_time: float
    said: int = 0
    heard: tuple[tuple[int, int, int], ...] = ()


@dataclass(frozen=True)
class RobotStatus:
    """The hello a robot announces at start and re-announces periodically.

    ``roster`` is the participant set this robot proposes (state "gathering") or has agreed
    on (any later state): (robot, start row, start column) of every robot taking part, the
    dead ones whose start was heard included (agent.core.roster)."""

    KIND: ClassVar[str] = "status"
    robot: int
    incarnation: int
    start: SubCell
    algo: str
    plan_digest: str
    state: str
    message: str = ""
    roster: tuple[tuple[int, int, int], ...] = ()


Hello = RobotStatus


@dataclass(frozen=True)
class RobotEvent:
    KIND: ClassVar[str] = "event"
    robot: int
    incarnation: int
    kind: EventKind
    subject: int | None = None
    detail: str = ""


DeathReason = Literal["heartbeat", "token", "leaving"]


@dataclass(frozen=True)
class DeathNotice:
    """``robot``/``incarnation`` is the dead life; ``detected_at`` is the detector's clock."""

    KIND: ClassVar[str] = "death"
    robot: int
    incarnation: int
    detected_by: int | None
    reason: DeathReason
    detected_at: float


MissionState = Literal["running", "complete", "failed"]


@dataclass(frozen=True)
class MissionStatus:
    KIND: ClassVar[str] = "mission"
    state: MissionState
    message: str
    summary: dict[str, SummaryValue] = field(default_factory=dict)
