"""The timers and start-up pace of a fleet of its size on this many cores (``mstc up``).

Small fleets run with the agents' own defaults; crowded ones (more than
CROWDED_AGENTS_PER_CORE agents per core) get longer leases, heartbeat timeouts and periods,
a paced start and niced agents; so do the lease and heartbeat timeout of a fleet at time
scale 0 with more than FLAT_OUT_AGENTS_PER_CORE agents per core. docs/operations.md,
"Fleet scale" and "Flat out", has the measurements.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

from agent.core.config import (
    DEFAULT_ANNOUNCE_PERIOD,
    DEFAULT_BOOT_TIMEOUT,
    DEFAULT_START_TIMEOUT,
)
from bus.config import DEFAULT_LEASE_MS
from bus.detector import DEFAULT_HEARTBEAT_PERIOD

# Heartbeat timeout handed to the agents. A SIGKILL is seen through the closed link and a hung
# process through its lease (~0.75 s), whatever this is; 1 s heartbeats alone were missed by
# CPU-starved agents on a busy 2-core machine and healthy robots were fenced
# (docs/operations.md, "Detection against false suspicion").
DEFAULT_DEAD_AFTER_S = 3.0
# Beyond this many agents per CPU core, start-up and time-scale-0 missions starve processes
# for over a second: 30 agents on 2 cores lost every robot to lease expiry at a 1 s lease,
# none at 5 s. Crowded fleets get the long lease and heartbeat timeout.
CROWDED_AGENTS_PER_CORE = 6
CROWDED_LEASE_MS = 5000
CROWDED_DEAD_AFTER_S = 5.0
# Crowded fleets (fleet_timing): every agent receives robots / period heartbeats and statuses
# per second, the fleet robots^2 / period. The periods keep these deliveries within a budget
# per core (30 robots on 2 cores keep the agents' own 0.2 s and 0.5 s), the heartbeat timeout
# HEARTBEATS_PER_TIMEOUT periods; at most BOOTING_PER_CORE agents per core start at a time;
# BOOT_CPU_S is the CPU an agent spends before it is heard (imports, session, pose).
# At time scale 0 every agent moves as fast as simhw answers: each is a CPU-bound process,
# and on a host whose cores are all taken the scheduler leaves a thread runnable but waiting
# for up to a second at a time (12 agents on 2 cores, city:60x60:1: the router's threads
# waited on the run queue 0.6-1.0 s in their worst seconds). A 1 s lease then expired
# between a healthy agent and the router in 6 of 13 missions, and the robot was declared
# dead by its token. Beyond this many agents per core a flat-out fleet gets the crowded
# lease and heartbeat timeout (0 of 8 lost with them and bus.handoff; docs/operations.md,
# "Flat out").
FLAT_OUT_AGENTS_PER_CORE = 4
HEARTBEAT_BUDGET = 2500.0  # heartbeat deliveries per second per core
ANNOUNCE_BUDGET = 1000.0  # re-announced statuses delivered per second per core
MAX_ANNOUNCE_S = 5.0
HEARTBEATS_PER_TIMEOUT = 4
# Where the budget lengthens the heartbeat period, the heartbeat timeout (the starvation rule
# below: 30 s at 60 robots on 2 cores) is far longer still, and heartbeats at the budget's
# period were nearly half of what a waiting agent received (60 robots, waiting for a re-plan:
# 82 heartbeats a second against 33 each of statuses, death notices and re-plan reports).
# Their period is then at least the timeout over this many: a hung robot is caught no later,
# and 60 robots send a fifth of the heartbeats. Smaller crowds keep 0.2 s (the chaos
# campaigns' sizes, whose ORMSTC loss repair rides on heartbeats).
STRETCHED_HEARTBEATS_PER_TIMEOUT = 8
# A starved router or agent delays every heartbeat behind it: the heartbeat timeout is also
# at least this much per agent per core (60 agents on 2 cores: 47 fenced at 5 s, 56 at 9 s).
STARVED_S_PER_AGENT = 1.0
# ... and so does every Zenoh lease (a starved process misses its keep-alives: 100 agents
# on 2 cores, lease 5 s, lost most robots to token deletions).
LEASE_MS_PER_AGENT = 400
# An idle agent's liveness service wakes every min(heartbeat, grace) / 2: 20 times a second
# at the agents' 0.1 s grace, 1 to 5 at this one; and a starved agent whose own link flaps
# (every token deleted at once, locally) has this long to notice before it declares the
# fleet dead (100 agents, grace 0.5 s: one agent fenced all the others).
CROWDED_TOKEN_GRACE_S = 2.0
BOOTING_PER_CORE = 4
# Every command, reply and status of a crowded fleet passes through the router (and every
# command through simhw): starved of CPU, its receive queues back up by seconds and simhw's
# replies come after the agents' attempt timeout, again and again (60 robots, agents at
# niceness 10 but in sessions of their own: the router got ~10 % of a core, 100-500 kB
# waited unread on each agent's link, 23 agents stopped on "no answer from simhw within
# 60 s"). Under Linux's fair scheduler a runnable process gets CPU in proportion to its
# niceness weight (deploy.autogroup makes the agents' niceness count); the agents run at the
# smallest niceness that keeps the router RELAY_CORE_SHARE of a core against the fleet all
# busy at once: the lowest priority would make them yield to every other session's work on
# the host as well (60 robots on 2 cores beside 1.8 cores of other work: none booted in 60 s).
RELAY_CORE_SHARE = 0.5
# The kernel's weights (sched_prio_to_weight) of niceness 0..19.
NICE_WEIGHT = (1024, 820, 655, 526, 423, 335, 272, 215, 172, 137,
               110, 87, 70, 56, 45, 36, 29, 23, 18, 15)
MAX_NICE = len(NICE_WEIGHT) - 1
BOOT_CPU_S = 1.0
BOOT_SLACK = 4


def crowded(robots: int, cores: int | None = None) -> bool:
    """More agents than CROWDED_AGENTS_PER_CORE per CPU core (``cores``: os.cpu_count())."""
    return robots > CROWDED_AGENTS_PER_CORE * core_count(cores)


def relay_core_share(robots: int, cores: int | None, agent_nice: int) -> float:
    """The share of one core the fair scheduler gives a runnable niceness-0 process (the
    router) when ``robots`` agents at ``agent_nice`` all want the CPU too: each core runs
    its share of the agents (robots / cores) next to it."""
    per_core = robots / core_count(cores)
    relay = NICE_WEIGHT[0]
    return relay / (relay + per_core * NICE_WEIGHT[agent_nice])


def agent_niceness(robots: int, cores: int | None = None) -> int:
    """The smallest niceness at which ``robots`` busy agents leave the router at least
    RELAY_CORE_SHARE of a core (the lowest priority, MAX_NICE, when none does)."""
    return next((nice for nice in range(1, MAX_NICE + 1)
                 if relay_core_share(robots, cores, nice) >= RELAY_CORE_SHARE), MAX_NICE)


def starved_flat_out(robots: int, cores: int | None = None) -> bool:
    """More than FLAT_OUT_AGENTS_PER_CORE agents per core: too many, at time scale 0, for
    the agents' own lease and heartbeat timeout."""
    return robots > FLAT_OUT_AGENTS_PER_CORE * core_count(cores)


