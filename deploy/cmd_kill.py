"""``mstc kill ID [--hw]``: SIGKILL robot ID's agent process (a fail-stop robot), or with
--hw fail its body in simhw (motors dead, the agent process lives on). The fleet is the one
of --run-dir, by default the most recent run directory."""

from __future__ import annotations

import argparse
import asyncio
import signal
from pathlib import Path

from deploy.errors import FleetError
from deploy.fleet import (
    FleetInfo,
    RunDir,
    is_running,
    latest_run_dir,
    port_reachable,
    send_signal,
)
from deploy.security import FleetSecurity, attach

CONNECT_TIMEOUT_S = 10.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("robot", type=int, metavar="ID", help="robot id")
    parser.add_argument("--hw", action="store_true",
                        help="fail the robot's body in simhw instead of killing its process")
    parser.add_argument("--run-dir", type=Path, default=None, metavar="DIR",
                        help="the fleet's run directory (default: the most recent under runs/)")
    parser.add_argument("--credentials", type=Path, default=None, metavar="FILE",
                        help="--hw: the mission's credentials (default: $MSTC_CREDENTIALS, "
                             "else the run directory's); kill logs in as operator")


def run(args: argparse.Namespace) -> int:
    run_dir = RunDir(args.run_dir or latest_run_dir())
    info = run_dir.read_fleet()
    if args.hw and info.kind == "tree":
        raise FleetError(f"mission {info.mission} covers a tree: its robots have no simulated "
                         f"bodies to fail (kill the agent without --hw)")
    if args.hw:
        creds = attach(args.credentials, run_dir.path, info)
        message = asyncio.run(fail_body(info, args.robot, creds))
        print(f"mstc kill: {message} (mission {info.mission})")
        return 0
    record = info.agent(args.robot)
    if not send_signal(record, signal.SIGKILL):
        raise FleetError(f"agent {args.robot} (pid {record.pid}) is not running")
    print(f"mstc kill: SIGKILL sent to agent {args.robot} (pid {record.pid}) "
          f"of mission {info.mission}")
    return 0


async def fail_body(info: FleetInfo, robot: int, creds: Path | None = None) -> str:
    """Ask the fleet's simhw to fail ``robot``'s body; FleetError if it refuses or is gone."""
    from bus import keys
    from bus.bridge import Bus
    from bus.config import ConnectionSettings
    from bus.messages import AdminCommand, AdminReply

    if not 0 <= robot < info.robots:
        raise FleetError(f"robots of this fleet are 0..{info.robots - 1}, got {robot}")
    # A stopped fleet is told apart before waiting on a router that will never answer.
    simhw = [p for p in info.processes if p.role == "simhw"]
    if simhw and not any(is_running(p) for p in simhw):
        raise FleetError(f"the fleet of mission {info.mission} is not running (its simhw, "
                         f"pid {simhw[0].pid}, has exited)")
    if not port_reachable(info.endpoint):
        raise FleetError(f"no router answers at {info.endpoint} (mission {info.mission}): "
                         f"is the fleet still running?")
    settings = FleetSecurity(creds).operator(
        ConnectionSettings(connect=(info.endpoint,), mission=info.mission))
    try:
        async with asyncio.timeout(CONNECT_TIMEOUT_S), Bus.connect(settings) as bus:
            replies = await bus.query(keys.hw_admin(info.mission),
                                      AdminCommand("fail", robot), AdminReply, timeout=3.0)
    except TimeoutError:
        refused = "" if creds is None else f"; or it refuses the operator of {creds}"
        raise FleetError(f"no connection to the router at {info.endpoint} within "
                         f"{CONNECT_TIMEOUT_S:g} s (mission {info.mission}{refused})") from None
    if not replies:
        raise FleetError(f"no answer from simhw of mission {info.mission} at {info.endpoint}")
    reply = replies[0].msg
    if not reply.ok:
        raise FleetError(f"simhw refused: {reply.message}")
    return reply.message
