"""``mstc credentials``: make, split and rotate the credentials file of a mission for
deployments by hand (``mstc up`` makes its own). See docs/security.md.

    mstc credentials new FILE --mission M --robots K   # every role, fresh passwords
    mstc credentials role FILE ROLE OUT                # ROLE's entry alone, for its host
    mstc credentials rotate FILE                       # same roles, fresh passwords
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bus.argtypes import positive_int
from bus.errors import BusError
from bus.security import credentials
from bus.security.roles import parse_role


def add_arguments(parser: argparse.ArgumentParser) -> None:
    actions = parser.add_subparsers(dest="action", required=True, metavar="ACTION")
    new = actions.add_parser("new", help="credentials for every role of a mission")
    new.add_argument("file", type=Path)
    new.add_argument("--mission", required=True)
    new.add_argument("--robots", type=positive_int, required=True, metavar="K",
                     help="robots 0..K-1 get a role each")
    new.add_argument("--force", action="store_true", help="replace an existing file")
    role = actions.add_parser("role", help="one role's entry alone, to copy to its host")
    role.add_argument("file", type=Path)
    role.add_argument("role", help="robot_<id>, simhw, operator, observer or router")
    role.add_argument("out", type=Path)
    rotate = actions.add_parser("rotate", help="fresh passwords for the same roles")
    rotate.add_argument("file", type=Path)


def run(args: argparse.Namespace) -> int:
    try:
        if args.action == "new":
            if args.file.exists() and not args.force:
                print(f"mstc credentials: error: {args.file} exists (--force to replace it)",
                      file=sys.stderr)
                return 2
            creds = credentials.generate(args.mission, args.robots)
            creds.save(args.file)
            print(f"{args.file}: mission {creds.mission}, roles "
                  f"{', '.join(r.name for r in creds.roles)}")
        elif args.action == "role":
            credentials.load(args.file).only(parse_role(args.role)).save(args.out)
            print(f"{args.out}: role {args.role} of {args.file}")
        else:
            credentials.load(args.file).rotated().save(args.file)
            print(f"{args.file}: new passwords; restart the router, hand out the role files "
                  f"and restart every process")
    except BusError as error:
        print(f"mstc credentials: error: {error}", file=sys.stderr)
        return 2
    return 0
