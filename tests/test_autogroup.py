"""A niced fleet child hands its niceness to its scheduler autogroup (deploy.autogroup):
without it, agents in sessions of their own weighed as much as the router whatever their
niceness, and a 60-robot fleet starved the router of CPU until simhw's replies came after
the agents' timeouts. Real processes for the kernel side; the retry on the kernel's rate
limit with a stand-in file."""

from __future__ import annotations

import errno
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from deploy import autogroup
from deploy.fleet import niced
from deploy.fleet_timing import (
    MAX_NICE,
    RELAY_CORE_SHARE,
    agent_niceness,
    fleet_timing,
    relay_core_share,
)

AGENT_NICE = fleet_timing(100, 2).agent_nice

# What deploy.fleet.Child runs for an agent: ``nice -n N python ... deploy.cli.main`` in a
# session of its own; the probe stops main right after its start-up step (no sub-command
# is parsed or imported), then reports its autogroup's niceness the way deploy.autogroup
# reads it ("None" for a process in init's session: the kernel shows it no autogroup).
PROBE = ("import sys\nimport deploy.cli as cli\nfrom deploy.autogroup import autogroup_nice\n"
         "def stop(argv):\n    raise SystemExit(0)\n"
         "cli._parser_for = stop\ntry:\n    cli.main(['agent'])\nexcept SystemExit:\n    pass\n"
         "print(autogroup_nice(), file=sys.stderr)\n")

needs_autogroups = pytest.mark.skipif(
    not autogroup.AUTOGROUP.exists() or shutil.which("nice") is None,
    reason="no scheduler autogroups (or no nice command) here")


def _autogroup_nice_of_probe(*, niceness: int, own_session: bool) -> int | None:
    proc = subprocess.run(niced([sys.executable, "-c", PROBE], niceness),
                          capture_output=True, text=True, timeout=60,
                          start_new_session=own_session)
    assert proc.returncode == 0, proc.stderr
    shown = proc.stderr.split()[-1]
    return None if shown == "None" else int(shown)


@needs_autogroups
def test_a_niced_child_in_its_own_session_gives_its_autogroup_its_niceness() -> None:
    assert _autogroup_nice_of_probe(niceness=AGENT_NICE, own_session=True) == AGENT_NICE


@needs_autogroups
def test_a_process_in_someone_elses_session_leaves_the_autogroup_alone() -> None:
    ours = autogroup.autogroup_nice()
    assert _autogroup_nice_of_probe(niceness=AGENT_NICE, own_session=False) == ours


@needs_autogroups
def test_an_unniced_child_changes_nothing() -> None:
    assert _autogroup_nice_of_probe(niceness=0, own_session=True) == 0


class _RateLimited:
    """/proc/self/autogroup as the kernel answers it when another process wrote within
    100 ms: EAGAIN ``busy`` times, then the write goes through."""

    def __init__(self, busy: int) -> None:
        self.busy = busy
        self.nice = 0

    def read_text(self) -> str:
        return f"/autogroup-7 nice {self.nice}\n"

    def write_text(self, text: str) -> int:
        if self.busy:
            self.busy -= 1
            raise OSError(errno.EAGAIN, os.strerror(errno.EAGAIN))
        self.nice = int(text)
        return len(text)


@pytest.fixture
def niced_leader(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(autogroup, "niceness", lambda: AGENT_NICE)
    monkeypatch.setattr(autogroup, "leads_own_session", lambda: True)
    monkeypatch.setattr(autogroup, "RETRY_S", 0.001)


@pytest.mark.usefixtures("niced_leader")
def test_a_process_the_kernel_shows_no_autogroup_has_none(tmp_path: Path) -> None:
    # init's session (where a CI runner may start the suite) is in the root task group:
    # its /proc/self/autogroup reads empty, and nothing is written there
    shown = tmp_path / "autogroup"
    shown.write_text("")
    assert autogroup.autogroup_nice(shown) is None
    assert not autogroup.share_niceness(shown) and shown.read_text() == ""
    assert autogroup.autogroup_nice(tmp_path / "absent") is None
    shown.write_text("/autogroup-41 nice 19\n")
    assert autogroup.autogroup_nice(shown) == 19


@pytest.mark.usefixtures("niced_leader")
def test_the_write_is_retried_while_the_kernel_rate_limits_it() -> None:
    fake = _RateLimited(busy=3)
    assert autogroup.share_niceness(fake)  # type: ignore[arg-type]
    assert fake.nice == AGENT_NICE


@pytest.mark.usefixtures("niced_leader")
def test_a_refusal_past_the_patience_is_reported_not_raised() -> None:
    fake = _RateLimited(busy=10**6)
    assert not autogroup.share_niceness(fake, patience=0.02)  # type: ignore[arg-type]
    assert fake.nice == 0


def test_the_agents_niceness_leaves_the_router_half_a_core_up_to_50_agents_per_core() -> None:
    for cores in (1, 2, 4):
        for robots in range(1, 50 * cores + 1):
            nice = agent_niceness(robots, cores)
            assert relay_core_share(robots, cores, nice) >= RELAY_CORE_SHARE, (robots, cores)
            # and no lower than that: the agents still compete with other sessions' work
            assert nice == 1 or relay_core_share(robots, cores, nice - 1) < RELAY_CORE_SHARE
    assert [agent_niceness(k, 2) for k in (30, 60, 100)] == [13, 16, 18]
    assert agent_niceness(1000, 2) == MAX_NICE
    # the niceness of the failed runs: the router's share at 60 and 100 robots on 2 cores
    assert relay_core_share(60, 2, agent_nice=10) < 0.25
    assert relay_core_share(100, 2, agent_nice=10) < 0.2
