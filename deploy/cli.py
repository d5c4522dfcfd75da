"""The ``mstc`` command: one entry point, one module per sub-command.

Each sub-command lives in its own module exposing ``add_arguments(parser)`` and
``run(args) -> int``; modules are imported only when their command runs, so ``mstc plan``
never pays for importing zenoh. User mistakes surface as PlannerError / UsageError and are
printed as one line, never as a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import sys
from collections.abc import Sequence
from typing import NoReturn

from deploy.autogroup import share_niceness
from deploy.errors import UsageError
from planner.errors import PlannerError

# name -> (module, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "plan": ("deploy.cmd_plan", "plan offline MSTC coverage of a map and print or plot it"),
    "router": ("deploy.cmd_router", "run the embedded Zenoh router"),
    "credentials": ("deploy.cmd_credentials",
                    "make, split per role or rotate a mission's credentials file"),
    "simhw": ("simhw.main", "run the simulated RV-400 hardware process (the world)"),
    "agent": ("agent.main", "run one robot's agent process"),
    "up": ("deploy.cmd_up", "start a local fleet: router, simhw and N agents"),
    "kill": ("deploy.cmd_kill", "kill a robot's agent (or fail its body with --hw)"),
    "down": ("deploy.cmd_down", "stop the fleet of a run directory"),
    "monitor": ("deploy.cmd_monitor", "watch a mission live (terminal view or --plain)"),
    "replay": ("deploy.cmd_replay", "replay a recorded mission through the live view"),
    "report": ("deploy.cmd_report", "summarise and verify a recorded mission"),
    "export": ("deploy.cmd_export", "write a recorded mission as MCAP and/or rosbag2"),
    "foxglove": ("deploy.cmd_foxglove", "serve a mission live to Foxglove (WebSocket)"),
    "ros-bridge": ("deploy.cmd_ros_bridge", "a mission's map, poses and paths as ROS 2 topics "
                                           "on Zenoh (rmw_zenoh's format)"),
    "chaos": ("deploy.cmd_chaos", "a seeded robustness campaign: fleets under faults, judged"),
    "tree-cover": ("deploy.cmd_tree_cover", "connected coverage of a tree (NCOCTA / COCTA)"),
    "tree-fleet": ("deploy.cmd_tree_fleet", "NCOCTA / COCTA as a fleet: router, radio, K agents"),
    "radio": ("simhw.radio", "run the radio relay of tree coverage (same or adjacent node)"),
    "tree-agent": ("agent.tree.command", "run one robot of tree coverage (NCOCTA / COCTA)"),
    "repro-mstc": ("deploy.repro_mstc", "reproduce paper 003 Fig. 4/5 (NB/BT/opt MSTC)"),
    "repro-createtree": ("deploy.repro_createtree", "reproduce paper 000 (Create Tree)"),
    "repro-tmstc": ("deploy.repro_tmstc", "reproduce paper 002 Tables II/III (TMSTC*)"),
    "repro-ormstc": ("deploy.repro_ormstc", "reproduce paper 004 Fig. 4 (ORMSTC)"),
    "repro-cocta": ("deploy.repro_cocta", "reproduce paper 001 Fig. 4 (NCOCTA/COCTA)"),
}


def _available() -> dict[str, tuple[str, str]]:
    found = {}
    for name, (module, text) in COMMANDS.items():
        if importlib.util.find_spec(module) is not None:
            found[name] = (module, text)
    return found


class ConciseParser(argparse.ArgumentParser):
    """Argument errors as one line naming the command and where help is, without the full
    usage block: `mstc up`'s usage is eight lines and would bury the one that matters."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see `{self.prog} --help`)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = ConciseParser(
        prog="mstc", description="Multi-robot spanning-tree coverage on Eclipse Zenoh.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, (module_name, text) in _available().items():
        module = importlib.import_module(module_name)
        command = sub.add_parser(name, help=text, description=text)
        module.add_arguments(command)
        command.set_defaults(_module=module)
    return parser


def _parser_for(argv: Sequence[str]) -> argparse.ArgumentParser:
    """A parser that imports only the module of the command being run (fast start-up)."""
    commands = _available()
    name = next((a for a in argv if not a.startswith("-")), None)
    if name not in commands:
        return build_parser()
    parser = ConciseParser(prog="mstc")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    module_name, text = commands[name]
    module = importlib.import_module(module_name)
    command = sub.add_parser(name, help=text, description=text)
    module.add_arguments(command)
    command.set_defaults(_module=module)
    return parser


def _is_user_error(error: Exception) -> bool:
    """Mistakes a user can fix: printed as one line. bus.errors is checked only if loaded,
    so commands that never touch the wire do not pay for importing it."""
    if isinstance(error, (PlannerError, UsageError)):
        return True
    bus_errors = sys.modules.get("bus.errors")
    return bus_errors is not None and isinstance(error, bus_errors.BusError)


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    share_niceness()  # a niced fleet child yields to the router and simhw (deploy.autogroup)
    parser = _parser_for(argv)
    args = parser.parse_args(argv)
    try:
        return int(args._module.run(args) or 0)
    except BrokenPipeError:
        # the reader of our output went away (e.g. `mstc plan --json | head`): not an error
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    except Exception as error:
        if not _is_user_error(error):
            raise
        print(f"mstc {args.command}: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
