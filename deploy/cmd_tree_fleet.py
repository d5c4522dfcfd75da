"""``mstc tree-fleet``: NCOCTA / COCTA as separate processes with a radio model (paper 001).

Starts an embedded router on a free 127.0.0.1 port, the radio relay (``mstc radio``) and one
``mstc tree-agent`` per robot, prints progress, and reports the coverage time and SF seen in
the robots' reports beside the lockstep simulator's (``run_coverage``) for the same input.
With ``--kill``, the lockstep run to equal is ``run_with_failures`` with every robot removed at
the step the fleet removed it (a SIGKILL lands between steps at a moment the launcher does not
choose exactly; the fleet's agents decide at which step boundary the death counts).

The run directory holds fleet.json like ``mstc up``'s, so ``mstc kill ID`` (a fail-stop robot,
judged like ``--kill``), ``mstc down`` and ``mstc monitor`` work on a tree mission; ``--record``
writes every message for ``mstc report`` (which recomputes this verdict) and ``mstc replay``.

Exit codes: 0 covered, connected at every step and equal to the lockstep run; 1 otherwise (a
process failed, the run stalled, or the results differ); 2 usage or start-up error.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from bus.argtypes import positive, positive_int
from bus.config import ConnectionSettings
from deploy import security
from deploy.errors import UsageError
from deploy.fleet import RunDir, check_port_free, default_run_dir, unique_mission
from deploy.monitor.types import RecorderLink
from deploy.settings import KillOrder
from deploy.supervisor import run_recorded
from deploy.tree_fleet import TreeFleet, TreeFleetOptions, free_endpoint
from deploy.tree_verdict import format_verdict, lockstep_run, summarize
from planner.algorithms import Family, choices_help, names
from planner.treecover.sim import run_coverage
from planner.treecover.trees import tree_from_spec


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--tree", required=True,
                        help="perfect:N=3,H=4 | general:N=2,H=6,remove=R,at=HEIGHT,seed=S | "
                             "office | FILE.tree")
    parser.add_argument("-n", "--robots", type=positive_int, required=True, help="team size k")
    parser.add_argument("--algo", choices=names(Family.TREE), default="cocta",
                        help=f"{choices_help(names(Family.TREE))} (default cocta)")
    parser.add_argument("--listen", metavar="ENDPOINT",
                        help="router endpoint (default: a free port on 127.0.0.1)")
    parser.add_argument("--run-dir", type=Path, default=None, metavar="DIR",
                        help="logs, PID files and fleet.json (default runs/<time>-<mission>)")
    parser.add_argument("--mission", default=None,
                        help="mission name (default: a unique fleet-<hex> per run)")
    parser.add_argument("--record", type=Path, default=None, metavar="FILE",
                        help="record every message of the mission to FILE (JSON Lines; "
                             "see mstc replay and mstc report)")
    parser.add_argument("--step-timeout", type=positive, default=10.0, metavar="SECONDS",
                        help="an agent's longest wait for one step's reports (default 10)")
    parser.add_argument("--stall-timeout", type=positive, default=30.0, metavar="SECONDS",
                        help="give up when no step completes for this long (default 30)")
    parser.add_argument("--lease-ms", type=positive_int, default=5000,
                        help="Zenoh lease of every process (default 5000: tolerant of a "
                             "CPU-starved machine)")
    parser.add_argument("--kill", type=kill_order, metavar="ROBOT@STEP", action="append",
                        default=[],
                        help="SIGKILL robot ROBOT's agent once step STEP is complete; the "
                             "survivors repair the trail and finish (repeatable; orders "
                             "for a later step wait until the earlier robot is removed)")
    parser.add_argument("--settle", type=positive, default=1.0, metavar="SECONDS",
                        help="how long agents wait for a dead robot's last report (default 1)")
    parser.add_argument("--json", action="store_true", help="print one JSON object at the end")
    parser.add_argument("--plain", action="store_true",
                        help="plain progress lines (the only kind this command prints; "
                             "accepted so that mstc up's command lines carry over)")
    security.add_arguments(parser)


def kill_order(text: str) -> KillOrder:
    robot, sep, step = text.partition("@")
    if not sep or not (robot.isascii() and robot.isdigit() and step.isascii()
                       and step.isdigit()):
        raise argparse.ArgumentTypeError(f"expected ROBOT@STEP such as 2@10, got {text!r}")
    return KillOrder(int(robot), step=int(step))


def run(args: argparse.Namespace) -> int:
    tree = tree_from_spec(args.tree)
    victims = [order.robot for order in args.kill]
    if any(robot >= args.robots for robot in victims):
        raise UsageError(f"--kill {max(victims)}@...: robots are 0..{args.robots - 1}")
    if len(set(victims)) != len(victims) or len(victims) >= args.robots:
        raise UsageError("--kill: each robot at most once, and one robot must survive")
    steps = [order.step for order in args.kill]
    shared = sorted({step for step in steps if step is not None and steps.count(step) > 1})
    if shared:  # allowed (it is how that case is reproduced), but not silently
        print(f"tree-fleet: warning: kills at the same step ({', '.join(map(str, shared))}) "
              "land in one settle period; the trail repair does not cover every such pair "
              "(docs/treecover.md, \"Trail repair\")", file=sys.stderr, flush=True)
    if args.record is not None and not args.record.parent.is_dir():
        raise UsageError(f"--record {args.record}: directory {args.record.parent} does not exist")
    lockstep = run_coverage(tree, args.robots, args.algo)  # also rejects infeasible inputs
    if args.listen is not None:
        check_port_free(args.listen)  # another fleet there: one line now, not a failed router
    mission = args.mission or unique_mission()
    run_dir = default_run_dir(mission) if args.run_dir is None else args.run_dir
    secured = security.prepare(args, run_dir, mission, args.robots, own_router=True)
    options = TreeFleetOptions(
        tree=args.tree, robots=args.robots, algo=args.algo, mission=mission,
        run_dir=run_dir, credentials=secured.credentials,
        endpoint=args.listen or free_endpoint(), lease_ms=args.lease_ms,
        step_timeout=args.step_timeout, stall_timeout=args.stall_timeout,
        kills=tuple(args.kill), settle=args.settle)
    say = (lambda _text: None) if args.json else (lambda text: print(text, flush=True))
    connection = secured.observer(ConnectionSettings(
        connect=(options.endpoint or "",), mission=mission, lease_ms=options.lease_ms))
    link = None if args.record is None else RecorderLink()
    outcome = run_recorded(TreeFleet(options, say, link).run(), connection, args.record,
                           "tree-fleet", link=link)
    lockstep, lockstep_cuts = lockstep_run(tree, args.robots, args.algo,
                                           outcome.observed.deaths)
    summary = summarize(tree, lockstep, outcome.observed, ok=outcome.ok,
                        message=outcome.message, lockstep_cuts=lockstep_cuts,
                        radio=outcome.radio, wall_seconds=outcome.wall_seconds,
                        mission_seconds=outcome.mission_seconds)
    summary["complete"] = outcome.observed.coverage_time is not None \
        and outcome.observed.visited == tree.n
    if outcome.kills_left:
        summary["kills_not_carried_out"] = list(outcome.kills_left)
    RunDir(options.run_dir).write_summary(summary)
    print(json.dumps(summary) if args.json else format_verdict(summary))
    return 0 if summary["verdict"] == "ok" else 1
