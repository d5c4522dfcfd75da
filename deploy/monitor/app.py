"""Driving the model: live from the wire (``mstc monitor``, ``mstc up --record``) or from a
recording (``mstc replay``), into a screen (rich live view or plain lines) and a recorder."""

from __future__ import annotations

import asyncio
import time
from collections import Counter
from collections.abc import Awaitable, Callable, Iterable
from pathlib import Path
from typing import Protocol, TypeVar

from rich.console import Console, RenderableType
from rich.live import Live

from bus import keys
from bus.bridge import Bus
from bus.config import ConnectionSettings, open_session_async
from bus.messages import SCHEMA_VERSION
from deploy.errors import FleetError
from deploy.monitor.layout import EventLog
from deploy.monitor.live import LiveFeed, poll
from deploy.monitor.model import FleetModel
from deploy.monitor.plain import PlainPrinter
from deploy.monitor.recorder import Recorder, Recorders, RecordWriter
from deploy.monitor.types import (
    Header,
    MonitorEvent,
    Record,
    RecorderLink,
    Recording,
    TokenChange,
)
from deploy.monitor.verdict import Verdict, mission_verdict
from deploy.monitor.view import FeedStats, render

T = TypeVar("T")
TICK_S = 0.05
# Records judged and written per turn of the loop: a backlog is worked off in slices, so a
# launcher that records its own mission keeps its timers (progress, kills, timeouts) running.
FEED_BATCH = 2000
REFRESH_S = 0.25
WORLD_PERIOD_S = 2.0
RENDER_SHARE = 5.0
# A verdict read off the robots' messages that counts a robot as over only because its
# token vanished ends a watch (--exit-when-done) only once it has held this long: a link
# between hosts that drops for a moment takes every far token with it, and the robots
# themselves confirm such a loss before they act on it (bus.detector). 5 s: longer than
# the agents take to declare a death they saw (a grace, or the heartbeat timeout).
GONE_GRACE_S = 5.0
CONNECT_POLL_S = 0.1


class Screen(Protocol):
    def events(self, events: list[MonitorEvent]) -> None: ...

    def refresh(self, model: FleetModel, stats: FeedStats) -> None: ...

    def close(self, model: FleetModel, stats: FeedStats) -> None: ...


class PlainScreen:
    """One line per event, a summary line at the end."""

    def __init__(self, printer: PlainPrinter | None = None) -> None:
        self.printer = printer or PlainPrinter()

    def events(self, events: list[MonitorEvent]) -> None:
        self.printer.events(events)

    def refresh(self, model: FleetModel, stats: FeedStats) -> None:
        return None

    def close(self, model: FleetModel, stats: FeedStats) -> None:
        self.printer.final(model, stats.dropped)


class NullScreen:
    """No output: a recorder only (``mstc up --record``)."""

    def events(self, events: list[MonitorEvent]) -> None:
        return None

    def refresh(self, model: FleetModel, stats: FeedStats) -> None:
        return None

    def close(self, model: FleetModel, stats: FeedStats) -> None:
        return None


class RichScreen:
    """The live view; the last frame stays on the terminal when it closes."""

    def __init__(self, console: Console | None = None) -> None:
        self.console = console or Console()
        self._live = Live(console=self.console, auto_refresh=False, transient=True,
                          screen=False)
        self._live.start()
        self.log = EventLog()

    def _frame(self, model: FleetModel, stats: FeedStats) -> RenderableType:
        # the terminal's size at each frame: a resized window gets a new layout
        return render(model, stats, width=self.console.width, height=self.console.height,
                      log=self.log)

    def events(self, events: list[MonitorEvent]) -> None:
        self.log.add(events)  # each frame shows the latest, important ones pinned

    def refresh(self, model: FleetModel, stats: FeedStats) -> None:
        self._live.update(self._frame(model, stats), refresh=True)

    def close(self, model: FleetModel, stats: FeedStats) -> None:
        self._live.stop()
        self.console.print(self._frame(model, stats))


class RateMeter:
    """Messages per second over the last second or so."""

    def __init__(self) -> None:
        self._last: tuple[float, int] | None = None
        self.rate = 0.0

    def update(self, now: float, total: int) -> float:
        if self._last is None:
            self._last = (now, total)
        elif now - self._last[0] >= 1.0:
            self.rate = (total - self._last[1]) / (now - self._last[0])
            self._last = (now, total)
        return self.rate


