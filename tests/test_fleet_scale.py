"""The timers and start-up pace mstc up derives from the fleet size and the core count
(deploy.fleet_timing.fleet_timing), and the gather's cheap paths for big fleets; pure, no
processes (the 100-robot runs are benchmarks: docs/operations.md, "Fleet scale")."""

from __future__ import annotations

import random

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from agent.core.config import DEFAULT_BOOT_TIMEOUT, DEFAULT_START_TIMEOUT
from agent.core.roster import decide, to_wire
from agent.offline.driver import PULL_ROBOTS, pull_period
from bus.messages import RobotStatus
from deploy.fleet import niced
from deploy.fleet_timing import (
    ANNOUNCE_BUDGET,
    BOOT_CPU_S,
    CROWDED_AGENTS_PER_CORE,
    HEARTBEAT_BUDGET,
    HEARTBEATS_PER_TIMEOUT,
    STRETCHED_HEARTBEATS_PER_TIMEOUT,
    FleetTiming,
    fleet_timing,
)


@pytest.mark.parametrize(("robots", "cores"), [(1, 1), (6, 1), (12, 2), (30, 8)])
def test_fleets_up_to_six_agents_per_core_run_with_the_agents_own_defaults(
        robots: int, cores: int) -> None:
    timing = fleet_timing(robots, cores)
    assert timing == FleetTiming(lease_ms=1000, dead_after=3.0, start_timeout=30.0 + robots)
    assert timing.agent_args() == []  # nothing passed: detection as fast as ever
    assert timing.booting == 0 and timing.agent_nice == 0


def test_crowded_fleets_keep_heartbeat_and_status_deliveries_within_a_budget_per_core() -> None:
    for cores in (1, 2, 4):
        for robots in range(CROWDED_AGENTS_PER_CORE * cores + 1, 301, 7):
            t = fleet_timing(robots, cores)
            assert t.heartbeat_period is not None and t.announce_period is not None
            assert robots ** 2 / t.heartbeat_period <= HEARTBEAT_BUDGET * cores * 1.01 or \
                t.heartbeat_period == 0.2
            assert robots ** 2 / t.announce_period <= ANNOUNCE_BUDGET * cores * 1.01 or \
                t.announce_period in (0.5, 5.0)
            assert t.dead_after >= HEARTBEATS_PER_TIMEOUT * t.heartbeat_period
            assert t.lease_ms >= 5000 and t.dead_after >= 5.0


def test_a_crowd_whose_heartbeat_the_budget_lengthens_beats_at_most_8_times_a_timeout(
        ) -> None:
    for cores in (1, 2, 4):
        for robots in range(CROWDED_AGENTS_PER_CORE * cores + 1, 301, 7):
            t = fleet_timing(robots, cores)
            assert t.heartbeat_period is not None
            budget = robots ** 2 / (HEARTBEAT_BUDGET * cores)
            if budget <= 0.2:  # the chaos campaigns' sizes keep the agents' own period
                assert t.heartbeat_period == 0.2
            else:
                assert t.heartbeat_period >= t.dead_after / STRETCHED_HEARTBEATS_PER_TIMEOUT
                assert t.heartbeat_period >= budget
                assert t.heartbeat_period <= t.dead_after / STRETCHED_HEARTBEATS_PER_TIMEOUT \
                    + 0.01 or t.heartbeat_period <= budget + 0.01
    assert fleet_timing(60, 2).heartbeat_period == 3.75  # 30 s timeout / 8
    # a timeout given shorter than the derived one never stretches the heartbeat beyond it
    assert fleet_timing(100, 2, dead_after=2.0).heartbeat_period == 2.0


def test_timers_grow_with_the_fleet_and_shrink_with_the_cores() -> None:
    sizes = [fleet_timing(robots, 2) for robots in (13, 30, 60, 100, 200)]
    for field in ("heartbeat_period", "announce_period", "dead_after", "lease_ms",
                  "boot_timeout", "start_timeout"):
        values = [getattr(t, field) for t in sizes]
        assert values == sorted(values), field
    assert fleet_timing(100, 8).dead_after < fleet_timing(100, 2).dead_after
    assert fleet_timing(100, 8).heartbeat_period < fleet_timing(100, 2).heartbeat_period  # type: ignore[operator]


