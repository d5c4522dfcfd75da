"""Every Zenoh key expression of the project, built and parsed from the key families of the
wire schema (bus.messages.schema; the layout is listed in docs/protocol.md, "Keys").

All keys live under ``mstc/<mission>/``. Robots are non-negative integers. No other module
builds key strings: a publisher calls a builder (or :func:`build` with a family's label), a
subscriber that wants "all robots" calls the ``all_*`` function (or :func:`wildcard`), and a
process that needs the robot back out of a received key calls :func:`parse`.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass

from bus.errors import KeyExprError
from bus.messages.schema import FAMILIES, INCARNATION, ROBOT, KeyFamily

ROOT = "mstc"
_MISSION_RE = re.compile(r"^[A-Za-z0-9_.\-]+$")

_BY_LABEL: dict[str, KeyFamily] = {fam.label: fam for fam in FAMILIES}
# parse looks only at the families of a key's length and first chunk
_BY_SHAPE: dict[tuple[int, str], tuple[KeyFamily, ...]] = {}
for _fam in FAMILIES:
    _shape = (len(_fam.chunks), _fam.chunks[0])
    _BY_SHAPE[_shape] = (*_BY_SHAPE.get(_shape, ()), _fam)
_ORMSTC = tuple(fam.chunks[1] for fam in FAMILIES if fam.chunks[0] == "ormstc")


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


def _family(label: str) -> KeyFamily:
    fam = _BY_LABEL.get(label)
    if fam is None:
        raise KeyExprError(f"unknown key family {label!r}")
    return fam


def build(label: str, mission: str, robot: int | None = None,
          incarnation: int | None = None) -> str:
    """The concrete key of family ``label`` (e.g. "hb", "tree/outbox") for these ids; the
    family's ids must all be given, and no others."""
    fam = _family(label)
    base = _base(mission)
    if (robot is not None) != (ROBOT in fam.chunks) \
            or (incarnation is not None) != (INCARNATION in fam.chunks):
        raise KeyExprError(f"key family {label!r} is {fam.path!r}: give exactly its ids")
    path = fam.path.format(robot="" if robot is None else _robot(robot),
                           incarnation="" if incarnation is None else _robot(incarnation))
    return f"{base}/{path}"


def wildcard(label: str, mission: str) -> str:
    """Every key of family ``label`` in ``mission`` (each id chunk a ``*``)."""
    return f"{_base(mission)}/{_family(label).path.format(robot='*', incarnation='*')}"


def of_robot(label: str, mission: str, robot: int | None) -> str:
    """Every key of family ``label`` about ``robot`` (all robots when None; any incarnation)."""
    fam = _family(label)
    chosen = "*" if robot is None or ROBOT not in fam.chunks else _robot(robot)
    return f"{_base(mission)}/{fam.path.format(robot=chosen, incarnation='*')}"


def everything(mission: str) -> str:
    """Every key of one mission (for recorders and monitors)."""
    return f"{_base(mission)}/**"


def heartbeat(mission: str, robot: int) -> str:
    return build("hb", mission, robot)


def all_heartbeats(mission: str) -> str:
    return wildcard("hb", mission)


def status(mission: str, robot: int) -> str:
    return build("status", mission, robot)


def all_statuses(mission: str) -> str:
    return wildcard("status", mission)


def progress(mission: str, robot: int) -> str:
    return build("progress", mission, robot)


def all_progress(mission: str) -> str:
    return wildcard("progress", mission)


def events(mission: str, robot: int) -> str:
    return build("event", mission, robot)


def all_events(mission: str) -> str:
    return wildcard("event", mission)


def look_steps(mission: str, robot: int) -> str:
    return build("look", mission, robot)


def all_look_steps(mission: str) -> str:
    return wildcard("look", mission)


def sonar_rays(mission: str, robot: int) -> str:
    return build("sonar", mission, robot)


def all_sonar_rays(mission: str) -> str:
    return wildcard("sonar", mission)


def death(mission: str, robot: int) -> str:
    """Where death notices *about* ``robot`` are published."""
    return build("death", mission, robot)


def all_deaths(mission: str) -> str:
    return wildcard("death", mission)


def alive(mission: str, robot: int, incarnation: int) -> str:
    """Liveliness token key; the incarnation is in it because tokens aggregate per key."""
    return build("alive", mission, robot, incarnation)


def all_alive(mission: str) -> str:
    return wildcard("alive", mission)


def alive_in_every_mission() -> str:
    """Every robot's liveliness token on a router, whatever its mission (a monitor finding
    the missions that are live)."""
    return f"{ROOT}/*/{_family('alive').path.format(robot='*', incarnation='*')}"


def replan(mission: str, robot: int) -> str:
    """A survivor's ReplanReport (offline agents re-balancing after a death)."""
    return build("replan", mission, robot)


def all_replans(mission: str) -> str:
    return wildcard("replan", mission)


def replan_share(mission: str, robot: int) -> str:
    """The re-plan a crowded fleet's computing survivor shares (ReplanShare)."""
    return build("replanned", mission, robot)


def all_replan_shares(mission: str) -> str:
    return wildcard("replanned", mission)


def plan_share(mission: str, robot: int) -> str:
    """The first plan a crowded offline fleet's lowest robot computes for all (PlanShare)."""
    return build("planned", mission, robot)