class Watcher:
    """Model + screen + optional recorder, fed with records."""

    def __init__(self, screen: Screen, recorder: Recorder | None = None,
                 model: FleetModel | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.model = model or FleetModel()
        self._clock = clock
        self._judged_at = 0.0  # when the verdict last took its state (clock time)
        self.screen = screen
        self.recorder = recorder
        self.connected = False
        self.verdict: Verdict | None = None
        self.mission = ""  # the mission watched, for a monitor that follows new runs
        self.new_run = False  # robots of a judged mission came back: the mission runs again
        self.written: Counter[str] | None = None  # records written, by key family

    def feed(self, records: Iterable[Record]) -> None:
        fed = False
        for record in records:
            fed = True
            if self.verdict is not None and self._returned(record):
                self.new_run = True
            events = self.model.apply(record)
            if self.recorder is not None:
                self.recorder.write(record)
                if self.written is not None:
                    self.written[keys.kind_of(record.key)] += 1
            if events:
                self.screen.events(events)
        if fed and (self.verdict is None or not self.verdict.published):
            self._judge()

    def _returned(self, record: Record) -> bool:
        """A robot's token back after it had vanished, once the mission had its verdict: a
        new run of the same mission (its robots start again from life 1)."""
        change = record.msg
        if not isinstance(change, TokenChange) or not change.present:
            return False
        view = self.model.robots.get(change.robot)
        return view is not None and view.token is False

    def _judge(self) -> None:
        """Take the mission's verdict once it has one; one read off the robots' messages
        (ORMSTC and tree missions publish none) is told as an event of its own, and judged
        again as they go on (a robot thought dead may come back)."""
        before, self.verdict = self.verdict, mission_verdict(self.model)
        if self.verdict is None or (before is not None and before.state == self.verdict.state):
            return
        self._judged_at = self._clock()
        if not self.verdict.published:
            state = self.verdict.state
            self.screen.events([self.model.note(
                self.model.t, "mission_complete" if state == "complete" else "mission_failed",
                f"mission {state}: {self.verdict.message}")])

    def settled(self) -> bool:
        """The mission has a final verdict and every robot is done, dead or gone; a verdict
        read off a robot known gone only by its vanished token has held GONE_GRACE_S."""
        robots = self.model.robots.values()
        if self.verdict is None or not all(v.done or v.dead or v.left for v in robots):
            return False
        return self.verdict.published or not any(v.gone_by_token_only for v in robots) or \
            self._clock() - self._judged_at >= GONE_GRACE_S


async def watch_live(settings: ConnectionSettings, watcher: Watcher, *,
                     stop: asyncio.Event | None = None, duration: float | None = None,
                     until_settled: bool = False, world_period: float = WORLD_PERIOD_S,
                     record: Path | None = None, record_mcap: Path | None = None,
                     source: str = "monitor",
                     link: RecorderLink | None = None) -> FeedStats:
    """Watch ``settings.mission`` until ``stop``, ``duration`` or (optionally) the end of
    the mission; the final state and world are queried once more before returning.
    ``record`` and ``record_mcap`` keep every message as JSON Lines and as MCAP; ``link``
    hears when every subscription is declared and how much has been written."""
    stop = stop or asyncio.Event()
    async with open_session_async(settings) as session, Bus(session, settings.mission) as bus:
        watcher.connected = True
        feed = LiveFeed(bus)
        started = time.time()
        kept: list[Recorder] = []
        if record is not None:
            kept.append(RecordWriter(record, Header(settings.mission, started, source,
                                                    SCHEMA_VERSION)))
        if record_mcap is not None:
            from deploy.robotics.export import McapRecorder  # the robotics extra

            kept.append(McapRecorder(record_mcap, settings.mission, started))
        if kept:
            watcher.recorder = kept[0] if len(kept) == 1 else Recorders(kept)
        if link is not None:
            watcher.written = link.written
        feed.start()
        if link is not None:
            link.subscribed.set()
        try:
            return await _loop(feed, watcher, stop, duration, until_settled, world_period)
        finally:
            if watcher.recorder is not None:
                watcher.recorder.close()


async def until_connected(connected: Callable[[], bool], settings: ConnectionSettings,
                          limit: float, *, say: Callable[[str], None],
                          note_after: float = 0.5) -> None:
    """Return once ``connected()``; say what it waits for if that takes more than
    ``note_after`` seconds, and raise FleetError after ``limit`` seconds: a monitor started
    with no router must not wait silently for ever."""
    where = ", ".join(settings.endpoints) or "the configured endpoints"
    waited, noted = 0.0, False
    while not connected():
        if waited >= note_after and not noted:
            say(f"waiting for a Zenoh router at {where} (mission {settings.mission}; giving "
                f"up after {limit:g} s)")
            noted = True
        if waited >= limit:
            raise FleetError(f"no Zenoh router answered at {where} within {limit:g} s "
                             f"(start the fleet with mstc up, or a router with mstc router)")
        await asyncio.sleep(CONNECT_POLL_S)
        waited += CONNECT_POLL_S


async def recorded(main: Awaitable[T], settings: ConnectionSettings, path: Path | None,
                   source: str = "up", mcap: Path | None = None,
                   link: RecorderLink | None = None) -> T:
    """Await ``main`` (a launcher) with a recorder of ``settings.mission`` beside it (JSON
    Lines to ``path``, MCAP to ``mcap``); the recording ends when ``main`` does (at once if
    the router never came up)."""
    stop, watcher = asyncio.Event(), Watcher(NullScreen())
    async with asyncio.TaskGroup() as group:
        recorder = group.create_task(watch_live(settings, watcher, stop=stop, record=path,
                                                record_mcap=mcap, source=source,
                                                link=link))
        try:
            return await main
        finally:
            stop.set()
            if not watcher.connected:
                recorder.cancel()


async def _loop(feed: LiveFeed, watcher: Watcher, stop: asyncio.Event,
                duration: float | None, until_settled: bool, world_period: float) -> FeedStats:
    meter, next_refresh = RateMeter(), 0.0
    async with asyncio.TaskGroup() as group:
        poller = group.create_task(poll(feed, world_period))
        try:
            while not stop.is_set():
                watcher.feed(feed.drain(FEED_BATCH))
                now = feed.clock()
                if now >= next_refresh:
                    meter.update(now, watcher.model.kinds.total())
                    watcher.screen.refresh(watcher.model, feed.stats(meter.rate))
                    if watcher.recorder is not None:
                        watcher.recorder.flush()
                    # A big map renders slowly: keep drawing to a fifth of the loop's time.
                    next_refresh = now + max(REFRESH_S, RENDER_SHARE * (feed.clock() - now))
                if duration is not None and now - feed.t0 >= duration:
                    break
                if until_settled and watcher.settled() and not feed.queue:
                    break
                await asyncio.sleep(0 if feed.queue else TICK_S)
        finally:
            poller.cancel()
    await feed.sync()
    watcher.feed(feed.drain())
    stats = feed.stats(meter.rate)
    watcher.screen.close(watcher.model, stats)
    return stats


def replay(recording: Recording, watcher: Watcher, speed: float, *,
           clock: Callable[[], float] = time.monotonic,
           sleep: Callable[[float], None] = time.sleep) -> FeedStats:
    """Play ``recording`` into ``watcher`` at ``speed`` times real time (0: at once)."""
    drops = {"recording.malformed": len(recording.errors)} if recording.errors else {}
    meter, start, last = RateMeter(), clock(), -REFRESH_S

    def stats() -> FeedStats:
        return FeedStats(source=f"replay x{speed:g}" if speed else "replay", rate=meter.rate,
                         drops=drops)

    first = recording.records[0].t if recording.records else 0.0
    for record in recording.records:
        while speed > 0 and (wait := start + (record.t - first) / speed - clock()) > 0:
            sleep(min(wait, REFRESH_S))
            now = clock()
            if now - last >= REFRESH_S:
                last = now
                meter.update(now, watcher.model.kinds.total())
                watcher.screen.refresh(watcher.model, stats())
        watcher.feed((record,))
    watcher.screen.close(watcher.model, stats())
    return stats()