def test_start_up_timeouts_cover_a_paced_start_of_the_whole_fleet() -> None:
    for robots, cores in ((13, 2), (60, 2), (100, 2), (100, 4), (300, 2)):
        t = fleet_timing(robots, cores)
        assert t.boot_timeout is not None and t.agent_start_timeout is not None
        # the last agent starts about robots x BOOT_CPU_S / cores after the first
        assert t.boot_timeout >= DEFAULT_BOOT_TIMEOUT + robots * BOOT_CPU_S / cores
        span = t.boot_timeout - DEFAULT_BOOT_TIMEOUT
        # the first agent to gather outwaits the boot timeout of the last one to start
        assert t.agent_start_timeout >= t.boot_timeout + span + DEFAULT_START_TIMEOUT - 1
        assert t.start_timeout > t.agent_start_timeout  # the agents report first
        assert t.booting == 4 * cores and t.agent_nice > 0


def test_given_values_win_over_the_derived_ones() -> None:
    t = fleet_timing(100, 2, lease_ms=800, dead_after=2.0, start_timeout=42.0)
    assert (t.lease_ms, t.dead_after, t.start_timeout) == (800, 2.0, 42.0)
    assert fleet_timing(6, 2, lease_ms=700).lease_ms == 700


def test_agent_args_name_every_derived_agent_option_once() -> None:
    args = fleet_timing(100, 2).agent_args()
    flags = args[::2]
    assert flags == ["--heartbeat-period", "--announce-period", "--token-grace",
                     "--boot-timeout", "--start-timeout"]
    assert all(float(value) > 0 for value in args[1::2])


def test_niced_keeps_the_command_and_only_prefixes_it() -> None:
    argv = ["python", "-m", "deploy.cli", "agent"]
    assert niced(argv, 0) == argv
    out = niced(argv, 10)
    assert out[-4:] == argv and (out == argv or out[-6:-4] == ["-n", "10"])


# --- the gather's cheap paths agree with the dict comparison --------------------------------

def _status(robot: int, start: tuple[int, int], wire: tuple[tuple[int, int, int], ...],
            state: str = "gathering") -> RobotStatus:
    return RobotStatus(robot, 1, start, "opt", "", state, "", wire)


@settings(max_examples=60, deadline=None)
@given(st.integers(2, 12), st.integers(0, 2 ** 16), st.booleans())
def test_a_roster_sent_unsorted_or_with_repeats_decides_as_its_sorted_form(
        k: int, seed: int, boot_over: bool) -> None:
    rng = random.Random(seed)
    starts = {r: (2 * r, 2 * (r % 3)) for r in range(k)}
    heard = [r for r in range(1, k) if rng.random() < 0.8]
    dead = tuple(r for r in range(1, k) if rng.random() < 0.1)
    proposals = {r: {m: starts[m] for m in range(k) if rng.random() < 0.7} for r in heard}
    sorted_peers = {r: _status(r, starts[r], to_wire(p)) for r, p in proposals.items()}
    messy_peers = {}
    for r, p in proposals.items():
        wire = list(to_wire(p))
        wire += wire[: rng.randint(0, len(wire))]  # repeated entries, as a peer may send
        rng.shuffle(wire)
        messy_peers[r] = _status(r, starts[r], tuple(wire))
    assert decide(0, starts[0], k, messy_peers, dead, boot_over) == \
        decide(0, starts[0], k, sorted_peers, dead, boot_over)


# --- the backstop pulls of every robot's state --------------------------------------------

def test_the_fleets_state_pulls_stay_within_pull_robots_per_announce_period() -> None:
    for k in (1, 6, 25, 30, 60, 100, 300):
        for announce in (0.5, 1.8, 5.0):
            period = pull_period(announce, k)
            assert period >= announce  # never more often than the announce period
            # every pull asks all k robots: the fleet's state replies per second
            assert k * k / period <= k * PULL_ROBOTS / announce * 1.0001
    assert pull_period(1.8, 60) == pytest.approx(4.32)
    assert pull_period(0.5, 6) == 0.5  # small fleets pull as before