def all_plan_shares(mission: str) -> str:
    return wildcard("planned", mission)


def state(mission: str, robot: int) -> str:
    """Queryable answering a robot's current state messages (late joiners, router restart)."""
    return build("state", mission, robot)


def mission_state(mission: str) -> str:
    """Queryable of the mission status holder; matched by :func:`all_states` too."""
    return build("state/mission", mission)


def all_states(mission: str) -> str:
    return wildcard("state", mission)


def ormstc_tree(mission: str, robot: int) -> str:
    return build("ormstc/tree", mission, robot)


def ormstc_claim(mission: str, robot: int) -> str:
    return build("ormstc/claim", mission, robot)


def ormstc_conn(mission: str, robot: int) -> str:
    return build("ormstc/conn", mission, robot)


def ormstc_start(mission: str, robot: int) -> str:
    return build("ormstc/start", mission, robot)


def ormstc_dead(mission: str, robot: int) -> str:
    """Where robot ``robot`` says another robot is dead (the dead one is in the payload)."""
    return build("ormstc/dead", mission, robot)


def ormstc_done(mission: str, robot: int) -> str:
    return build("ormstc/done", mission, robot)


def ormstc_withdraw(mission: str, robot: int) -> str:
    return build("ormstc/withdraw", mission, robot)


def ormstc_retract(mission: str, robot: int) -> str:
    return build("ormstc/retract", mission, robot)


def all_ormstc(mission: str, what: str = "*") -> str:
    """ORMSTC keys of all robots: ``what`` is one of the ORMSTC kinds or "*"."""
    if what != "*" and what not in _ORMSTC:
        raise KeyExprError(f"unknown ORMSTC key kind {what!r}")
    return f"{_base(mission)}/ormstc/{what}/*"


def hw_cmd(mission: str, robot: int) -> str:
    return build("hw/cmd", mission, robot)


def all_hw_cmds(mission: str) -> str:
    return wildcard("hw/cmd", mission)


def hw_admin(mission: str) -> str:
    return build("hw/admin", mission)


def sim_pose(mission: str, robot: int) -> str:
    return build("sim/pose", mission, robot)


def all_sim_poses(mission: str) -> str:
    return wildcard("sim/pose", mission)


def sim_cover(mission: str, robot: int) -> str:
    return build("sim/cover", mission, robot)


def all_sim_covers(mission: str) -> str:
    return wildcard("sim/cover", mission)


def sim_bump(mission: str, robot: int) -> str:
    return build("sim/bump", mission, robot)


def all_sim_bumps(mission: str) -> str:
    return wildcard("sim/bump", mission)


def world(mission: str) -> str:
    return build("sim/world", mission)


def mission_status(mission: str) -> str:
    return build("mission", mission)


def tree_outbox(mission: str, robot: int) -> str:
    """What tree-coverage robot ``robot`` transmits; only the radio subscribes to it."""
    return build("tree/outbox", mission, robot)


def all_tree_outboxes(mission: str) -> str:
    return wildcard("tree/outbox", mission)


def tree_inbox(mission: str, robot: int) -> str:
    """What the radio delivers to ``robot`` (transmissions from robots in range)."""
    return build("tree/inbox", mission, robot)


def all_tree_inboxes(mission: str) -> str:
    return wildcard("tree/inbox", mission)


def tree_radio(mission: str) -> str:
    return build("tree/radio", mission)


@dataclass(frozen=True)
class ParsedKey:
    """What a received key says: ``kind`` is its family's label, e.g. "hb", "alive",
    "ormstc/tree", "hw/cmd", "tree/outbox"."""

    mission: str
    kind: str
    robot: int | None = None
    incarnation: int | None = None


def _int(chunk: str) -> int | None:
    return int(chunk) if chunk.isascii() and chunk.isdigit() else None


def _match(fam: KeyFamily, mission: str, rest: list[str]) -> ParsedKey | None:
    ids: dict[str, int] = {}
    for chunk, part in zip(fam.chunks, rest, strict=True):
        if chunk in (ROBOT, INCARNATION):
            value = _int(part)
            if value is None:
                return None
            ids[chunk] = value
        elif chunk != part:
            return None
    return ParsedKey(mission, fam.label, ids.get(ROBOT), ids.get(INCARNATION))


def parse(key: str) -> ParsedKey | None:
    """Parse a concrete key of this project; None if it is not one (foreign or malformed)."""
    return _parse(str(key))


# A mission has few distinct keys and every received message parses its key twice or more
# (drop counters, the monitor's model, the recorder): a cache makes that a lookup.
@functools.lru_cache(maxsize=4096)
def _parse(key: str) -> ParsedKey | None:
    parts = key.split("/")
    if len(parts) < 3 or parts[0] != ROOT or not _MISSION_RE.match(parts[1]):
        return None
    mission, rest = parts[1], parts[2:]
    for fam in _BY_SHAPE.get((len(rest), rest[0]), ()):
        parsed = _match(fam, mission, rest)
        if parsed is not None:
            return parsed
    return None


def kind_of(key: str) -> str:
    """A short label of a key for drop counters and logs ("foreign" when not ours)."""
    parsed = parse(key)
    return "foreign" if parsed is None else parsed.kind
