"""Recoverable families (bus.recovery): a recorder cut off by a router restart or freeze gets
back from the publishers' caches every sample it missed, in order, also with credentials on;
what no cache holds any more becomes a gap record, and the report names it instead of
failing the mission. Real processes: a router, a publisher process, the recorder here."""

from __future__ import annotations

import asyncio
import os
import signal
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from waiting import wait_until

from bus import keys
from bus.config import ConnectionSettings
from bus.messages import CoverEvent
from bus.router import start_router_process, stop_process
from bus.security import credentials
from deploy.monitor.app import NullScreen, Watcher, watch_live
from deploy.monitor.recorder import read_recording
from deploy.monitor.report import build_report
from deploy.monitor.types import Gap, Recording
from deploy.monitor.view import FeedStats

pytestmark = [pytest.mark.integration, pytest.mark.slow]

MISSION = "recover"
ROBOTS = 2
MOVES = 120
# The publisher: simhw's cover events of two robots walking their rows at 50 moves/s, one
# line on stdout at the start, halfway and at the end; it keeps its caches until stdin ends.
# With a cache depth argument it uses bus.recovery's publishers directly with that depth.
PUBLISHER = """
import sys, time
from pathlib import Path
from bus import keys
from bus.codec import encode
from bus.config import ConnectionSettings, open_session
from bus.messages import CoverEvent
from bus.qos import qos_for
from bus.recovery import Publishers

endpoint, creds, depth = sys.argv[1], sys.argv[2], int(sys.argv[3])
settings = ConnectionSettings(connect=(endpoint,), mission="%(m)s",
                              credentials=Path(creds) if creds else None,
                              role="simhw" if creds else None)
with open_session(settings) as session:
    publishers = Publishers(session)
    print("ready", flush=True)
    time.sleep(1.0)  # the recorder's subscription reaches the router
    for i in range(%(n)d):
        for r in range(%(k)d):
            msg = CoverEvent(robot=r, cell=(2 * r, i), sim_time=i * 0.1, visits=1)
            publishers.put(keys.sim_cover("%(m)s", r), encode(msg), qos_for(CoverEvent),
                           depth or %(depth)d)
        if i == %(n)d // 3:
            print("halfway", flush=True)
        time.sleep(0.02)
    print("done", flush=True)
    sys.stdin.read()
    publishers.close()
"""