def core_count(cores: int | None) -> int:
    """``cores``, or os.cpu_count() (at least 1)."""
    return max(1, cores or os.cpu_count() or 1)


@dataclass(frozen=True)
class FleetTiming:
    """The timers and start-up pace ``mstc up`` gives a fleet of its size on this many cores.

    None for an agent option means "the agents' own default" (not passed): small fleets run
    exactly as an agent started by hand would, and so detect deaths as fast."""

    lease_ms: int
    dead_after: float
    heartbeat_period: float | None = None
    announce_period: float | None = None
    token_grace: float | None = None
    boot_timeout: float | None = None  # agents' --boot-timeout
    agent_start_timeout: float | None = None  # agents' --start-timeout
    start_timeout: float = 30.0  # the launcher's: every agent announced by then
    booting: int = 0  # agents started but not heard at most at once (0: start all at once)
    agent_nice: int = 0  # the agents' niceness: the router and simhw, which every agent
    # waits on, keep their share of the CPU

    def agent_args(self) -> list[str]:
        """The agent options these timers set (before the user's --agent-arg, which win)."""
        given = (("--heartbeat-period", self.heartbeat_period),
                 ("--announce-period", self.announce_period),
                 ("--token-grace", self.token_grace),
                 ("--boot-timeout", self.boot_timeout),
                 ("--start-timeout", self.agent_start_timeout))
        return [arg for flag, value in given if value is not None
                for arg in (flag, f"{value:g}")]


