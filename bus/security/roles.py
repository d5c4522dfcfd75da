"""The roles of a mission's processes; a role's name is its user name on the router and the
common name of its TLS client certificate."""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Literal

from bus.errors import ConfigError

RoleKind = Literal["robot", "simhw", "operator", "observer", "router"]
# simhw: the simulator and the radio; operator: the launcher, kill and down (the only role
# reaching hw/admin); observer: monitor, recorder, report, bridges (read-only); router: a
# router of another host joining the mission's router (`mstc router --connect`). The router
# role's log-in alone grants nothing: routers recognise each other by the router
# certificate (ROUTER_COMMON_NAME, mTLS only), since a router forwards every role's traffic.
SERVICE_KINDS: tuple[RoleKind, ...] = ("simhw", "operator", "observer", "router")
# The common name of the routers' certificate (scripts/make-certs.sh), for listening and for
# joining another router.
ROUTER_COMMON_NAME = "mstc-router"
_ROBOT_RE = re.compile(r"^robot_(0|[1-9][0-9]{0,5})$")


@dataclass(frozen=True)
class Role:
    kind: RoleKind
    robot: int | None = None

    def __post_init__(self) -> None:
        if (self.kind == "robot") != (self.robot is not None):
            raise ConfigError(f"role {self.kind!r}: a robot id goes with the robot role only")
        if self.robot is not None and (type(self.robot) is not int or self.robot < 0):
            raise ConfigError(f"robot id must be a non-negative int, got {self.robot!r}")

    @property
    def name(self) -> str:
        return f"robot_{self.robot}" if self.kind == "robot" else self.kind

    def __str__(self) -> str:
        return self.name

    @property
    def rank(self) -> tuple[int, int]:
        """Robots by id, then the services: the order of listings."""
        if self.robot is not None:
            return (0, self.robot)
        return (1, SERVICE_KINDS.index(self.kind))


def robot(robot_id: int) -> Role:
    return Role("robot", robot_id)


SIMHW = Role("simhw")
OPERATOR = Role("operator")
OBSERVER = Role("observer")
ROUTER = Role("router")


def parse_role(name: str) -> Role:
    """``robot_3``, ``simhw``, ``operator``, ``observer`` or ``router``; ConfigError
    otherwise."""
    match = _ROBOT_RE.match(name)
    if match:
        return robot(int(match.group(1)))
    for kind in SERVICE_KINDS:
        if name == kind:
            return Role(kind)
    raise ConfigError(f"unknown role {name!r}: expected robot_<id>, simhw, operator, observer "
                      "or router")


def mission_roles(robots: int) -> tuple[Role, ...]:
    """Every role of a mission of ``robots`` robots (ids 0..robots-1)."""
    if robots < 1:
        raise ConfigError(f"a mission has at least one robot, got {robots}")
    return (*(robot(i) for i in range(robots)), SIMHW, OPERATOR, OBSERVER, ROUTER)
