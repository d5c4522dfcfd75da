"""The simhw process's Zenoh side: binds an HwService to the bus and runs until told to stop.

Queryables: one ``hw/<r>/cmd`` per body, ``hw/admin`` and ``sim/world`` (keys from bus.keys).
The bus bridge hands every query to the event loop; command responders are coroutines, so the
bridge runs each in its own task group (the process's one TaskGroup) and bodies move
concurrently while one body's commands queue on its lock. Payloads that do not decode are
answered with an error reply by the bridge and counted in its DropCounter, which the admin
"status" reports. SIGTERM, SIGINT or an admin "shutdown" end the process cleanly (the bus
and the session are closed on the way out).
"""

from __future__ import annotations

import asyncio
import contextlib
import signal
from collections.abc import Awaitable, Callable

from bus import keys
from bus.bridge import Bus
from bus.config import ConnectionSettings
from bus.messages import AdminCommand, HwCommand, HwReply
from simhw.clock import SimClock
from simhw.dead_bodies import watch_deaths
from simhw.kinematics import Kinematics
from simhw.service import HwService
from simhw.types import ServerOptions
from simhw.world import World

# Lets the reply to "shutdown" leave before the session closes.
SHUTDOWN_GRACE_S = 0.1


def _command_responder(service: HwService,
                       robot: int) -> Callable[[HwCommand | None], Awaitable[HwReply]]:
    async def respond(cmd: HwCommand | None) -> HwReply:
        if cmd is None:
            return service.reject_empty(robot)
        return await service.execute(robot, cmd)
    return respond


def bind(bus: Bus, service: HwService) -> None:
    """Declare simhw's queryables on ``bus``."""
    mission = service.mission
    for robot in range(service.world.k):
        bus.declare_queryable(keys.hw_cmd(mission, robot),
                              _command_responder(service, robot), HwCommand)
    bus.declare_queryable(
        keys.hw_admin(mission),
        lambda cmd: service.admin_command(cmd) if cmd is not None else service.admin(b""),
        AdminCommand)
    bus.declare_queryable(keys.world(mission), lambda _: service.world_state())


async def serve(settings: ConnectionSettings, world: World, clock: SimClock,
                kinematics: Kinematics, options: ServerOptions,
                on_ready: Callable[[HwService], None] | None = None) -> HwService:
    """Serve ``world`` until SIGTERM/SIGINT or an admin shutdown; return the service."""
    loop = asyncio.get_running_loop()
    async with Bus.connect(settings) as bus:
        service = HwService(world, clock, kinematics, settings.mission, bus.publish,
                            time_scale=options.time_scale,
                            frozen_hold_s=options.frozen_hold_s)
        service.drops = bus.drops
        bind(bus, service)
        watch_deaths(bus, service, options.dead_bodies)
        service.publish_initial()
        handled = []
        for sig in (signal.SIGTERM, signal.SIGINT):
            with contextlib.suppress(NotImplementedError, RuntimeError):
                # Not available off the main thread or on some platforms: Ctrl-C still works.
                loop.add_signal_handler(sig, service.shutdown.set)
                handled.append(sig)
        try:
            if on_ready is not None:
                on_ready(service)
            await service.shutdown.wait()
            await asyncio.sleep(SHUTDOWN_GRACE_S)
        finally:
            for sig in handled:
                loop.remove_signal_handler(sig)
    return service
