"""The simulated hardware's API: motion and sensing commands, and the operators' admin calls."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar, Literal

from bus.messages.base import Pose, SummaryValue

HwAction = Literal["forward", "turn_left", "turn_right", "sense", "pose", "stop"]

Sensor = Literal["front", "left", "right"]

HwStatus = Literal["ok", "bumped", "failed", "frozen", "rejected"]


@dataclass(frozen=True)
class HwCommand:
    KIND: ClassVar[str] = "hw_cmd"
    cmd_id: int
    robot: int
    incarnation: int
    action: HwAction
    sensors: tuple[Sensor, ...] = ()


@dataclass(frozen=True)
class HwReply:
    """``odometry`` is (forward_m, turn_rad) since the last reply; sonar in sub-cells."""

    KIND: ClassVar[str] = "hw_reply"
    cmd_id: int
    robot: int
    status: HwStatus
    message: str
    pose: Pose
    odometry: tuple[float, float]
    sonar: dict[str, int | None]
    bumper: bool
    sim_time: float


AdminAction = Literal["fail", "freeze", "unfreeze", "status", "shutdown", "pause", "resume"]


@dataclass(frozen=True)
class AdminCommand:
    """``after_covered`` arms the command for the moment that many sub-cells are covered:
    with "fail" simhw fails the body then, instead of when the command arrives; "pause"
    (which needs it) holds every body from then until a "resume", so that a launcher can
    SIGKILL an agent at that coverage however far behind it hears."""

    KIND: ClassVar[str] = "admin_cmd"
    action: AdminAction
    robot: int | None = None
    after_covered: int | None = None


@dataclass(frozen=True)
class AdminReply:
    KIND: ClassVar[str] = "admin_reply"
    ok: bool
    message: str
    data: dict[str, SummaryValue] = field(default_factory=dict)
