"""``mstc radio``: the radio relay of connected tree coverage (docs/treecover.md, "In the fleet").

Robots never subscribe to each other: each transmits on its own ``tree/robot/<r>/outbox`` and
hears only its ``tree/robot/<r>/inbox``, which this process alone writes. It holds the tree and
where each robot stands at each step (from the robots' own reports) and forwards a
transmission only to robots on the same or an adjacent node (simhw.radio_model), so the
communication limit of paper 001 holds by construction. What it refuses, holds or drops is
counted and answered on the ``tree/radio`` queryable (RadioStats).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
import signal
import sys

from bus import keys
from bus.argtypes import positive_int
from bus.bridge import BoundedFifo, Bus
from bus.config import add_connection_arguments, settings_from_args
from bus.errors import BusError
from bus.messages import RadioStats, TreeReport
from planner.treecover.trees import tree_from_spec
from planner.treecover.types import Tree
from simhw.radio_model import RadioModel

READY_MARK = "radio ready"
# A step floods k reports to k robots: room for many steps of a large team.
BACKLOG = 65536


class RadioRelay:
    """Forwards outbox transmissions to the inboxes of robots in range."""

    def __init__(self, bus: Bus, tree: Tree, robots: int) -> None:
        self.bus = bus
        self.model: RadioModel[TreeReport] = RadioModel(tree.parent.tolist(), robots)
        self.spoofed = 0

    def bind(self) -> None:
        mission = self.bus.mission
        self.bus.subscribe(keys.all_tree_outboxes(mission), TreeReport, self._on_transmission,
                           BoundedFifo(BACKLOG))
        self.bus.declare_queryable(keys.tree_radio(mission), lambda _request: self.stats())

    def stats(self) -> RadioStats:
        c = self.model.counters
        return RadioStats(transmissions=c.transmissions, deliveries=c.deliveries,
                          refused=c.refused, pending=self.model.pending,
                          unlocated=c.unlocated, spoofed=self.spoofed)

    def _on_transmission(self, key: str, report: TreeReport) -> None:
        parsed = keys.parse(key)
        if parsed is None or parsed.robot != report.sender:
            # a robot can only transmit as itself: its outbox is its antenna
            self.spoofed += 1
            self.bus.drops.count(keys.kind_of(key), "spoofed", f"sender {report.sender}")
            return
        try:
            out = []
            if report.robot == report.sender:
                out = self.model.locate(report.robot, report.step, report.node)
            out += self.model.transmit(report.sender, report.step, report)
        except ValueError as error:
            self.bus.drops.count(keys.kind_of(key), "invalid", str(error))
            return
        for robot, copy in out:
            self.bus.publish(keys.tree_inbox(self.bus.mission, robot), copy)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--tree", required=True, metavar="SPEC",
                        help="perfect:N=3,H=4 | general:... | office | FILE.tree")
    parser.add_argument("--robots", type=positive_int, required=True, metavar="K",
                        help="number of robots (ids 0..K-1)")
    add_connection_arguments(parser)


async def serve(args: argparse.Namespace, tree: Tree) -> None:
    """Relay until SIGTERM or SIGINT."""
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        with contextlib.suppress(NotImplementedError, RuntimeError):
            loop.add_signal_handler(sig, stop.set)
    settings = settings_from_args(args)
    async with Bus.connect(settings) as bus:
        relay = RadioRelay(bus, tree, args.robots)
        relay.bind()
        print(f"{READY_MARK}: mission {bus.mission}, tree {tree.name} ({tree.n} nodes), "
              f"robots {args.robots}", flush=True)
        await stop.wait()
        stats = relay.stats()
        print(f"radio stopping: {stats}", flush=True)


def run(args: argparse.Namespace) -> int:
    tree = tree_from_spec(args.tree)
    logging.basicConfig(level=logging.WARNING, format="radio %(levelname)s %(message)s")
    try:
        asyncio.run(serve(args, tree))
    except BusError as error:
        print(f"mstc radio: error: {error}", file=sys.stderr)
        return 2
    return 0
