"""Options of ``mstc agent --algo ormstc`` and the machine configuration they make (no Zenoh
here, so option mistakes are reported before the bus is loaded).

Time options are wall-clock seconds: the machine is ticked with the agent's monotonic clock,
because what they wait for (peers' messages and acknowledgements, a body in the way) takes
the network's and the processes' time, not simulated time (and with ``simhw --time-scale 0``
there is no shared simulated clock at all).
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass

from agent.core.config import AgentConfig
from bus.argtypes import non_negative, seconds
from planner.ormstc.types import MachineConfig, Priority, SenseMode

# Claim window (s): how long a claim waits before it may be decided. The agents decide a claim
# only once every live peer has acknowledged it (MachineConfig.await_acks), which is safe
# whatever the delays (docs/ormstc.md, "Claims under message loss"), and a peer acknowledges a
# claim at once (an early heartbeat), so 0 is safe too and a claim then costs a round trip.
# The window stays because it evens out the robots' pace: with 0, at simhw time scale 0 a
# robot's speed is its share of the CPU, and the split of cells drifted from the lockstep
# model's (bench_ormstc_fleet.py: mean ratio 0.98 -> 1.03-1.08 over the builtin worlds;
# 1.01 -> 1.05 at mstc up's time scale 40: docs/ormstc.md "Claims at the speed of a round
# trip"). 0.25 s was chosen as twice the worst one-way delay measured on a loaded host
# (median 1.1-1.5 ms, worst 117-197 ms at load 10-27).
DEFAULT_CLAIM_WAIT = 0.25
DEFAULT_WATCH_INTERVAL = 0.5
CLAIM_RESENDS = 3  # resend rounds a lost claim's winner is given to be heard (claim_ttl)
DEFAULT_BUMP_BACKOFF = 0.05
# simhw's body at time scale 1 takes 1.93 s for a step and 2.07 s for a quarter turn, so a body
# ahead that turns and moves on holds the robot up about 4 s without being stuck
DEFAULT_HOLD_UP = 5.0


@dataclass(frozen=True)
class OrmstcOptions:
    """The machine's parameters (identity, seed and the process's patience: AgentConfig)."""

    claim_wait: float = DEFAULT_CLAIM_WAIT
    sense_mode: SenseMode = SenseMode.ALL
    priority: Priority = Priority.ID
    watch_interval: float = DEFAULT_WATCH_INTERVAL
    bump_backoff: float = DEFAULT_BUMP_BACKOFF
    hold_up: float = DEFAULT_HOLD_UP
    announce_connections: bool = False

    def machine(self, config: AgentConfig, start: tuple[int, int]) -> MachineConfig:
        return MachineConfig(
            robot=config.robot, team=config.k, start=(float(start[0]), float(start[1])),
            claim_wait=self.claim_wait, sense_mode=self.sense_mode, priority=self.priority,
            watch_interval=self.watch_interval, bump_backoff=self.bump_backoff,
            hold_up=self.hold_up, announce_connections=self.announce_connections, seed=config.seed,
            await_acks=True,  # messages can be lost: agent/ormstc/wire.py repairs them
            claim_ttl=claim_ttl(self.claim_wait, config.heartbeat_period))


def rejoin_silence(heartbeat_period: float, dead_after: float) -> float:
    """How long a peer must have been silent before hearing it again means it was cut off, and
    this robot restates its messages (agent.ormstc.wire.Rejoin): max(1 s, 5 heartbeat
    periods), and in a crowded fleet at least a quarter of the heartbeat timeout, which
    ``mstc up`` stretches for the starvation a loaded host inflicts. 30 robots on 2 cores
    (0.2 s heartbeats, 15 s timeout) heard peers again after 1 s silences all the time and
    restated 20-odd messages each time, 36-72 times per robot in 100 s, until claims waited
    behind the flood (docs/ormstc.md, "Router restarts"); messages lost in a shorter silence
    are resent anyway (each heartbeat says what its robot heard)."""
    return max(1.0, 5 * heartbeat_period, dead_after / 4)


def resend_grace(heartbeat_period: float) -> float:
    """How long a message goes unacknowledged before it is sent again (agent.ormstc.driver's
    Resender): acknowledgements ride on heartbeats."""
    return max(0.3, 1.5 * heartbeat_period)


def claim_ttl(claim_wait: float, heartbeat_period: float) -> float:
    """How long a robot that lost a claim waits for the winner's tree edge before deciding the
    cell again. The winner decides only once every live peer acknowledged its claim, and each
    lost message (a claim, an acknowledgement, the edge) costs a resend after
    ``resend_grace``: 40 robots under the chaos campaign's loss (heartbeats every 2.5 s)
    walked back over their own cells to claims whose edges were on the way, with the
    lockstep's 2 claim_wait + 1 (docs/ormstc.md, "Heavier loss"). A winner that dies first
    is taken over at once whatever this is; only a live winner that declines the cell (a
    body found in it) is repaired this much later."""
    return 2 * claim_wait + 1 + CLAIM_RESENDS * resend_grace(heartbeat_period)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options only ``--algo ormstc`` reads (it reads no map: only simhw has one)."""
    group = parser.add_argument_group("ORMSTC (--algo ormstc)")
    group.add_argument("--claim-wait", type=non_negative, default=DEFAULT_CLAIM_WAIT,
                       metavar="SECONDS",
                       help="how long a claim waits before it is decided, besides every live "
                            "peer's acknowledgement, which alone makes it safe; 0 makes a claim "
                            "cost a round trip (default %(default)s)")
    group.add_argument("--sense-mode", choices=[m.value for m in SenseMode],
                       default=SenseMode.ALL.value,
                       help="'single' senses one neighbouring cell per sonar command (use "
                            "with simhw --sonar-mode one-at-a-time; default all)")
    group.add_argument("--priority", choices=[p.value for p in Priority],
                       default=Priority.ID.value,
                       help="who wins a contested cell: highest id, or fewest cells "
                            "(default id)")
    group.add_argument("--watch-interval", type=seconds, default=DEFAULT_WATCH_INTERVAL,
                       metavar="SECONDS",
                       help="after completion, ask about neighbours this often "
                            "(default %(default)s)")
    group.add_argument("--bump-backoff", type=seconds, default=DEFAULT_BUMP_BACKOFF,
                       metavar="SECONDS",
                       help="back off 1-2 x this after a bump (default %(default)s)")
    group.add_argument("--hold-up", type=seconds, default=DEFAULT_HOLD_UP, metavar="SECONDS",
                       help="held up this long by another body, a robot walks round a cell "
                            "it lost or steps aside (default %(default)s)")
    group.add_argument("--announce-connections", action="store_true",
                       help="publish connection edges too (for monitors)")


def from_args(args: argparse.Namespace) -> OrmstcOptions:
    return OrmstcOptions(
        claim_wait=args.claim_wait, sense_mode=SenseMode(args.sense_mode),
        priority=Priority(args.priority), watch_interval=args.watch_interval,
        bump_backoff=args.bump_backoff, hold_up=args.hold_up,
        announce_connections=args.announce_connections)
