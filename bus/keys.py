"""Every Zenoh key expression of the project, built in one place.

All keys live under ``mstc/<mission>/``. Robots are non-negative integers. No other module
builds key strings: a subscriber that wants "all robots" calls the ``all_*`` function, and
a process that needs the robot back out of a received key calls :func:`parse`.
Layout (``<r>`` robot id, ``<i>`` incarnation)::

    mstc/<m>/hb/<r>                 Heartbeat
    mstc/<m>/status/<r>             RobotStatus (hello, re-announced)
    mstc/<m>/progress/<r>           Progress
    mstc/<m>/event/<r>              RobotEvent
    mstc/<m>/look/<r>               LookStep (ORMSTC: a step made only to sense)
    mstc/<m>/death/<r>              DeathNotice (<r> = the dead robot)
    mstc/<m>/alive/<r>/<i>          liveliness token
    mstc/<m>/state/<r>              queryable: the robot's re-learnable state
    mstc/<m>/ormstc/tree/<r>        ORMSTC tree edges (payload types: ORMSTC work)
    mstc/<m>/ormstc/claim/<r>       ORMSTC cell claims
    mstc/<m>/ormstc/conn/<r>        ORMSTC connections
    mstc/<m>/ormstc/start/<r>       ORMSTC start sub-cell
    mstc/<m>/ormstc/dead/<r>        ORMSTC "robot x is dead, its cells are free"
    mstc/<m>/ormstc/done/<r>        ORMSTC completion
    mstc/<m>/ormstc/withdraw/<r>    ORMSTC withdrawal of a completion
    mstc/<m>/hw/<r>/cmd             queryable (simhw): HwCommand -> HwReply
    mstc/<m>/hw/admin               queryable (simhw): AdminCommand -> AdminReply
    mstc/<m>/sim/pose/<r>           GroundTruthPose (sim only)
    mstc/<m>/sim/cover/<r>          CoverEvent (sim only)
    mstc/<m>/sim/bump/<r>           BumpEvent (sim only)
    mstc/<m>/sim/world              queryable (simhw): WorldState
    mstc/<m>/mission                MissionStatus (also answered on mstc/<m>/state/mission)
    mstc/<m>/tree/robot/<r>/outbox  TreeReport a tree-coverage robot transmits (radio's input)
    mstc/<m>/tree/robot/<r>/inbox   TreeReport the radio lets through to robot <r>
    mstc/<m>/tree/radio             queryable (radio): RadioStats
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from bus.errors import KeyExprError

ROOT = "mstc"
_MISSION_RE = re.compile(r"^[A-Za-z0-9_.\-]+$")

# Robot-scoped kinds whose key is mstc/<m>/<kind>/<robot>.
_PER_ROBOT = ("hb", "status", "progress", "event", "death", "state", "look")
_ORMSTC = ("tree", "claim", "conn", "start", "dead", "done", "withdraw")
_SIM = ("pose", "cover", "bump")


def check_mission(mission: str) -> str:
    """Return ``mission`` if it is one safe key chunk, else raise KeyExprError."""
    if not _MISSION_RE.match(mission):
        raise KeyExprError(
            f"mission name {mission!r} must be letters, digits, '_', '-' or '.' only")
    return mission


def _robot(robot: int) -> str:
    if isinstance(robot, bool) or not isinstance(robot, int) or robot < 0:
        raise KeyExprError(f"robot id must be a non-negative int, got {robot!r}")
    return str(robot)


def _base(mission: str) -> str:
    return f"{ROOT}/{check_mission(mission)}"


def everything(mission: str) -> str:
    """Every key of one mission (for recorders and monitors)."""
    return f"{_base(mission)}/**"


def _per_robot(kind: str, mission: str, robot: int) -> str:
    return f"{_base(mission)}/{kind}/{_robot(robot)}"


def _all(kind: str, mission: str) -> str:
    return f"{_base(mission)}/{kind}/*"


def heartbeat(mission: str, robot: int) -> str:
    return _per_robot("hb", mission, robot)


def all_heartbeats(mission: str) -> str:
    return _all("hb", mission)


def status(mission: str, robot: int) -> str:
    return _per_robot("status", mission, robot)


def all_statuses(mission: str) -> str:
    return _all("status", mission)


def progress(mission: str, robot: int) -> str:
    return _per_robot("progress", mission, robot)


def all_progress(mission: str) -> str:
    return _all("progress", mission)


def events(mission: str, robot: int) -> str:
    return _per_robot("event", mission, robot)


def all_events(mission: str) -> str:
    return _all("event", mission)


def look_steps(mission: str, robot: int) -> str:
    return _per_robot("look", mission, robot)


def all_look_steps(mission: str) -> str:
    return _all("look", mission)


def death(mission: str, robot: int) -> str:
    """Where death notices *about* ``robot`` are published."""
    return _per_robot("death", mission, robot)


def all_deaths(mission: str) -> str:
    return _all("death", mission)


def alive(mission: str, robot: int, incarnation: int) -> str:
    """Liveliness token key; the incarnation is in it because tokens aggregate per key."""
    return f"{_per_robot('alive', mission, robot)}/{_robot(incarnation)}"


def all_alive(mission: str) -> str:
    return f"{_base(mission)}/alive/*/*"


def state(mission: str, robot: int) -> str:
    """Queryable answering a robot's current state messages (late joiners, router restart)."""
    return _per_robot("state", mission, robot)


def mission_state(mission: str) -> str:
    """Queryable of the mission status holder; matched by :func:`all_states` too."""
    return f"{_base(mission)}/state/mission"


def all_states(mission: str) -> str:
    return _all("state", mission)


