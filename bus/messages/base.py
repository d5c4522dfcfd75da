"""What every message module shares: the registry of kinds and the wire's plain aliases.

Field types are limited to what the codec checks strictly: int, float, str, bool, bytes,
None, Literal[...], tuple[...] (fixed or ``tuple[X, ...]``), dict[str|int, X], unions, and
nested record dataclasses (registered with :func:`record`). Adding a message is a dataclass
with a ``KIND`` class variable decorated with :func:`message`.

Conventions: robots are ints; a pose is (row, col, heading) in sub-cells with heading
0=N 1=E 2=S 3=W; ``sim_time`` is simulated seconds; ``incarnation`` grows each time a
robot's process (re)starts so that stale lives can be fenced.
"""

from __future__ import annotations

from typing import Any, TypeVar

# The wire generation a process speaks. A kind whose fields change gets ``SINCE`` = the new
# generation; payloads of older generations stay readable for every kind that has not changed
# since (docs/protocol.md, "Versioning rule"), so one kind's change does not make old
# recordings of the others unreadable.
# 2: WorldState.first/.crossed; AgentState in bus/ with tree/claims; 3: TreeReport.gone/.dead
SCHEMA_VERSION = 3

Pose = tuple[int, int, int]
SubCell = tuple[int, int]
Cell = tuple[int, int]  # (row, col) of a 2 x 2 sub-cell cell
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
