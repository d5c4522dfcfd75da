"""``mstc simhw``: run the simulated RV-400 hardware process (one world, all bodies)."""

from __future__ import annotations

import argparse
import asyncio
import logging
import sys

from bus import argtypes
from bus.argtypes import non_negative, positive_int, time_scale
from bus.config import add_connection_arguments, settings_from_args
from bus.errors import BusError
from planner.errors import RobotPlacementError
from planner.grid import coarsen, validate_starts
from planner.maps import resolve_world
from planner.placement import parse_starts, random_starts
from planner.types import OccupancyGrid
from simhw.clock import make_clock
from simhw.kinematics import Kinematics
from simhw.service import HwService
from simhw.types import DEAD_BODIES, Heading, Pose, ServerOptions, SonarMode, WorldConfig
from simhw.world import World

_HEADING_NAMES = {"N": Heading.N, "E": Heading.E, "S": Heading.S, "W": Heading.W,
                  "0": Heading.N, "1": Heading.E, "2": Heading.S, "3": Heading.W}


def _headings(text: str) -> tuple[Heading, ...]:
    parts = [p.strip().upper() for p in text.replace(";", ",").split(",") if p.strip()]
    bad = [p for p in parts if p not in _HEADING_NAMES]
    if bad or not parts:
        raise argparse.ArgumentTypeError(
            f"headings are N, E, S, W (or 0-3) separated by commas; got {text!r}")
    return tuple(_HEADING_NAMES[p] for p in parts)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--world", required=True, metavar="SPEC",
                        help="builtin world name or map file (see mstc plan --help)")
    parser.add_argument("--cell-size", type=positive_int, default=None, metavar="PX",
                        help="map pixels per sub-cell side (default 1)")
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--starts", "--robots", dest="starts", metavar="'r,c;r,c;...'",
                       help="start sub-cell of each robot, in robot-id order (--robots is the "
                            "old spelling, kept as an alias: elsewhere --robots is a count)")
    where.add_argument("--random-robots", type=positive_int, metavar="K",
                       help="place K robots at random in the largest free component")
    parser.add_argument("--seed", type=argtypes.seed, default=0,
                        help="seed of random placement and odometry noise (default 0)")
    parser.add_argument("--headings", type=_headings, default=None, metavar="H,H,...",
                        help="initial heading per robot: N, E, S or W (default all N)")
    parser.add_argument("--time-scale", type=time_scale, default=1.0, metavar="X",
                        help="sim seconds per wall second; 0 or inf = as fast as possible "
                             "(default 1)")
    parser.add_argument("--sonar-mode", choices=[m.value for m in SonarMode],
                        default=SonarMode.ALL.value,
                        help="'one-at-a-time' allows one sonar direction per sense command, "
                             "like the paper's RV-400 (default all)")
    parser.add_argument("--sonar-range", type=positive_int, default=WorldConfig.sonar_range,
                        metavar="N", help="sonar range in sub-cells (default %(default)s)")
    parser.add_argument("--odometry-noise", type=non_negative, default=0.0, metavar="SIGMA",
                        help="relative std. dev. of per-step odometry error (default 0)")
    parser.add_argument("--frozen-hold", type=non_negative, default=600.0, metavar="S",
                        help="wall seconds a command to a frozen body is held before it is "
                             "answered 'frozen' (default 600)")
    parser.add_argument("--dead-bodies", choices=DEAD_BODIES, default="vanish",
                        help="a dead robot's body: 'vanish' stops blocking others (the MSTC "
                             "papers' assumption) or 'block' stays in the way (default vanish)")
    add_connection_arguments(parser)


def build_world(args: argparse.Namespace) -> World:
    """The World the arguments describe (user mistakes raise a PlannerError subclass)."""
    grid: OccupancyGrid = resolve_world(args.world, args.cell_size)
    if args.starts is not None:
        starts = parse_starts(args.starts)
    else:
        starts = random_starts(grid, args.random_robots, args.seed)
    validate_starts(grid, coarsen(grid), starts)
    headings = args.headings or (Heading.N,) * len(starts)
    if len(headings) != len(starts):
        raise RobotPlacementError(
            f"--headings gives {len(headings)} headings for {len(starts)} robots")
    config = WorldConfig(sonar_mode=SonarMode(args.sonar_mode), sonar_range=args.sonar_range,
                         odometry_noise=args.odometry_noise)
    poses = [Pose(r, c, h) for (r, c), h in zip(starts, headings, strict=True)]
    return World(grid, poses, config, seed=args.seed)


def _announce(service: HwService) -> None:
    grid = service.world.grid
    starts = ";".join(f"{b.pose.row},{b.pose.col}" for b in service.world.bodies())
    print(f"simhw ready: mission {service.mission}, world {grid.name} "
          f"({grid.shape[0]} x {grid.shape[1]} sub-cells), robots {starts}", flush=True)


def run(args: argparse.Namespace) -> int:
    world = build_world(args)
    # Imported after the world is built so that user mistakes are reported without loading
    # the Zenoh bridge (and build_world's tests need none).
    from simhw.server import serve

    logging.basicConfig(level=logging.WARNING, format="simhw %(levelname)s %(message)s")
    options = ServerOptions(time_scale=args.time_scale, frozen_hold_s=args.frozen_hold,
                            dead_bodies=args.dead_bodies)
    try:
        settings = settings_from_args(args, default_role="simhw")
        asyncio.run(serve(settings, world, make_clock(args.time_scale), Kinematics(),
                          options, on_ready=_announce))
    except BusError as error:
        print(f"mstc simhw: error: {error}", file=sys.stderr)
        return 2
    return 0
