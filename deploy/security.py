"""How a fleet launcher (``mstc up``, ``mstc tree-fleet``) and the tools that attach to its
run directory log in (docs/security.md).

By default a launcher that starts its own router makes fresh credentials for the mission in
the run directory (mode 0600), starts the router enforcing them and starts every child with
them; each child logs in with its own role (agents ``robot_<id>``, simhw and the radio
``simhw``), the launcher as ``operator``, its recorder as ``observer``. ``--insecure`` opts
out; ``--credentials FILE`` uses a file made beforehand (the only way to use a router that
is not the launcher's own, ``--connect``, that enforces log-ins).
"""

from __future__ import annotations

import argparse
import os
from dataclasses import dataclass, replace
from pathlib import Path

from bus.config import ConnectionSettings
from bus.errors import ConfigError
from bus.security import credentials
from bus.security.roles import OBSERVER, OPERATOR, robot
from deploy.errors import UsageError
from deploy.fleet import FleetInfo, RunDir


def add_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--insecure", action="store_true",
                       help="no log-in and no access control on the router: anyone who "
                            "reaches its port can read and steer the mission (only for "
                            "third-party clients such as z_sub; docs/security.md)")
    group.add_argument("--credentials", type=Path, default=None, metavar="FILE",
                       help="use this mission credentials file (mstc credentials new) "
                            "instead of making one in the run directory; needed with "
                            "--connect to a router that enforces it")


@dataclass(frozen=True)
class FleetSecurity:
    """The credentials file of a fleet (None: an insecure run)."""

    credentials: Path | None = None

    @property
    def secure(self) -> bool:
        return self.credentials is not None

    def child_args(self) -> list[str]:
        """Options for every child, the router included (each child picks its own role)."""
        return [] if self.credentials is None else ["--credentials", str(self.credentials)]

    def connection(self, settings: ConnectionSettings, role: str) -> ConnectionSettings:
        if self.credentials is None:
            return settings
        return replace(settings, credentials=self.credentials, role=role)

    def operator(self, settings: ConnectionSettings) -> ConnectionSettings:
        return self.connection(settings, OPERATOR.name)

    def observer(self, settings: ConnectionSettings) -> ConnectionSettings:
        return self.connection(settings, OBSERVER.name)


def prepare(args: argparse.Namespace, run_dir: Path, mission: str, robots: int,
            own_router: bool) -> FleetSecurity:
    """The launcher's security before anything starts (made in the run directory unless
    given); UsageError (one line) for a file that does not fit the mission. A router the
    launcher does not start (--connect) has its own policy, which the launcher cannot make
    credentials for: without --credentials its processes log in with none."""
    given: Path | None = args.credentials
    if args.insecure or (given is None and not own_router):
        return FleetSecurity()
    if given is None:
        path = RunDir(run_dir).create().path / credentials.CREDENTIALS_FILE
        credentials.generate(mission, robots).save(path)
        return FleetSecurity(path.resolve())
    try:
        creds = credentials.load(given)
    except ConfigError as error:
        raise UsageError(str(error)) from error
    if creds.mission != mission:
        raise UsageError(f"--credentials {given} is for mission {creds.mission!r}: give "
                         f"--mission {creds.mission}")
    missing = [robot(r).name for r in range(robots) if robot(r).name not in creds.passwords]
    missing += [r.name for r in (OPERATOR, OBSERVER) if r.name not in creds.passwords]
    if missing:
        raise UsageError(f"--credentials {given} has no entry for {', '.join(missing)}")
    return FleetSecurity(given.resolve())


def attach(explicit: Path | None, run_dir: Path | None,
           info: FleetInfo | None = None) -> Path | None:
    """The credentials a tool attaching to a fleet uses: --credentials, $MSTC_CREDENTIALS,
    the run directory's file, or the file the fleet recorded; None if the fleet is
    insecure."""
    found = credentials.locate(explicit, run_dir, os.environ)
    if found is None and info is not None and info.credentials:
        found = Path(info.credentials)
    return found
