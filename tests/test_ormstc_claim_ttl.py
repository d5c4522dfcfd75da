"""How long a robot that lost a claim waits for the winner's tree edge before deciding the
cell again (planner.ormstc connections' unsure links; agent.ormstc.options.claim_ttl). 40
ORMSTC agents under the chaos campaign's message loss walked back over their own cells to
claims whose winners' edges were still on the way (docs/ormstc.md, "Heavier loss")."""

from __future__ import annotations

import pytest

from agent.core.config import AgentConfig
from agent.ormstc.options import OrmstcOptions, claim_ttl, rejoin_silence, resend_grace
from planner.ormstc.machine import OrmstcMachine
from planner.ormstc.types import MachineConfig


def _lost_claim(ttl: float | None) -> OrmstcMachine:
    """Robot 0, which lost the claim on cell (0, 1) to robot 1 at time 0, no edge heard."""
    machine = OrmstcMachine(MachineConfig(robot=0, team=2, start=(0.0, 0.0), claim_wait=0.25,
                                          claim_ttl=ttl))
    machine.mine.add((0, 0))
    machine._connect(1, (0, 0), (0, 1), unsure=True)
    return machine


def _retried(machine: OrmstcMachine, now: float) -> bool:
    targets, _ = machine.connections.targets(machine.know, machine.mine, now, over=False)
    return ((0, 0), (0, 1)) in targets


@pytest.mark.parametrize(("ttl", "expiry"), [(None, 1.5), (12.0, 12.0)])
def test_a_lost_claim_is_decided_again_only_after_its_time_to_live(
        ttl: float | None, expiry: float) -> None:
    machine = _lost_claim(ttl)
    assert not _retried(machine, expiry - 0.01)
    assert _retried(machine, expiry)


def test_a_winner_that_dies_before_its_edge_is_taken_over_at_once() -> None:
    machine = _lost_claim(60.0)
    machine.know.mark_dead(1)
    assert _retried(machine, 0.1)


def test_agents_give_a_lost_claims_winner_resend_rounds_that_grow_with_the_heartbeat() -> None:
    small = claim_ttl(0.25, 0.2)  # a small fleet: heartbeats every 0.2 s
    crowd = claim_ttl(0.25, 2.5)  # 40 robots on 2 cores
    assert small == pytest.approx(2 * 0.25 + 1 + 3 * 0.3)
    assert crowd == pytest.approx(2 * 0.25 + 1 + 3 * resend_grace(2.5)) and crowd > 10
    config = AgentConfig(robot=0, k=40, algo="ormstc", heartbeat_period=2.5)
    assert OrmstcOptions().machine(config, (0, 0)).claim_ttl == crowd


def test_a_crowd_restates_only_after_silences_a_loaded_host_does_not_cause() -> None:
    """30 robots on 2 cores restated after every 1 s gap in a peer's heartbeats, 36-72 times
    per robot in 100 s, until claims waited behind the flood; small fleets keep 1 s."""
    assert rejoin_silence(0.2, 3.0) == 1.0  # the agents' own defaults (small fleets): as before
    assert rejoin_silence(0.2, 15.0) == pytest.approx(3.75)  # mstc up's timers, 30 robots
    assert rejoin_silence(2.5, 20.0) == pytest.approx(12.5)  # 40 robots: 5 heartbeats
