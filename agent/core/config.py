"""Value types of the agent: its configuration. The state message it answers queries with,
``AgentState`` (and ``pack_covered``/``unpack_covered``), lives in bus.messages so that
monitors decode it without importing agent code; it is re-exported here for old imports.
"""

from __future__ import annotations

from dataclasses import dataclass

from bus.messages import AgentState, pack_covered, unpack_covered

__all__ = ["AgentConfig", "AgentState", "pack_covered", "unpack_covered"]

DEFAULT_START_TIMEOUT = 30.0
DEFAULT_ANNOUNCE_PERIOD = 0.5
DEFAULT_HW_TIMEOUT = 60.0
DEFAULT_LINGER = 1.0


@dataclass(frozen=True)
class AgentConfig:
    """Everything an agent process is told on its command line (connection aside)."""

    robot: int
    k: int
    algo: str
    world: str
    cell_size: int | None = None
    tree: str = "dfs"
    seed: int = 0
    incarnation: int = 1
    start_timeout: float = DEFAULT_START_TIMEOUT
    heartbeat_period: float = 0.2
    dead_after: float = 3.0
    announce_period: float = DEFAULT_ANNOUNCE_PERIOD
    hw_timeout: float = DEFAULT_HW_TIMEOUT
    linger: float = DEFAULT_LINGER
