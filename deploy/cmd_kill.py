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
    latest_run_dir,
    send_signal,
)
from deploy.security import FleetSecurity, attach


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
    settings = FleetSecurity(creds).operator(
        ConnectionSettings(connect=(info.endpoint,), mission=info.mission))
    async with asyncio.timeout(10.0), Bus.connect(settings) as bus:
        replies = await bus.query(keys.hw_admin(info.mission), AdminCommand("fail", robot),
                                  AdminReply, timeout=3.0)
    if not replies:
        raise FleetError(f"no answer from simhw of mission {info.mission} at {info.endpoint}")
    reply = replies[0].msg
    if not reply.ok:
        raise FleetError(f"simhw refused: {reply.message}")
    return reply.message