class Fleet:
    """The router and the publisher process of one test."""

    def __init__(self, endpoint: str, creds: Path | None, depth: int) -> None:
        self.endpoint, self.creds = endpoint, creds
        self.router = self._router()
        script = PUBLISHER % {"m": MISSION, "n": MOVES, "k": ROBOTS, "depth": 4096}
        self.publisher = subprocess.Popen(
            [sys.executable, "-c", script, endpoint, str(creds or ""), str(depth)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)

    def _router(self) -> subprocess.Popen[str]:
        extra = () if self.creds is None else ("--credentials", str(self.creds))
        return start_router_process(self.endpoint, extra_args=extra)

    async def said(self, line: str) -> None:
        assert self.publisher.stdout is not None
        async with asyncio.timeout(30.0):
            heard = await asyncio.to_thread(self.publisher.stdout.readline)
        assert heard.strip() == line, f"publisher said {heard!r}, expected {line!r}"

    def restart_router(self) -> None:
        stop_process(self.router)
        self.router = self._router()

    async def freeze_router(self, seconds: float) -> None:
        os.kill(self.router.pid, signal.SIGSTOP)
        try:
            await asyncio.sleep(seconds)  # the fault's length, not a wait for a result
        finally:
            os.kill(self.router.pid, signal.SIGCONT)

    def stop(self) -> None:
        if self.publisher.stdin is not None:
            self.publisher.stdin.close()
        try:
            self.publisher.wait(10.0)
        except subprocess.TimeoutExpired:
            self.publisher.kill()
            self.publisher.wait()
        stop_process(self.router)


@pytest.fixture
def secure_creds(tmp_path: Path) -> Path:
    path = tmp_path / credentials.CREDENTIALS_FILE
    credentials.generate(MISSION, ROBOTS).save(path)
    return path


@pytest.fixture
def fleet_factory(free_port: int) -> Iterator[Callable[[Path | None, int], Fleet]]:
    made: list[Fleet] = []

    def make(creds: Path | None, depth: int = 0) -> Fleet:
        made.append(Fleet(f"tcp/127.0.0.1:{free_port}", creds, depth))
        return made[-1]

    yield make
    for fleet in made:
        fleet.stop()


def _cover_walks(watcher: Watcher) -> dict[int, int]:
    return {r: len(v.path) for r, v in watcher.model.robots.items()}


async def _record(fleet: Fleet, path: Path, fault: Callable[[], object],
                  done: Callable[[Watcher], bool]) -> tuple[Recording, FeedStats]:
    """Record the mission while ``fault`` hits the router a third of the way through; stop
    once ``done(watcher)``. The recording, and the recorder's bus statistics."""
    role = None if fleet.creds is None else "observer"
    settings = ConnectionSettings(connect=(fleet.endpoint,), mission=MISSION,
                                  credentials=fleet.creds, role=role)
    watcher, stop = Watcher(NullScreen()), asyncio.Event()
    async with asyncio.TaskGroup() as group:
        recorder = group.create_task(watch_live(settings, watcher, stop=stop, record=path,
                                                world_period=60.0))
        await fleet.said("ready")
        await fleet.said("halfway")
        result = fault()
        if asyncio.iscoroutine(result):
            await result
        await fleet.said("done")
        await wait_until(lambda: done(watcher), 20.0, "the recording to catch up")
        stop.set()
    return read_recording(path), recorder.result()


def _covers(recording: Recording) -> dict[int, list[int]]:
    walks: dict[int, list[int]] = {}
    for record in recording.records:
        if isinstance(record.msg, CoverEvent):
            walks.setdefault(record.msg.robot, []).append(record.msg.cell[1])
    return walks


@pytest.mark.parametrize("secure", [False, True], ids=["open", "credentials"])
@pytest.mark.parametrize("fault", ["restart", "freeze"])
async def test_a_recording_cut_off_by_the_router_recovers_every_sample(
        fleet_factory: Callable[[Path | None, int], Fleet], secure_creds: Path,
        tmp_path: Path, fault: str, secure: bool) -> None:
    fleet = fleet_factory(secure_creds if secure else None, 0)

    def inject() -> object:
        if fault == "restart":
            fleet.restart_router()
            return None
        return fleet.freeze_router(0.8)

    path = tmp_path / "rec.jsonl"
    recording, stats = await _record(fleet, path, inject, lambda w: _cover_walks(w) == {
        r: MOVES for r in range(ROBOTS)})
    assert "sim/cover.missed" not in stats.drops
    assert _covers(recording) == {r: list(range(MOVES)) for r in range(ROBOTS)}
    assert not [r for r in recording.records if isinstance(r.msg, Gap)]
    report = build_report(recording)
    assert report.ok, report.invariants
    assert report.gaps == ()


async def test_what_no_cache_holds_is_a_gap_the_report_names_without_failing(
        fleet_factory: Callable[[Path | None, int], Fleet], tmp_path: Path) -> None:
    # A cache of 3 samples cannot cover a restart of a second at 50 samples/s.
    fleet = fleet_factory(None, 3)

    def gaps(watcher: Watcher) -> bool:
        walks = _cover_walks(watcher)
        ended = all(watcher.model.robots[r].path[-1:] == [(2 * r, MOVES - 1)]
                    for r in range(ROBOTS) if r in watcher.model.robots)
        return len(walks) == ROBOTS and ended

    recording, stats = await _record(fleet, tmp_path / "rec.jsonl", fleet.restart_router,
                                     gaps)
    walks = _covers(recording)
    lost = {r: MOVES - len(walks[r]) for r in range(ROBOTS)}
    assert all(n > 0 for n in lost.values()), lost
    found = [r.msg for r in recording.records if isinstance(r.msg, Gap)]
    by_robot: dict[int, int] = {}
    for gap in found:
        parsed = keys.parse(gap.key)
        assert parsed is not None and parsed.kind == "sim/cover" == gap.family
        assert parsed.robot is not None
        assert gap.since is not None and gap.since < gap.until
        by_robot[parsed.robot] = by_robot.get(parsed.robot, 0) + gap.missed
    assert by_robot == lost
    assert stats.drops["sim/cover.missed"] == sum(lost.values())  # the bus counts them too
    report = build_report(recording)
    assert report.ok, report.invariants
    adjacent = next(i for i in report.invariants if i.name == "every move 4-adjacent")
    assert adjacent.status == "ok" and "jumps across the recording's gaps" in adjacent.detail
    assert len(report.gaps) == len(found)
