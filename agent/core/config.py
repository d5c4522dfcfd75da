"""The one configuration of every agent process, whatever its family, and its one set of
defaults; the options only one family reads live beside its driver (agent/<family>/options.py).

No Zenoh here (nor in the options modules), so option mistakes are reported before the bus
is loaded. Time options are wall-clock seconds of the agent's own monotonic clock.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass

from agent.core.errors import ConfigError
from bus import argtypes
from bus.argtypes import index, non_negative, positive, positive_int
from bus.detector import DEFAULT_HEARTBEAT_PERIOD, DEFAULT_TOKEN_GRACE

DEFAULT_START_TIMEOUT = 30.0
# A robot never heard this long after one's own gather began takes no part (it never booted,
# or died before it could announce its start); a loaded host boots a fleet in a few seconds.
DEFAULT_BOOT_TIMEOUT = 10.0
DEFAULT_DEAD_AFTER = 3.0
# The tree agent re-announced every 1.0 s, the two others every 0.5 s; 0.5 is kept for all:
# the offline and ORMSTC agents also pace their gather and refresh wake-ups with it, while
# the tree agent only re-publishes its status with it (a few small messages more per second).
DEFAULT_ANNOUNCE_PERIOD = 0.5
DEFAULT_HW_TIMEOUT = 60.0
DEFAULT_LINGER = 1.0


@dataclass(frozen=True)
class AgentConfig:
    """What every agent process is told on its command line (connection and the options of
    its family aside)."""

    robot: int
    k: int
    algo: str
    incarnation: int = 1
    seed: int = 0
    start_timeout: float = DEFAULT_START_TIMEOUT
    boot_timeout: float = DEFAULT_BOOT_TIMEOUT
    heartbeat_period: float = DEFAULT_HEARTBEAT_PERIOD
    dead_after: float = DEFAULT_DEAD_AFTER
    token_grace: float = DEFAULT_TOKEN_GRACE
    announce_period: float = DEFAULT_ANNOUNCE_PERIOD
    hw_timeout: float = DEFAULT_HW_TIMEOUT
    linger: float = DEFAULT_LINGER


def add_identity_arguments(parser: argparse.ArgumentParser) -> None:
    """``--id`` and ``--robots``: who this robot is in which fleet."""
    parser.add_argument("--id", type=index, required=True, metavar="I",
                        help="this robot's id, 0..K-1 (its body in simhw)")
    parser.add_argument("--robots", type=positive_int, required=True, metavar="K",
                        help="number of robots in the fleet")


def add_life_arguments(parser: argparse.ArgumentParser) -> None:
    """The options every family reads (``--algo`` and ``--tree`` are the entry's)."""
    parser.add_argument("--incarnation", type=positive_int, default=1, metavar="N",
                        help="this life's number; a restart must use a higher one (default 1)")
    parser.add_argument("--heartbeat-period", type=positive, default=DEFAULT_HEARTBEAT_PERIOD,
                        metavar="SECONDS",
                        help="seconds between heartbeats (default %(default)s)")
    parser.add_argument("--dead-after", type=positive, default=DEFAULT_DEAD_AFTER,
                        metavar="SECONDS",
                        help="a robot silent this long is declared dead (default %(default)s)")
    parser.add_argument("--token-grace", type=positive, default=DEFAULT_TOKEN_GRACE,
                        metavar="SECONDS",
                        help="a peer's vanished liveliness token is confirmed (the peer "
                             "declared dead) after this long (default %(default)s)")
    parser.add_argument("--announce-period", type=positive, default=DEFAULT_ANNOUNCE_PERIOD,
                        metavar="SECONDS",
                        help="re-announce state and re-query peers this often "
                             "(default %(default)s)")


def add_body_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of the families whose robots have a simhw body (offline, ormstc)."""
    group = parser.add_argument_group("robots with a simhw body (offline, ormstc)")
    group.add_argument("--seed", type=argtypes.seed, default=0,
                       help="seed of the family's random choices: the spanning tree "
                            "(offline), the machine's (ormstc); default 0")
    group.add_argument("--start-timeout", type=positive, default=DEFAULT_START_TIMEOUT,
                       metavar="SECONDS",
                       help="how long to wait for simhw, every start and every plan digest "
                            "(default %(default)s)")
    group.add_argument("--boot-timeout", type=positive, default=DEFAULT_BOOT_TIMEOUT,
                       metavar="SECONDS",
                       help="a robot never heard this long into the gather takes no part; "
                            "the others go on without it (default %(default)s)")
    group.add_argument("--hw-timeout", type=positive, default=DEFAULT_HW_TIMEOUT,
                       metavar="SECONDS",
                       help="longest wait for one motion of the body, lost replies and "
                            "re-tries included (default %(default)s)")
    group.add_argument("--linger", type=non_negative, default=DEFAULT_LINGER,
                       metavar="SECONDS",
                       help="stay after completion so peers can still query (default "
                            "%(default)s)")


def config_from_args(args: argparse.Namespace) -> AgentConfig:
    """The AgentConfig of parsed options; ConfigError for an id outside the fleet. A command
    without the body options (``mstc tree-agent``) leaves their defaults."""
    if args.id >= args.robots:
        raise ConfigError(f"--id {args.id} is not below --robots {args.robots}")
    body = vars(args)
    return AgentConfig(
        robot=args.id, k=args.robots, algo=args.algo, incarnation=args.incarnation,
        seed=body.get("seed", 0), start_timeout=body.get("start_timeout", DEFAULT_START_TIMEOUT),
        boot_timeout=body.get("boot_timeout", DEFAULT_BOOT_TIMEOUT),
        heartbeat_period=args.heartbeat_period, dead_after=args.dead_after,
        token_grace=args.token_grace,
        announce_period=args.announce_period,
        hw_timeout=body.get("hw_timeout", DEFAULT_HW_TIMEOUT),
        linger=body.get("linger", DEFAULT_LINGER))