def fleet_timing(robots: int, cores: int | None = None, *, lease_ms: int | None = None,
                 dead_after: float | None = None, start_timeout: float | None = None,
                 flat_out: bool = False) -> FleetTiming:
    """The timers of a fleet of ``robots`` agents on ``cores`` CPU cores (a pure function of
    the two; the given values win). docs/operations.md, "Fleet scale", has the measurements.

    Up to CROWDED_AGENTS_PER_CORE agents per core: the defaults (lease 1 s, heartbeat timeout
    3 s, the agents' own periods, every agent started at once). Beyond, every agent hears
    every other's heartbeats and statuses, so the deliveries grow with the square of the
    fleet while the CPU does not: the periods grow so that they stay within a budget per core
    (the heartbeat timeout stays HEARTBEATS_PER_TIMEOUT periods), the agents start at most
    BOOTING_PER_CORE per core at a time (each waits to be heard before the next starts), and
    the gather and start-up timeouts cover the paced start of the whole fleet. A fleet
    running ``flat_out`` (time scale 0) with more than FLAT_OUT_AGENTS_PER_CORE agents per
    core gets at least the crowded lease and heartbeat timeout (starved_flat_out)."""
    n = core_count(cores)
    if not crowded(robots, n):
        starved = flat_out and starved_flat_out(robots, n)
        return FleetTiming(
            lease_ms=(CROWDED_LEASE_MS if starved else DEFAULT_LEASE_MS)
            if lease_ms is None else lease_ms,
            dead_after=(CROWDED_DEAD_AFTER_S if starved else DEFAULT_DEAD_AFTER_S)
            if dead_after is None else dead_after,
            start_timeout=start_timeout or 30.0 + robots)
    squared = robots * robots
    heartbeat = _centi(max(DEFAULT_HEARTBEAT_PERIOD, squared / (HEARTBEAT_BUDGET * n)))
    dead = (max(CROWDED_DEAD_AFTER_S, HEARTBEATS_PER_TIMEOUT * heartbeat,
                round(STARVED_S_PER_AGENT * robots / n, 1))
            if dead_after is None else dead_after)
    if heartbeat > DEFAULT_HEARTBEAT_PERIOD:
        heartbeat = max(heartbeat, _centi(dead / STRETCHED_HEARTBEATS_PER_TIMEOUT))
    announce = _centi(min(MAX_ANNOUNCE_S, max(DEFAULT_ANNOUNCE_PERIOD,
                                              squared / (ANNOUNCE_BUDGET * n))))
    # The last agent starts about robots x BOOT_CPU_S / cores after the first on an idle
    # host; the gather waits for it BOOT_SLACK times that (a shared, loaded host: 100 agents
    # on 2 cores took 131 s to start), the agents' other waits and the launcher's start-up
    # timeout that plus the span (the first agent waits for the last one's boot timeout) and
    # their usual margin. They only bite when a robot never comes.
    span = BOOT_SLACK * robots * BOOT_CPU_S / n
    boot = round(DEFAULT_BOOT_TIMEOUT + span)
    return FleetTiming(
        lease_ms=(max(CROWDED_LEASE_MS, int(round(LEASE_MS_PER_AGENT * robots / n, -3)))
                  if lease_ms is None else lease_ms),
        dead_after=dead,
        heartbeat_period=heartbeat, announce_period=announce, token_grace=CROWDED_TOKEN_GRACE_S,
        boot_timeout=boot,
        # the first agent's own gather ends once the last one's boot timeout has passed
        agent_start_timeout=round(boot + span) + DEFAULT_START_TIMEOUT,
        start_timeout=start_timeout or round(boot + span) + DEFAULT_START_TIMEOUT + 10.0,
        booting=BOOTING_PER_CORE * n, agent_nice=agent_niceness(robots, n))


def _centi(seconds: float) -> float:
    """``seconds`` rounded up to a hundredth (a period never shorter than its budget's)."""
    return math.ceil(round(seconds * 100, 6)) / 100