def ormstc_tree(mission: str, robot: int) -> str:
    return f"{_base(mission)}/ormstc/tree/{_robot(robot)}"


def ormstc_claim(mission: str, robot: int) -> str:
    return f"{_base(mission)}/ormstc/claim/{_robot(robot)}"


def ormstc_conn(mission: str, robot: int) -> str:
    return f"{_base(mission)}/ormstc/conn/{_robot(robot)}"


def ormstc_start(mission: str, robot: int) -> str:
    return f"{_base(mission)}/ormstc/start/{_robot(robot)}"


def ormstc_dead(mission: str, robot: int) -> str:
    """Where robot ``robot`` says another robot is dead (the dead one is in the payload)."""
    return f"{_base(mission)}/ormstc/dead/{_robot(robot)}"


def ormstc_done(mission: str, robot: int) -> str:
    return f"{_base(mission)}/ormstc/done/{_robot(robot)}"


def ormstc_withdraw(mission: str, robot: int) -> str:
    return f"{_base(mission)}/ormstc/withdraw/{_robot(robot)}"


def all_ormstc(mission: str, what: str = "*") -> str:
    """ORMSTC keys of all robots: ``what`` is one of the ORMSTC kinds or "*"."""
    if what != "*" and what not in _ORMSTC:
        raise KeyExprError(f"unknown ORMSTC key kind {what!r}")
    return f"{_base(mission)}/ormstc/{what}/*"


def hw_cmd(mission: str, robot: int) -> str:
    return f"{_base(mission)}/hw/{_robot(robot)}/cmd"


def all_hw_cmds(mission: str) -> str:
    return f"{_base(mission)}/hw/*/cmd"


def hw_admin(mission: str) -> str:
    return f"{_base(mission)}/hw/admin"


def sim_pose(mission: str, robot: int) -> str:
    return f"{_base(mission)}/sim/pose/{_robot(robot)}"


def all_sim_poses(mission: str) -> str:
    return f"{_base(mission)}/sim/pose/*"


def sim_cover(mission: str, robot: int) -> str:
    return f"{_base(mission)}/sim/cover/{_robot(robot)}"


def all_sim_covers(mission: str) -> str:
    return f"{_base(mission)}/sim/cover/*"


def sim_bump(mission: str, robot: int) -> str:
    return f"{_base(mission)}/sim/bump/{_robot(robot)}"


def all_sim_bumps(mission: str) -> str:
    return f"{_base(mission)}/sim/bump/*"


def world(mission: str) -> str:
    return f"{_base(mission)}/sim/world"


def mission_status(mission: str) -> str:
    return f"{_base(mission)}/mission"


def tree_outbox(mission: str, robot: int) -> str:
    """What tree-coverage robot ``robot`` transmits; only the radio subscribes to it."""
    return f"{_base(mission)}/tree/robot/{_robot(robot)}/outbox"


def all_tree_outboxes(mission: str) -> str:
    return f"{_base(mission)}/tree/robot/*/outbox"


def tree_inbox(mission: str, robot: int) -> str:
    """What the radio delivers to ``robot`` (transmissions from robots in range)."""
    return f"{_base(mission)}/tree/robot/{_robot(robot)}/inbox"


def all_tree_inboxes(mission: str) -> str:
    return f"{_base(mission)}/tree/robot/*/inbox"


def tree_radio(mission: str) -> str:
    return f"{_base(mission)}/tree/radio"


@dataclass(frozen=True)
class ParsedKey:
    """What a received key says: ``kind`` is e.g. "hb", "alive", "ormstc/tree", "hw/cmd"."""

    mission: str
    kind: str
    robot: int | None = None
    incarnation: int | None = None


def _int(chunk: str) -> int | None:
    return int(chunk) if chunk.isascii() and chunk.isdigit() else None


def parse(key: str) -> ParsedKey | None:
    """Parse a concrete key of this project; None if it is not one (foreign or malformed)."""
    parts = str(key).split("/")
    if len(parts) < 3 or parts[0] != ROOT or not _MISSION_RE.match(parts[1]):
        return None
    mission, rest = parts[1], parts[2:]
    head = rest[0]
    if len(rest) == 2 and head in _PER_ROBOT:
        if head == "state" and rest[1] == "mission":
            return ParsedKey(mission, "state/mission")
        robot = _int(rest[1])
        return None if robot is None else ParsedKey(mission, head, robot)
    if len(rest) == 3 and head == "alive":
        robot, inc = _int(rest[1]), _int(rest[2])
        if robot is None or inc is None:
            return None
        return ParsedKey(mission, "alive", robot, inc)
    if len(rest) == 3 and head in ("ormstc", "sim") and rest[1] in _ORMSTC + _SIM:
        robot = _int(rest[2])
        return None if robot is None else ParsedKey(mission, f"{head}/{rest[1]}", robot)
    if rest == ["hw", "admin"]:
        return ParsedKey(mission, "hw/admin")
    if len(rest) == 3 and head == "hw" and rest[2] == "cmd":
        robot = _int(rest[1])
        return None if robot is None else ParsedKey(mission, "hw/cmd", robot)
    if len(rest) == 4 and rest[:2] == ["tree", "robot"] and rest[3] in ("outbox", "inbox"):
        robot = _int(rest[2])
        return None if robot is None else ParsedKey(mission, f"tree/{rest[3]}", robot)
    if rest in (["sim", "world"], ["mission"], ["tree", "radio"]):
        return ParsedKey(mission, "/".join(rest))
    return None


def kind_of(key: str) -> str:
    """A short label of a key for drop counters and logs ("foreign" when not ours)."""
    parsed = parse(key)
    return "foreign" if parsed is None else parsed.kind
