"""Wire messages: frozen dataclasses, one per kind, registered by their ``KIND`` tag.

Field types are limited to what the codec checks strictly: int, float, str, bool, bytes,
None, Literal[...], tuple[...] (fixed or ``tuple[X, ...]``), dict[str|int, X], unions, and
nested record dataclasses (registered with :func:`record`). Adding a message is a dataclass
with a ``KIND`` class variable decorated with :func:`message`.

Conventions: robots are ints; a pose is (row, col, heading) in sub-cells with heading
0=N 1=E 2=S 3=W; ``sim_time`` is simulated seconds; ``incarnation`` grows each time a
robot's process (re)starts so that stale lives can be fenced.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal, TypeVar

import numpy as np
import numpy.typing as npt

# The wire generation a process speaks. A kind whose fields change gets ``SINCE`` = the new
# generation; payloads of older generations stay readable for every kind that has not changed
# since (docs/protocol.md, "Versioning rule"), so one kind's change does not make old
# recordings of the others unreadable.
# 2: WorldState.first/.crossed; AgentState in bus/ with tree/claims; 3: TreeReport.gone/.dead
SCHEMA_VERSION = 3

Pose = tuple[int, int, int]
SubCell = tuple[int, int]
SummaryValue = int | float | str

M = TypeVar("M")
MESSAGE_TYPES: dict[str, type[Any]] = {}
RECORD_TYPES: set[type[Any]] = set()
KIND_SINCE: dict[str, int] = {}  # kind -> the generation its fields last changed in


def message(cls: type[M]) -> type[M]:
    """Register a message dataclass under its ``KIND`` tag (unique) and its ``SINCE``
    generation (default 1: unchanged since the first)."""
    kind = cls.__dict__.get("KIND")
    if not isinstance(kind, str) or not kind:
        raise TypeError(f"{cls.__name__} needs a non-empty KIND class variable")
    if kind in MESSAGE_TYPES:
        raise TypeError(f"message kind {kind!r} registered twice")
    since = cls.__dict__.get("SINCE", 1)
    if type(since) is not int or not 1 <= since <= SCHEMA_VERSION:
        raise TypeError(f"{cls.__name__}.SINCE must be a generation 1..{SCHEMA_VERSION}")
    MESSAGE_TYPES[kind] = cls
    KIND_SINCE[kind] = since
    return cls


def version_problem(kind: str, version: object) -> str | None:
    """Why a payload of ``kind`` at wire generation ``version`` cannot be read here, or None."""
    if type(version) is not int or not 1 <= version <= SCHEMA_VERSION:
        return f"schema version {version!r}, expected 1..{SCHEMA_VERSION}"
    since = KIND_SINCE.get(kind, 1)
    if version < since:
        return (f"{kind} of schema version {version}: its fields changed in version {since} "
                f"(this mstc speaks {SCHEMA_VERSION})")
    return None


def record(cls: type[M]) -> type[M]:
    """Register a dataclass that may appear nested inside messages."""
    RECORD_TYPES.add(cls)
    return cls


# --- robots -------------------------------------------------------------------------------

RobotStateName = str  # free text such as "starting", "covering", "done", "fenced"

EventKind = Literal[
    "started", "section_complete", "takeover_started", "takeover_finished", "leaving",
    "completed", "completion_withdrawn", "fenced", "stopped",
]


@message
@dataclass(frozen=True)
class Heartbeat:
    KIND: ClassVar[str] = "heartbeat"
    robot: int
    incarnation: int
    seq: int
    pose: Pose | None
    state: str
    sim_time: float


@message
@dataclass(frozen=True)
class RobotStatus:
    """The hello a robot announces at start and re-announces periodically."""

    KIND: ClassVar[str] = "status"
    robot: int
    incarnation: int
    start: SubCell
    algo: str
    plan_digest: str
    state: str
    message: str = ""


Hello = RobotStatus


@message
@dataclass(frozen=True)
class Progress:
    KIND: ClassVar[str] = "progress"
    robot: int
    incarnation: int
    seq: int
    cell: SubCell
    sim_time: float


@message
@dataclass(frozen=True)
class LookStep:
    """An ORMSTC robot stepped into ``cell`` (a sub-cell of its own cell) only to sense: the
    ``seq``-th step aside or back of a look from beside (docs/ormstc.md, sensing), so that a
    report can tell these entries from coverage revisits."""

    KIND: ClassVar[str] = "look_step"
    robot: int
    incarnation: int
    seq: int
    cell: SubCell


@message
@dataclass(frozen=True)
class RobotEvent:
    KIND: ClassVar[str] = "event"
    robot: int
    incarnation: int
    kind: EventKind
    subject: int | None = None
    detail: str = ""


DeathReason = Literal["heartbeat", "token", "leaving"]


@message
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


@message
@dataclass(frozen=True)
class MissionStatus:
    KIND: ClassVar[str] = "mission"
    state: MissionState
    message: str
    summary: dict[str, SummaryValue] = field(default_factory=dict)


# --- simulated hardware API ----------------------------------------------------------------

HwAction = Literal["forward", "turn_left", "turn_right", "sense", "pose", "stop"]
Sensor = Literal["front", "left", "right"]
HwStatus = Literal["ok", "bumped", "failed", "frozen", "rejected"]


@message
@dataclass(frozen=True)
class HwCommand:
    KIND: ClassVar[str] = "hw_cmd"
    cmd_id: int
    robot: int
    incarnation: int
    action: HwAction
    sensors: tuple[Sensor, ...] = ()


@message
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


AdminAction = Literal["fail", "freeze", "unfreeze", "status", "shutdown"]


@message
@dataclass(frozen=True)
class AdminCommand:
    KIND: ClassVar[str] = "admin_cmd"
    action: AdminAction
    robot: int | None = None


@message
@dataclass(frozen=True)
class AdminReply:
    KIND: ClassVar[str] = "admin_reply"
    ok: bool
    message: str
    data: dict[str, SummaryValue] = field(default_factory=dict)


# --- simulator ground truth (sim-only keys) ------------------------------------------------

@message
@dataclass(frozen=True)
class GroundTruthPose:
    KIND: ClassVar[str] = "gt_pose"
    robot: int
    pose: Pose
    sim_time: float


@message
@dataclass(frozen=True)
class CoverEvent:
    """``visits`` is how many times ``cell`` (a sub-cell) has been covered, this one included."""

    KIND: ClassVar[str] = "cover"
    robot: int
    cell: SubCell
    sim_time: float
    visits: int


@message
@dataclass(frozen=True)
class BumpEvent:
    """``at`` is where the body stood, ``into`` the sub-cell it tried to enter."""

    KIND: ClassVar[str] = "bump"
    robot: int
    at: SubCell
    into: SubCell
    sim_time: float


@record
@dataclass(frozen=True)
class RobotTruth:
    robot: int
    pose: Pose
    alive: bool
    frozen: bool
    failed: bool
    covered: int


NO_ROBOT = 255  # "nobody" in the packed per-sub-cell and per-edge robot arrays


@message
@dataclass(frozen=True)
class WorldState:
    """The whole world for a monitor. ``free`` is numpy.packbits of the row-major free mask;
    ``visits`` is zlib-compressed uint8 visit counts (saturating at 255), row-major;
    ``first`` the same for the robot that entered each sub-cell first (255: nobody);
    ``crossed`` the same for the first robot to cross each border between 2 x 2 cells:
    the ``right`` then the ``down`` array over cells (planner.types.SpanningTree's layout)."""

    KIND: ClassVar[str] = "world"
    SINCE: ClassVar[int] = 2
    map_name: str
    shape: tuple[int, int]
    free: bytes
    visits: bytes
    robots: tuple[RobotTruth, ...]
    sim_time: float
    time_scale: float
    first: bytes
    crossed: bytes


RobotArray = npt.NDArray[np.uint8]


def make_world_state(
    map_name: str, free: npt.NDArray[np.bool_], visits: npt.NDArray[np.integer[Any]],
    robots: tuple[RobotTruth, ...], sim_time: float, time_scale: float, *,
    first: RobotArray | None = None, crossed: tuple[RobotArray, RobotArray] | None = None,
) -> WorldState:
    """Pack a free mask, visit counts and first visitors (same 2-D shape; robot ids < 255)
    and the first crossers of cell borders into a WorldState; omitted arrays mean nobody."""
    if free.shape != visits.shape or free.ndim != 2:
        raise ValueError("free and visits must be 2-D arrays of the same shape")
    h, w = free.shape
    firsts = np.full(free.shape, NO_ROBOT, np.uint8) if first is None else first
    right, down = crossed if crossed is not None else (
        np.full((h // 2, max(w // 2 - 1, 0)), NO_ROBOT, np.uint8),
        np.full((max(h // 2 - 1, 0), w // 2), NO_ROBOT, np.uint8))
    if firsts.shape != free.shape or right.shape != (h // 2, max(w // 2 - 1, 0)) \
            or down.shape != (max(h // 2 - 1, 0), w // 2):
        raise ValueError("first must have the map's shape, crossed the cells' border shapes")
    counts = np.clip(visits, 0, 255).astype(np.uint8)
    return WorldState(
        map_name=map_name, shape=(int(h), int(w)),
        free=np.packbits(free.astype(bool), axis=None).tobytes(),
        visits=zlib.compress(counts.tobytes()), robots=robots,
        sim_time=float(sim_time), time_scale=float(time_scale),
        first=zlib.compress(firsts.astype(np.uint8).tobytes()),
        crossed=zlib.compress(right.astype(np.uint8).tobytes()
                              + down.astype(np.uint8).tobytes()))


def world_free(state: WorldState) -> npt.NDArray[np.bool_]:
    """The free mask of a WorldState as a bool array of ``state.shape``."""
    count = state.shape[0] * state.shape[1]
    bits = np.unpackbits(np.frombuffer(state.free, dtype=np.uint8), count=count)
    return bits.astype(bool).reshape(state.shape)


def world_visits(state: WorldState) -> npt.NDArray[np.uint8]:
    """The visit counts of a WorldState as a uint8 array of ``state.shape``."""
    return _unzip(state.visits, state.shape[0] * state.shape[1]).reshape(state.shape)


def world_first(state: WorldState) -> RobotArray:
    """Who entered each sub-cell first (NO_ROBOT: nobody yet), an array of ``state.shape``."""
    return _unzip(state.first, state.shape[0] * state.shape[1]).reshape(state.shape)


def world_crossed(state: WorldState) -> tuple[RobotArray, RobotArray]:
    """The first crossers of cell borders as (right, down) arrays (NO_ROBOT: nobody)."""
    h, w = state.shape[0] // 2, state.shape[1] // 2
    n_right, n_down = h * max(w - 1, 0), max(h - 1, 0) * w
    raw = _unzip(state.crossed, n_right + n_down)
    return (raw[:n_right].reshape(h, max(w - 1, 0)), raw[n_right:].reshape(max(h - 1, 0), w))


def _unzip(data: bytes, size: int) -> npt.NDArray[np.uint8]:
    """ValueError (not a zlib error) for a payload that does not unpack to ``size`` bytes."""
    try:
        raw = np.frombuffer(zlib.decompress(data), dtype=np.uint8)
    except zlib.error as error:
        raise ValueError(f"packed array does not decompress: {error}") from error
    if raw.size != size:
        raise ValueError(f"packed array has {raw.size} bytes, expected {size}")
    return raw


# --- agents' state replies ----------------------------------------------------------------

@message
@dataclass(frozen=True)
class AgentState:
    """An agent's re-learnable knowledge, the reply of its ``state/<r>`` queryable (never
    published): its phase, its moves, every cycle index it knows covered (``pack_covered``:
    bits in cycle-index order; offline algorithms), the robots it knows dead, the robots it
    took over, its drop counters ("kind.reason" -> count), for ORMSTC its tree edges
    (parent, child) and its claims not settled yet (cells of 2 x 2 sub-cells), and for
    offline algorithms the plan's tree kind and seed (so a monitor can rebuild the tree)."""

    KIND: ClassVar[str] = "agent_state"
    SINCE: ClassVar[int] = 2
    robot: int
    incarnation: int
    state: str
    moves: int
    n: int
    covered: bytes
    dead: tuple[int, ...]
    took_over: tuple[int, ...]
    drops: dict[str, int] = field(default_factory=dict)
    tree: tuple[tuple[tuple[int, int], tuple[int, int]], ...] = ()
    claims: tuple[tuple[int, int], ...] = ()
    tree_kind: str = ""
    seed: int = 0


def pack_covered(covered: npt.NDArray[np.bool_]) -> bytes:
    """Bits, then zlib: coverage is long runs, so even a 10^6-sub-cell map fits a message."""
    return zlib.compress(np.packbits(covered.astype(bool)).tobytes())


def unpack_covered(data: bytes, n: int) -> npt.NDArray[np.bool_]:
    """The bool array of ``n`` packed by pack_covered; ValueError if ``data`` is not one."""
    try:
        raw = np.frombuffer(zlib.decompress(data), dtype=np.uint8)
    except zlib.error as error:
        raise ValueError(f"coverage bits do not decompress: {error}") from error
    if raw.size * 8 < n:
        raise ValueError(f"{raw.size} bytes cannot hold {n} bits")
    return np.unpackbits(raw, count=n).astype(bool)


# --- ORMSTC (docs/ormstc.md, "ORMSTC on the wire") ----------------------------------------
# The twins of planner.ormstc's messages. ``incarnation`` is the sender's life and ``seq``
# numbers that life's ORMSTC messages 1, 2, ... over all kinds (gaps are visible). Cells are
# (row, col) of 2 x 2 sub-cell cells; a sub-cell is (row, col) in sub-cells.

Cell = tuple[int, int]


@message
@dataclass(frozen=True)
class OrmstcStart:
    """Alg. 1: robot's start sub-cell; its cell is the robot's from now on."""

    KIND: ClassVar[str] = "ormstc_start"
    robot: int
    incarnation: int
    seq: int
    sub: SubCell


@message
@dataclass(frozen=True)
class OrmstcClaim:
    """Robot wants to grow into ``cell``; ``covered`` = cells it owns (FEWEST priority)."""

    KIND: ClassVar[str] = "ormstc_claim"
    robot: int
    incarnation: int
    seq: int
    cell: Cell
    covered: int


@message
@dataclass(frozen=True)
class OrmstcTreeEdge:
    """Robot built the tree edge ``parent`` -> ``child``: ``child`` is its cell."""

    KIND: ClassVar[str] = "ormstc_tree"
    robot: int
    incarnation: int
    seq: int
    parent: Cell
    child: Cell


@message
@dataclass(frozen=True)
class OrmstcConnection:
    """Robot's cell ``mine`` borders ``theirs`` of robot ``peer`` (monitoring only)."""

    KIND: ClassVar[str] = "ormstc_conn"
    robot: int
    incarnation: int
    seq: int
    peer: int
    mine: Cell
    theirs: Cell


@message
@dataclass(frozen=True)
class OrmstcDeadRobot:
    """Robot found robot ``dead`` dead: its cells are free again."""

    KIND: ClassVar[str] = "ormstc_dead"
    robot: int
    incarnation: int
    seq: int
    dead: int


@message
@dataclass(frozen=True)
class OrmstcCompletion:
    """Robot covered every cell it can reach (``cells`` of its own)."""

    KIND: ClassVar[str] = "ormstc_done"
    robot: int
    incarnation: int
    seq: int
    cells: int


@message
@dataclass(frozen=True)
class OrmstcWithdrawal:
    """Robot takes back its completion to cover cells robot ``peer`` no longer holds."""

    KIND: ClassVar[str] = "ormstc_withdraw"
    robot: int
    incarnation: int
    seq: int
    peer: int


OrmstcWire = (OrmstcStart | OrmstcClaim | OrmstcTreeEdge | OrmstcConnection | OrmstcDeadRobot
              | OrmstcCompletion | OrmstcWithdrawal)
ORMSTC_MESSAGES: tuple[type[Any], ...] = (
    OrmstcStart, OrmstcClaim, OrmstcTreeEdge, OrmstcConnection, OrmstcDeadRobot,
    OrmstcCompletion, OrmstcWithdrawal)
